//! The tiling shared by every path of the CNN's convolution ([`super::convolve`]):
//! the tile shapes, the walk over them, the portable path (the reference the SIMD
//! kernels agree with bit for bit) and the lane-ordered sums of the LayerNorm.

use super::super::element::{Real, MAX_LANES};

/// Output time steps per AVX2 tile (with 4 vectors of channels: 8 accumulators of the
/// 16 registers), then 1 for the steps left over; the portable path's tiles too.
pub(super) const TILES: [usize; 2] = [2, 1];
/// Output time steps per AVX-512 tile (with 4 vectors of channels: 24 accumulators of
/// the 32 registers, so that 4 weight loads feed 24 fused multiply-adds), then tiles of
/// 4, 2 and 1 step for the steps left over: a one-step tile waits on its fused
/// multiply-adds one after another, a wider one overlaps them.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(super) const TILES_512: [usize; 4] = [6, 4, 2, 1];
/// The same for the fused LayerNorm ([`super::avx512_norm::convolve_norm`]) of blocks of at
/// most 2 vectors of channels (28 accumulators): its per-step sums, divisions and
/// square roots wait on one another less, the more steps a tile normalises together.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(super) const TILES_NARROW_512: [usize; 4] = [14, 4, 2, 1];

/// `match (t_n, nv)` over the tile shapes: `t_n` one of the step counts `[T, ..., 1]`
/// (a size list, whose constant the caller asserts equal to it), `nv` 4, 3, 2 or 1
/// vectors (`wide`) or 2 or 1 (`narrow`); each arm is `$call!(T, NV)`. Any other pair
/// is a bug in the caller's tiling: a panic (the bindings report it as an internal
/// error) rather than steps left uncomputed.
#[cfg(target_arch = "x86_64")]
macro_rules! tile_shapes {
    (wide, $t_n:expr, $nv:expr, $call:ident, [$($t:tt),+]) => {
        match ($t_n, $nv) {
            $(
                ($t, 4) => $call!($t, 4),
                ($t, 3) => $call!($t, 3),
                ($t, 2) => $call!($t, 2),
                ($t, 1) => $call!($t, 1),
            )+
            (t_n, nv) => unreachable!("no tile of {t_n} steps and {nv} vectors"),
        }
    };
    (narrow, $t_n:expr, $nv:expr, $call:ident, [$($t:tt),+]) => {
        match ($t_n, $nv) {
            $(
                ($t, 2) => $call!($t, 2),
                ($t, 1) => $call!($t, 1),
            )+
            (t_n, nv) => unreachable!("no narrow tile of {t_n} steps and {nv} vectors"),
        }
    };
}
#[cfg(target_arch = "x86_64")]
pub(super) use tile_shapes;

/// Σ f(v) over `values`, in [`Real::LANES`] partial sums (so that it vectorises):
/// partial sum j adds `f(values[j])`, `f(values[j + LANES])`, … in order from zero, and
/// [`lane_total`] adds them up. The fused AVX-512 LayerNorm
/// ([`super::avx512_norm::convolve_norm`]) keeps this order.
#[inline(always)]
pub(in super::super) fn lane_sum<T: Real>(values: &[T], f: impl Fn(T) -> T) -> T {
    let mut acc = [T::ZERO; MAX_LANES];
    let chunks = values.chunks_exact(T::LANES);
    let tail: T = chunks.remainder().iter().map(|&v| f(v)).sum();
    for chunk in chunks {
        for (a, &v) in acc.iter_mut().zip(chunk) {
            *a += f(v);
        }
    }
    lane_total(&acc[..T::LANES], tail)
}

/// The partial sums of [`lane_sum`] added up, then the values left over beyond the
/// last whole chunk (`tail`).
#[inline(always)]
pub(super) fn lane_total<T: Real>(acc: &[T], tail: T) -> T {
    acc.iter().copied().sum::<T>() + tail
}

/// Panics unless `a` holds `l_out` steps of `step` (each reading `kdim` values), `w` is
/// `kdim × c_pad`, `bias` has `c_pad` values and `c_pad` is a multiple of
/// [`Real::LANES`]: what every path of [`super::convolve`] relies on.
#[allow(clippy::too_many_arguments)]
pub(super) fn assert_operands<T: Real>(
    a: &[T],
    step: usize,
    kdim: usize,
    w: &[T],
    c_pad: usize,
    bias: &[T],
    l_out: usize,
) {
    assert!(
        l_out == 0 || (l_out - 1) * step + kdim <= a.len(),
        "convolution input too short"
    );
    assert!(w.len() == kdim * c_pad && bias.len() == c_pad && c_pad.is_multiple_of(T::LANES));
}

/// The channel blocks and time tiles of [`super::convolve`] for vectors of `lanes`
/// channels: calls `tile(t0, c0, T, NV)` with NV at most 4 vectors and T the first of
/// `sizes` (step counts, largest first, the last 1) that fits in the steps left.
/// `c_pad` is a multiple of `lanes`.
#[inline(always)]
pub(super) fn for_each_tile(
    l_out: usize,
    c_pad: usize,
    lanes: usize,
    sizes: &[usize],
    mut tile: impl FnMut(usize, usize, usize, usize),
) {
    debug_assert!(sizes.last() == Some(&1));
    let mut c0 = 0;
    while c0 < c_pad {
        let nv = ((c_pad - c0) / lanes).min(4);
        let mut t = 0;
        for &size in sizes {
            while t + size <= l_out {
                tile(t, c0, size, nv);
                t += size;
            }
        }
        c0 += nv * lanes;
    }
}

pub(super) fn convolve_portable<T: Real>(
    a: &[T],
    step: usize,
    kdim: usize,
    w: &[T],
    c_pad: usize,
    bias: &[T],
    y: &mut [T],
) {
    let lanes = T::LANES;
    for_each_tile(y.len() / c_pad, c_pad, lanes, &TILES, |t0, c0, t_n, nv| {
        for t in t0..t0 + t_n {
            let out = &mut y[t * c_pad + c0..][..nv * lanes];
            out.copy_from_slice(&bias[c0..c0 + nv * lanes]);
            let row = &a[t * step..][..kdim];
            for (&x, wrow) in row.iter().zip(w.chunks_exact(c_pad)) {
                for (o, &wv) in out.iter_mut().zip(&wrow[c0..c0 + nv * lanes]) {
                    *o = x.mul_add(wv, *o);
                }
            }
        }
    });
}
