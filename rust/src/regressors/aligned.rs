//! float64 or float32 buffers that start on a 64-byte boundary: a cache line, and one
//! AVX-512 vector. The CNN's weights and activations are read and written in such vectors
//! ([`super::conv1d`]); a `Vec<f64>` is only sure to be 8-byte aligned (glibc gives 16),
//! so most of them straddled two cache lines, and how many depended on where the
//! allocator happened to put each buffer: the same build took 10.0-11.3 ms per 600
//! windows from one process to the next.

use super::element::Real;
use std::marker::PhantomData;
use std::ops::{Deref, DerefMut};

/// One cache line of zero bits: 8 float64 or 16 float32 zeros.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Line([u64; 8]);

/// `len` values of `T`, the first at a 64-byte boundary; derefs to `[T]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Aligned<T = f64> {
    lines: Vec<Line>,
    len: usize,
    values: PhantomData<T>,
}

impl<T: Real> Aligned<T> {
    /// `len` zeros.
    pub(crate) fn zeros(len: usize) -> Self {
        Self {
            lines: vec![Line::default(); len.div_ceil(Self::PER_LINE)],
            len,
            values: PhantomData,
        }
    }

    const PER_LINE: usize = std::mem::size_of::<Line>() / std::mem::size_of::<T>();
}

impl<T: Real> From<&[T]> for Aligned<T> {
    fn from(values: &[T]) -> Self {
        let mut out = Self::zeros(values.len());
        out.copy_from_slice(values);
        out
    }
}

impl<T: Real> FromIterator<T> for Aligned<T> {
    fn from_iter<I: IntoIterator<Item = T>>(values: I) -> Self {
        Self::from(values.into_iter().collect::<Vec<T>>().as_slice())
    }
}

impl<T: Real> Deref for Aligned<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        // SAFETY: `Line` is `repr(C)` around `[u64; 8]` (size 64, no padding, aligned
        // to 64), so the lines are `PER_LINE · lines.len()` contiguous values of `T`
        // (f32 or f64: `Real` is sealed; alignment 4 or 8 divides 64; every bit pattern,
        // the zeros included, is a valid value), and `len <= PER_LINE · lines.len()`
        // (set so in `zeros`, never changed after).
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast::<T>(), self.len) }
    }
}

impl<T: Real> DerefMut for Aligned<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        // SAFETY: as in `deref`, and `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast::<T>(), self.len) }
    }
}

impl<'a, T: Real> IntoIterator for &'a Aligned<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;

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
            let narrow: Aligned<f32> = values.iter().map(|&v| v as f32).collect();
            assert_eq!(narrow.as_ptr() as usize % 64, 0, "len {len}");
            assert!(
                narrow.len() == len && narrow.iter().zip(&values).all(|(&a, &b)| a == b as f32)
            );
        }
    }
}
