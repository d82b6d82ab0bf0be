//! float64 buffers that start on a 64-byte boundary: a cache line, and one AVX-512
//! vector. The CNN's weights and activations are read and written in such vectors
//! ([`super::conv1d`]); a `Vec<f64>` is only sure to be 8-byte aligned (glibc gives 16),
//! so most of them straddled two cache lines, and how many depended on where the
//! allocator happened to put each buffer: the same build took 10.0-11.3 ms per 600
//! windows from one process to the next.

use std::ops::{Deref, DerefMut};

/// One cache line of values.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Line([f64; 8]);

/// `len` float64 values, the first at a 64-byte boundary; derefs to `[f64]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Aligned {
    lines: Vec<Line>,
    len: usize,
}

impl Aligned {
    /// `len` zeros.
    pub(crate) fn zeros(len: usize) -> Self {
        Self {
            lines: vec![Line::default(); len.div_ceil(8)],
            len,
        }
    }
}

impl From<&[f64]> for Aligned {
    fn from(values: &[f64]) -> Self {
        let mut out = Self::zeros(values.len());
        out.copy_from_slice(values);
        out
    }
}

impl FromIterator<f64> for Aligned {
    fn from_iter<I: IntoIterator<Item = f64>>(values: I) -> Self {
        Self::from(values.into_iter().collect::<Vec<f64>>().as_slice())
    }
}

impl Deref for Aligned {
    type Target = [f64];

    fn deref(&self) -> &[f64] {
        // SAFETY: `Line` is `repr(C)` around `[f64; 8]` (size 64, no padding), so the
        // lines are `8 · lines.len()` contiguous, initialised f64 values, and
        // `len <= 8 · lines.len()` (set so in `zeros`, never changed after).
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast::<f64>(), self.len) }
    }
}

impl DerefMut for Aligned {
    fn deref_mut(&mut self) -> &mut [f64] {
        // SAFETY: as in `deref`, and `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast::<f64>(), self.len) }
    }
}

impl<'a> IntoIterator for &'a Aligned {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_values_start_on_a_cache_line_and_keep_their_length_and_order() {
        for len in [0usize, 1, 7, 8, 9, 200, 1601] {
            let values: Vec<f64> = (0..len).map(|i| i as f64 * 0.5 - 3.0).collect();
            let mut a = Aligned::from(values.as_slice());
            assert_eq!(a.as_ptr() as usize % 64, 0, "len {len}");
            assert_eq!(&a[..], &values[..]);
            let b: Aligned = values.iter().copied().collect();
            assert_eq!(&b[..], &values[..]);
            let mut z = Aligned::zeros(len);
            assert!(z.len() == len && z.iter().all(|&v| v == 0.0));
            z.copy_from_slice(&a);
            a.iter_mut().for_each(|v| *v += 1.0);
            assert_eq!(&z[..], &values[..]);
            assert_eq!(z.clone().as_ptr() as usize % 64, 0);
        }
    }
}
