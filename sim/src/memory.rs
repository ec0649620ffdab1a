//! Process-wide allocator settings of the `nerflex` binary.
//!
//! A bake allocates and frees buffers of tens of megabytes per view and
//! per pass (the projected quads, the two-layer G-buffers, the training
//! pixels) on every rayon worker. glibc hands freed memory at the top of
//! a worker's heap back to the kernel once it exceeds the trim threshold,
//! so the next view's buffer faults its pages in and the kernel zeroes
//! them again: on lego (128, 17) 5.09 M page faults and 21.8 s of system
//! time in a 155 s (two-core) run, 10 % of the CPU samples in the kernel's
//! page clearing. Keeping freed memory in the process cut that to 1.43 M
//! faults and 11.8 s for 1.0 GB more peak memory (docs/baking.md,
//! "Session 36").

/// Keeps the memory a thread frees for its next allocations instead of
/// returning it to the kernel (glibc's `M_TRIM_THRESHOLD` at its largest);
/// large single allocations are still mapped and unmapped on their own.
/// A no-op where the C library is not glibc. Call once, before threads
/// start.
pub fn keep_freed_pages() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets allocator parameters; it is called
    // before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
    }
}
