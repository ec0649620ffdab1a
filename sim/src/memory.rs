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
//!
//! [`HugePageAlloc`] goes further on large blocks: on transparent huge
//! pages they fault in a 2 MiB page at a time and their random reads miss
//! the TLB less (lego (128, 17): the whole command 0.76–0.95 of its time
//! paired, the system time a third lower; a short `nerflex train` 0.86–0.90;
//! docs/baking.md, "Session 52").

use std::alloc::{GlobalAlloc, Layout, System};

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

/// Size and alignment of a transparent huge page on x86-64 and aarch64
/// Linux (bytes).
pub const HUGE_PAGE_BYTES: usize = 2 << 20;

/// The `nerflex` binary's allocator: the system's, with every block of at
/// least [`HUGE_PAGE_BYTES`] advised onto transparent huge pages
/// (`madvise(MADV_HUGEPAGE)` over its whole 2 MiB pages; this machine's
/// kernel gives them only where advised). The bake's large buffers (the
/// feature lattice, the training pixels, the G-buffers) are read at random
/// and first touched page by page: with 2 MiB pages the fine-tune's
/// lattice reads miss the TLB far less and a buffer's first touch takes
/// one fault per 2 MiB instead of 512. Advice only: contents, sizes and
/// alignments are the system allocator's, and where the kernel has no
/// huge pages nothing changes.
#[derive(Debug, Default, Clone, Copy)]
pub struct HugePageAlloc;

// SAFETY: every call is forwarded to `System` with the same arguments;
// `advise` only gives the kernel advice on memory the block owns.
unsafe impl GlobalAlloc for HugePageAlloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `GlobalAlloc::alloc`'s caller guarantees.
        let p = unsafe { System.alloc(layout) };
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `GlobalAlloc::alloc_zeroed`'s caller guarantees.
        let p = unsafe { System.alloc_zeroed(layout) };
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System` through this allocator.
        unsafe { System.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `GlobalAlloc::realloc`'s caller guarantees.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        advise(p, new_size);
        p
    }
}

/// The whole 2 MiB pages inside `[start, start + len)`, if any, as
/// `(first byte, length)`.
pub fn huge_pages_within(start: usize, len: usize) -> Option<(usize, usize)> {
    let first = start.checked_next_multiple_of(HUGE_PAGE_BYTES)?;
    let end = start.checked_add(len)? / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES;
    (end > first).then(|| (first, end - first))
}

/// Advises the whole huge pages of the block at `p` (`len` bytes; null:
/// nothing) onto transparent huge pages.
#[inline]
fn advise(p: *mut u8, len: usize) {
    if p.is_null() || len < HUGE_PAGE_BYTES {
        return;
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if let Some((first, bytes)) = huge_pages_within(p as usize, len) {
        // SAFETY: the range lies within the block just allocated, which
        // this process owns; MADV_HUGEPAGE changes no contents, and an
        // error (no huge page support) leaves the memory as it was.
        unsafe {
            libc::madvise(first as *mut libc::c_void, bytes, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_whole_huge_pages_inside_the_block_are_advised() {
        const H: usize = HUGE_PAGE_BYTES;
        // Aligned and whole.
        assert_eq!(huge_pages_within(4 * H, 3 * H), Some((4 * H, 3 * H)));
        // Unaligned start: from the next boundary; the tail's part page
        // is left out.
        assert_eq!(huge_pages_within(4 * H + 16, 3 * H), Some((5 * H, 2 * H)));
        // Smaller than a page once aligned: nothing.
        assert_eq!(huge_pages_within(H + 1, H), None);
        assert_eq!(huge_pages_within(0, H - 1), None);
        // Near the top of the address space: no overflow.
        assert_eq!(huge_pages_within(usize::MAX - H, 4 * H), None);
        assert_eq!(huge_pages_within(usize::MAX - 16, 8), None);
    }

    #[test]
    fn the_allocator_hands_out_usable_blocks_of_every_size() {
        let a = HugePageAlloc;
        for size in [
            1usize,
            64,
            4096,
            HUGE_PAGE_BYTES - 1,
            3 * HUGE_PAGE_BYTES + 5,
        ] {
            let layout = Layout::from_size_align(size, 16).expect("layout");
            // SAFETY: non-zero size; every block is written within its
            // size and freed with its layout.
            unsafe {
                let p = a.alloc_zeroed(layout);
                assert!(!p.is_null());
                assert!(std::slice::from_raw_parts(p, size).iter().all(|&b| b == 0));
                p.write_bytes(7, size);
                let q = a.realloc(p, layout, 2 * size);
                assert!(!q.is_null());
                assert!(std::slice::from_raw_parts(q, size).iter().all(|&b| b == 7));
                a.dealloc(q, Layout::from_size_align(2 * size, 16).expect("layout"));
            }
        }
    }
}
