//! Process-wide allocator settings of the `nerflex` binary.
//!
//! A bake allocates and frees buffers of tens of megabytes per view and
//! per pass (the projected quads, the two-layer G-buffers, the training
//! pixels) on every rayon worker. glibc hands freed memory at the top of
//! a worker's heap back to the kernel once it passes the trim threshold,
//! so the next view's buffers fault their pages in again and the kernel
//! zeroes them (10–13 % of a lego bake's CPU samples). Keeping freed
//! memory, with the projected quads allocated at their final size, took
//! lego (128, 17)'s whole command to 0.92 of its time and its peak from
//! 4.39 to 3.57 GB, the export byte-identical (docs/baking.md, "Session
//! 36").

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
