//! Convolution, LayerNorm and LeakyReLU in one pass with AVX-512, for blocks whose
//! output channels fill whole vectors (8 float64 or 16 float32 lanes), at most 4 of
//! them: each register tile then holds whole steps, normalised before they leave the
//! registers. Every value is computed as the separate passes compute it (the
//! convolution's tile, [`super::tiles::lane_sum`]'s order of additions, the same
//! divisions and square root, no fused multiply-add outside the convolution), so the
//! bits are the same (tested).

use super::super::element::{Real, Wide};
use super::simd::{tile, Geometry};
use super::tiles::{
    assert_operands, for_each_tile, lane_total, tile_shapes, TILES_512, TILES_NARROW_512,
};

/// What follows the convolution in a block of the CNN: LayerNorm over the channels of
/// each step (`gamma`, `beta`, `eps`), then LeakyReLU (`slope`).
pub(in super::super) struct Norm<'a, T> {
    pub gamma: &'a [T],
    pub beta: &'a [T],
    pub eps: T,
    pub slope: T,
}

/// Where [`convolve_norm`] puts a block's activations.
pub(in super::super) enum Activations<'a, T> {
    /// Row t (of `c` channels) at `rows[t·c..]`: the next block's input.
    Rows(&'a mut [T]),
    /// Added up over the steps, in step order, into the `c` channels: the last block's
    /// pooling.
    Pool(&'a mut [T]),
}

/// Whether [`convolve_norm`] takes `c` output channels of `T` (padded to `c_pad`).
pub(in super::super) fn takes<T: Real>(c: usize, c_pad: usize) -> bool {
    c == c_pad && c.is_multiple_of(T::LANES_512) && c > 0 && c <= 4 * T::LANES_512
}

/// `l_out` steps of the convolution of [`super::convolve`] (its arguments), each
/// normalised and activated into `out`, with the AVX-512 vectors `V`.
///
/// Panics where the slices do not fit (as [`super::convolve`] does): `a` too short
/// for `l_out` steps, `w`, `bias`, `norm` or `out` not of `c_pad` channels (`out`:
/// `l_out` rows, or one row to pool into), or [`takes`] false for `c_pad`.
///
/// # Safety
/// The CPU must have AVX-512F.
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
pub(in super::super) unsafe fn convolve_norm<V: Wide>(
    a: &[V::Elem],
    step: usize,
    kdim: usize,
    w: &[V::Elem],
    c_pad: usize,
    bias: &[V::Elem],
    l_out: usize,
    norm: &Norm<'_, V::Elem>,
    out: Activations<'_, V::Elem>,
) {
    const { assert!(matches!(TILES_512, [6, 4, 2, 1])) };
    const { assert!(matches!(TILES_NARROW_512, [14, 4, 2, 1])) };
    assert_operands(a, step, kdim, w, c_pad, bias, l_out);
    assert!(takes::<V::Elem>(c_pad, c_pad) && V::LANES == V::Elem::LANES_512);
    let fits = match &out {
        Activations::Rows(rows) => rows.len() == l_out * c_pad,
        Activations::Pool(sums) => sums.len() == c_pad,
    };
    assert!(fits && norm.gamma.len() == c_pad && norm.beta.len() == c_pad);
    let g = Geometry {
        a: a.as_ptr(),
        step,
        kdim,
        w: w.as_ptr(),
        c_pad,
        bias: bias.as_ptr(),
    };
    let (dst, pool) = match out {
        Activations::Rows(rows) => (rows.as_mut_ptr(), false),
        Activations::Pool(sums) => (sums.as_mut_ptr(), true),
    };
    let narrow = c_pad <= 2 * V::LANES;
    let sizes: &[usize] = if narrow {
        &TILES_NARROW_512
    } else {
        &TILES_512
    };
    for_each_tile(l_out, c_pad, V::LANES, sizes, |t0, _, t_n, nv| {
        // SAFETY: the tiles stay inside the slices (asserted above); one channel
        // block of `nv` = c_pad / LANES vectors covers every channel.
        unsafe {
            let at = if pool { dst } else { dst.add(t0 * c_pad) };
            let step = if pool { 0 } else { c_pad };
            macro_rules! conv_norm {
                ($tt:tt, $nv:tt) => {
                    normalise::<V, $tt, $nv>(&tile::<V, $tt, $nv>(&g, t0, 0), norm, at, step)
                };
            }
            if narrow {
                tile_shapes!(narrow, t_n, nv, conv_norm, [14, 4, 2, 1])
            } else {
                tile_shapes!(wide, t_n, nv, conv_norm, [6, 4, 2, 1])
            }
        }
    });
}

/// A tile's steps (`T` rows of `NV` whole vectors of channels): LayerNorm, then
/// LeakyReLU, row t stored at `at + t·step`, or (`step` 0: pooling) added to `at`
/// in step order. Each stage runs over all the tile's steps before the next, so
/// that their sums, divisions and square roots overlap. Not inlined: inside the
/// tile's loop its registers pushed the accumulators to the stack (measured in
/// float64: 10.7 against 6.7 ms per 600 windows).
///
/// # Safety
/// The CPU must have AVX-512F; `norm` has `NV` vectors of channels and `at` room for
/// the rows.
#[inline(never)]
#[target_feature(enable = "avx512f")]
unsafe fn normalise<V: Wide, const T: usize, const NV: usize>(
    rows: &[[V; NV]; T],
    norm: &Norm<'_, V::Elem>,
    at: *mut V::Elem,
    step: usize,
) {
    let c = V::Elem::from_f64((NV * V::LANES) as f64);
    // SAFETY (whole body): the caller's contract.
    unsafe {
        let mut mean = [V::Elem::ZERO; T];
        for t in 0..T {
            mean[t] = sum_in_lane_order(&rows[t]) / c;
        }
        let mut rstd = [V::Elem::ZERO; T];
        for t in 0..T {
            let m = V::splat(mean[t]);
            let mut squares = rows[t];
            for d in squares.iter_mut() {
                let centred = V::sub(*d, m);
                *d = V::mul(centred, centred);
            }
            rstd[t] = sum_in_lane_order(&squares) / c + norm.eps;
        }
        for r in rstd.iter_mut() {
            *r = V::Elem::ONE / r.sqrt();
        }
        let slope = V::splat(norm.slope);
        for (t, row) in rows.iter().enumerate() {
            let (m, r) = (V::splat(mean[t]), V::splat(rstd[t]));
            for (v, &x) in row.iter().enumerate() {
                let d = V::sub(x, m);
                let gamma = V::load(norm.gamma.as_ptr().add(v * V::LANES));
                let beta = V::load(norm.beta.as_ptr().add(v * V::LANES));
                let y = V::add(V::mul(V::mul(d, r), gamma), beta);
                let act = V::leaky(y, slope);
                let p = at.add(t * step + v * V::LANES);
                if step == 0 {
                    V::add(V::load(p), act).store(p);
                } else {
                    act.store(p);
                }
            }
        }
    }
}

/// Σ over the lanes of `vectors` in [`super::tiles::lane_sum`]'s order.
///
/// # Safety
/// The CPU must have AVX-512F.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn sum_in_lane_order<V: Wide>(vectors: &[V]) -> V::Elem {
    // SAFETY: the caller's contract.
    let parts = unsafe { V::lane_partials(vectors) };
    lane_total(
        &parts[..V::Elem::LANES],
        std::iter::empty::<V::Elem>().sum(),
    )
}
