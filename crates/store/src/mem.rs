//! Big sorting buffers on huge pages where the system gives them on request (Linux's
//! transparent huge pages in `madvise` mode): a 10 GB run otherwise takes millions of page
//! faults and misses the TLB on nearly every random access of the sort and the gather.

/// Asks for huge pages under the whole capacity of `v` (before its memory is first touched).
pub(crate) fn prefer_huge_pages<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = v.capacity() * std::mem::size_of::<T>();
        if bytes < 4 * HUGE {
            return;
        }
        let start = v.as_mut_ptr() as usize;
        let (lo, hi) = (start.next_multiple_of(HUGE), (start + bytes) / HUGE * HUGE);
        if hi > lo {
            // SAFETY: the range lies inside the vector's allocation, and the advice changes
            // only how its pages are backed, never their contents. Failure is harmless.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}
