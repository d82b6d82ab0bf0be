//! The SIMD paths of [`super::convolve`]: one register-tiled kernel over the vectors of
//! [`Vector`], compiled for AVX2 and FMA ([`avx2`]: 4 float64 or 8 float32 lanes) and
//! for AVX-512 ([`avx512`]: 8 or 16 lanes).

use super::super::element::Vector;
use super::tiles::{for_each_tile, tile_shapes, TILES, TILES_512};

/// A SIMD convolution `$name` (see [`super::convolve`]) over vectors `V`, compiled for
/// `$feature`, tiles of the step counts `$tiles` (`[$t, ...]` the same list, for
/// `tile_shapes!`) × up to 4 vectors.
macro_rules! kernel {
    ($name:ident, $doc:literal, $feature:literal, $tiles:ident, [$($t:tt),+]) => {
        #[doc = $doc]
        ///
        /// # Safety
        /// The CPU must have the target features this copy is compiled for, `c_pad`
        /// must be a whole number of `V`'s vectors, and the slices must satisfy
        /// `convolve`'s assertions.
        #[target_feature(enable = $feature)]
        pub(crate) unsafe fn $name<V: Vector>(
            a: &[V::Elem],
            step: usize,
            kdim: usize,
            w: &[V::Elem],
            c_pad: usize,
            bias: &[V::Elem],
            y: &mut [V::Elem],
        ) {
            const { assert!(matches!($tiles, [$($t),+])) };
            let (a, w, bias, yp) = (a.as_ptr(), w.as_ptr(), bias.as_ptr(), y.as_mut_ptr());
            let g = Geometry {
                a,
                step,
                kdim,
                w,
                c_pad,
                bias,
            };
            for_each_tile(y.len() / c_pad, c_pad, V::LANES, &$tiles, |t0, c0, t_n, nv| {
                macro_rules! conv {
                    ($tt:tt, $nv:tt) => {
                        store::<V, $tt, $nv>(tile::<V, $tt, $nv>(&g, t0, c0), yp, c_pad, t0, c0)
                    };
                }
                // SAFETY: every index below stays inside the slices `convolve` checked.
                unsafe { tile_shapes!(wide, t_n, nv, conv, [$($t),+]) }
            });
        }
    };
}

kernel!(
    avx2,
    "[`super::convolve`] with AVX registers and fused multiply-adds.",
    "avx2,fma",
    TILES,
    [2, 1]
);
kernel!(
    avx512,
    "[`super::convolve`] with AVX-512 registers and fused multiply-adds.",
    "avx512f",
    TILES_512,
    [6, 4, 2, 1]
);

/// The convolution's operands as raw pointers (see [`super::convolve`]).
pub(crate) struct Geometry<E> {
    pub a: *const E,
    pub step: usize,
    pub kdim: usize,
    pub w: *const E,
    pub c_pad: usize,
    pub bias: *const E,
}

/// Output steps `t0..t0 + T`, channels `c0..c0 + NV·lanes`, in registers. Inlined into
/// the kernel that calls it, whose target features it then has.
///
/// # Safety
/// The CPU must have `V`'s target features, and `t0 + T <= l_out`,
/// `c0 + NV·lanes <= c_pad` for slices that satisfy `convolve`'s assertions.
#[inline(always)]
pub(crate) unsafe fn tile<V: Vector, const T: usize, const NV: usize>(
    g: &Geometry<V::Elem>,
    t0: usize,
    c0: usize,
) -> [[V; NV]; T] {
    let &Geometry {
        a,
        step,
        kdim,
        w,
        c_pad,
        bias,
    } = g;
    // SAFETY (whole body): the caller keeps the tile inside the slices.
    unsafe {
        let mut acc = [[V::zero(); NV]; T];
        for row in acc.iter_mut() {
            for (v, r) in row.iter_mut().enumerate() {
                *r = V::load(bias.add(c0 + v * V::LANES));
            }
        }
        for j in 0..kdim {
            let wp = w.add(j * c_pad + c0);
            let wv: [V; NV] = std::array::from_fn(|v| V::load(wp.add(v * V::LANES)));
            for (tt, row) in acc.iter_mut().enumerate() {
                let x = V::splat(*a.add((t0 + tt) * step + j));
                for (r, wv) in row.iter_mut().zip(&wv) {
                    *r = V::fmadd(x, *wv, *r);
                }
            }
        }
        acc
    }
}

/// A tile's accumulators into `y` (`l_out × c_pad`).
///
/// # Safety
/// The CPU must have `V`'s target features; the caller keeps the tile inside `y`.
#[inline(always)]
unsafe fn store<V: Vector, const T: usize, const NV: usize>(
    acc: [[V; NV]; T],
    y: *mut V::Elem,
    c_pad: usize,
    t0: usize,
    c0: usize,
) {
    // SAFETY: the caller's contract.
    unsafe {
        for (tt, row) in acc.iter().enumerate() {
            for (v, r) in row.iter().enumerate() {
                r.store(y.add((t0 + tt) * c_pad + c0 + v * V::LANES));
            }
        }
    }
}
