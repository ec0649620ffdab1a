//! A cache hint for the hot loops that read memory in an order the
//! hardware cannot guess (the trainer's lattice, the fine-tune's pixels,
//! the peel's quads).

/// Asks the CPU to bring the cache lines of `x` in (a hint, no effect on
/// results; nothing off x86-64).
#[inline(always)]
pub(crate) fn prefetch<T: ?Sized>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let (p, bytes) = ((x as *const T).cast::<i8>(), std::mem::size_of_val(x));
        for off in (0..bytes).step_by(64).chain(bytes.checked_sub(1)) {
            // SAFETY: a prefetch never faults, and `p + off` lies in `x`.
            #[allow(unused_unsafe)]
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p.add(off))
            };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
