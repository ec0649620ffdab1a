//! A cache hint for the hot loops that read memory in an order the
//! hardware cannot guess.

/// Asks the CPU to bring the cache lines of `x` in (a hint, no effect on
/// results).
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (x as *const T).cast::<i8>();
        let size = std::mem::size_of::<T>().max(1);
        // SAFETY: a prefetch never faults, and every offset is inside the
        // `size` bytes of `x` from `p` (the last one included).
        #[allow(unused_unsafe)]
        unsafe {
            for off in (0..size).step_by(64) {
                _mm_prefetch::<_MM_HINT_T0>(p.add(off));
            }
            _mm_prefetch::<_MM_HINT_T0>(p.add(size - 1));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
