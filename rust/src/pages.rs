//! Room for large outputs: a vector whose pages the kernel may back by huge pages.
//!
//! A pass that keeps every epoch writes 248 bytes per IMU sample into memory it has
//! just allocated; each 4 KiB page of it costs a page fault on first write (about a
//! microsecond with the zeroing and the accounting), more than the writing itself.
//! Where transparent huge pages are enabled on request (`madvise` in
//! `/sys/kernel/mm/transparent_hugepage/enabled`, the usual default), asking for them
//! makes that one fault per 2 MiB. Elsewhere (THP off, or always on, or not Linux)
//! the request does nothing and the vector is a plain one. Two costs come with it: a
//! huge page is resident as a whole once any of it is written, so a vector filled
//! short of its room (a thinned pass reserves for the most epochs it may keep) holds
//! up to 2 MiB more than it wrote; and where the kernel compacts memory for advised
//! regions at the fault (`defrag` set to `madvise`, its default), a fragmented
//! machine may stall there instead.

/// The size of a huge page on x86-64 and of most arm64 kernels \[bytes\].
const HUGE_PAGE: usize = 2 << 20;

/// An empty vector with room for `n` values, its whole huge pages asked to be backed
/// by huge pages where it spans at least two (the request is advice: it changes no
/// value, and its failure is ignored).
pub fn vec_with_capacity<T>(n: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(n);
    let bytes = v.capacity().saturating_mul(std::mem::size_of::<T>());
    if bytes >= 2 * HUGE_PAGE {
        advise_huge(v.as_ptr() as usize, bytes);
    }
    v
}

#[cfg(target_os = "linux")]
fn advise_huge(start: usize, bytes: usize) {
    let first = start.next_multiple_of(HUGE_PAGE);
    let end = (start + bytes) / HUGE_PAGE * HUGE_PAGE;
    if end > first {
        // SAFETY: [first, end) lies inside the vector's allocation, which this
        // function's caller owns and has not written; MADV_HUGEPAGE only changes how
        // the kernel backs those pages, never their contents or their mapping.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_start: usize, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_vector_is_a_plain_empty_one_with_the_room_asked_for() {
        // The last one spans the two huge pages the request needs (4.8 MB).
        for n in [0, 1, 1000, 40_000] {
            let mut v: Vec<[f64; 15]> = vec_with_capacity(n);
            assert!(v.is_empty());
            assert!(v.capacity() >= n);
            v.extend((0..n).map(|i| [i as f64; 15]));
            assert!(v.iter().enumerate().all(|(i, row)| row[14] == i as f64));
        }
    }
}
