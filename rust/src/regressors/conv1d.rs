//! The convolution kernels of the CNN forward pass ([`super::convnet`]): register tiles
//! over time-major im2col rows, with AVX-512 or AVX2 and FMA where the CPU has them and
//! a portable path with the same arithmetic (tested to agree bit for bit).

/// Output channels per SIMD vector (4 float64 lanes of AVX) in the convolution tiles;
/// the channel padding is a multiple of it.
pub(super) const LANES: usize = 4;
/// Output time steps per AVX2 tile (with 4 vectors of channels: 8 accumulators of the
/// 16 registers), then 1 for the steps left over.
const TILES: [usize; 2] = [2, 1];
/// Output channels per AVX-512 vector (8 float64 lanes).
const LANES_512: usize = 8;
/// Output time steps per AVX-512 tile (with 4 vectors of channels: 24 accumulators of
/// the 32 registers, so that 4 weight loads feed 24 fused multiply-adds), then tiles of
/// 4, 2 and 1 step for the steps left over: a one-step tile waits on its fused
/// multiply-adds one after another, a wider one overlaps them.
const TILES_512: [usize; 4] = [6, 4, 2, 1];
/// The same for the fused LayerNorm ([`avx512_norm::convolve_norm`]) of blocks of at
/// most 2 vectors of channels (28 accumulators): its per-step sums, divisions and
/// square roots wait on one another less, the more steps a tile normalises together.
const TILES_NARROW_512: [usize; 4] = [14, 4, 2, 1];

/// `match (t_n, nv)` over the tile shapes: `t_n` one of the step counts `[T, ..., 1]`
/// (a size list, whose constant the caller asserts equal to it), `nv` 4, 3, 2 or 1
/// vectors (`wide`) or 2 or 1 (`narrow`); each arm is `$call!(T, NV)`. Any other pair
/// is a bug in the caller's tiling: a panic (the bindings report it as an internal
/// error) rather than steps left uncomputed.
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

/// Σ f(v) over `values`, in [`LANES`] partial sums (so that it vectorises): partial
/// sum j adds `f(values[j])`, `f(values[j + LANES])`, … in order from 0.0, and
/// [`lane_total`] adds them up. The fused AVX-512 LayerNorm
/// ([`avx512_norm::convolve_norm`]) keeps this order.
#[inline(always)]
pub(super) fn lane_sum(values: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0f64; LANES];
    let chunks = values.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().map(|&v| f(v)).sum();
    for chunk in chunks {
        for (a, &v) in acc.iter_mut().zip(chunk) {
            *a += f(v);
        }
    }
    lane_total(acc, tail)
}

/// The partial sums of [`lane_sum`] added up, then the values left over beyond the
/// last whole chunk (`tail`).
#[inline(always)]
fn lane_total(acc: [f64; LANES], tail: f64) -> f64 {
    acc.iter().sum::<f64>() + tail
}

/// `y[t, o] = bias[o] + Σ_j a[t·step + j]·w[j, o]` for every output step t and every
/// column o of `w` (`kdim × c_pad`, `c_pad` a multiple of [`LANES`]); `y` is
/// `l_out × c_pad`. Tiles of a few steps × up to four vectors of channels accumulate in
/// registers: with AVX-512 where the CPU has it and `c_pad` is a multiple of 8, else
/// with AVX2 and FMA where it has those. Every path adds the products of an output in
/// the same order, each with one fused multiply-add (`f64::mul_add` in the portable
/// path: correctly rounded, slow only on a CPU without FMA), so they agree bit for bit.
pub(super) fn convolve(
    a: &[f64],
    step: usize,
    kdim: usize,
    w: &[f64],
    c_pad: usize,
    bias: &[f64],
    y: &mut [f64],
) {
    let l_out = y.len() / c_pad;
    assert_operands(a, step, kdim, w, c_pad, bias, l_out);
    #[cfg(target_arch = "x86_64")]
    if c_pad.is_multiple_of(LANES_512) && std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F (checked just above), `c_pad` is a whole number of
        // its vectors, and the slices are long enough for every tile (asserted above).
        unsafe { avx512::convolve(a, step, kdim, w, c_pad, bias, y) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (checked just above), and the slices are long
        // enough for every tile (asserted above).
        unsafe { avx::convolve(a, step, kdim, w, c_pad, bias, y) };
        return;
    }
    convolve_portable(a, step, kdim, w, c_pad, bias, y);
}

/// Panics unless `a` holds `l_out` steps of `step` (each reading `kdim` values), `w` is
/// `kdim × c_pad`, `bias` has `c_pad` values and `c_pad` is a multiple of [`LANES`]:
/// what every path of [`convolve`] relies on.
#[allow(clippy::too_many_arguments)]
fn assert_operands(
    a: &[f64],
    step: usize,
    kdim: usize,
    w: &[f64],
    c_pad: usize,
    bias: &[f64],
    l_out: usize,
) {
    assert!(
        l_out == 0 || (l_out - 1) * step + kdim <= a.len(),
        "convolution input too short"
    );
    assert!(w.len() == kdim * c_pad && bias.len() == c_pad && c_pad.is_multiple_of(LANES));
}

/// The channel blocks and time tiles of [`convolve`] for vectors of `lanes` channels:
/// calls `tile(t0, c0, T, NV)` with NV at most 4 vectors and T the first of `sizes`
/// (step counts, largest first, the last 1) that fits in the steps left. `c_pad` is a
/// multiple of `lanes`.
#[inline(always)]
fn for_each_tile(
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

pub(super) fn convolve_portable(
    a: &[f64],
    step: usize,
    kdim: usize,
    w: &[f64],
    c_pad: usize,
    bias: &[f64],
    y: &mut [f64],
) {
    for_each_tile(y.len() / c_pad, c_pad, LANES, &TILES, |t0, c0, t_n, nv| {
        for t in t0..t0 + t_n {
            let out = &mut y[t * c_pad + c0..][..nv * LANES];
            out.copy_from_slice(&bias[c0..c0 + nv * LANES]);
            let row = &a[t * step..][..kdim];
            for (x, wrow) in row.iter().zip(w.chunks_exact(c_pad)) {
                for (o, wv) in out.iter_mut().zip(&wrow[c0..c0 + nv * LANES]) {
                    *o = x.mul_add(*wv, *o);
                }
            }
        }
    });
}

/// A SIMD copy of [`convolve`] in module `$name`: vectors `$vec` of `$lanes` float64
/// lanes, tiles of the step counts `$tiles` (the last 1; `[$t, ...]` the same list, for
/// `tile_shapes!`) × up to 4 vectors, compiled for `$feature`; the intrinsics that load,
/// broadcast, fuse-multiply-add and store such a vector.
macro_rules! simd_kernel {
    (
        $name:ident, $doc:literal, $feature:literal, $lanes:ident, $tiles:ident,
        [$($t:tt),+], $vec:ident,
        $setzero:ident, $loadu:ident, $set1:ident, $fmadd:ident, $storeu:ident
    ) => {
        #[cfg(target_arch = "x86_64")]
        mod $name {
            use super::{for_each_tile, $lanes, $tiles};
            use std::arch::x86_64::*;

            #[doc = $doc]
            ///
            /// # Safety
            /// The CPU must have the target features this copy is compiled for, `c_pad`
            /// must be a whole number of its vectors, and the slices must satisfy
            /// `convolve`'s assertions.
            #[target_feature(enable = $feature)]
            pub unsafe fn convolve(
                a: &[f64],
                step: usize,
                kdim: usize,
                w: &[f64],
                c_pad: usize,
                bias: &[f64],
                y: &mut [f64],
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
                for_each_tile(y.len() / c_pad, c_pad, $lanes, &$tiles, |t0, c0, t_n, nv| {
                    macro_rules! conv {
                        ($tt:tt, $nv:tt) => {
                            store(tile::<$tt, $nv>(&g, t0, c0), yp, c_pad, t0, c0)
                        };
                    }
                    // SAFETY: every index below stays inside the slices `convolve` checked.
                    unsafe { tile_shapes!(wide, t_n, nv, conv, [$($t),+]) }
                });
            }

            /// The convolution's operands as raw pointers (see [`super::convolve`]).
            #[derive(Clone, Copy)]
            pub(super) struct Geometry {
                pub a: *const f64,
                pub step: usize,
                pub kdim: usize,
                pub w: *const f64,
                pub c_pad: usize,
                pub bias: *const f64,
            }

            /// Output steps `t0..t0 + T`, channels `c0..c0 + NV·lanes`, in registers.
            ///
            /// # Safety
            /// The CPU must have the target features, and `t0 + T <= l_out`,
            /// `c0 + NV·lanes <= c_pad` for slices that satisfy `convolve`'s assertions.
            #[inline]
            #[target_feature(enable = $feature)]
            pub(super) unsafe fn tile<const T: usize, const NV: usize>(
                g: &Geometry,
                t0: usize,
                c0: usize,
            ) -> [[$vec; NV]; T] {
                let Geometry {
                    a,
                    step,
                    kdim,
                    w,
                    c_pad,
                    bias,
                } = *g;
                // SAFETY (whole body): the caller keeps the tile inside the slices.
                unsafe {
                    let mut acc = [[$setzero(); NV]; T];
                    for row in acc.iter_mut() {
                        for (v, r) in row.iter_mut().enumerate() {
                            *r = $loadu(bias.add(c0 + v * $lanes));
                        }
                    }
                    for j in 0..kdim {
                        let wp = w.add(j * c_pad + c0);
                        let wv: [$vec; NV] = std::array::from_fn(|v| $loadu(wp.add(v * $lanes)));
                        for (tt, row) in acc.iter_mut().enumerate() {
                            let x = $set1(*a.add((t0 + tt) * step + j));
                            for (r, wv) in row.iter_mut().zip(&wv) {
                                *r = $fmadd(x, *wv, *r);
                            }
                        }
                    }
                    acc
                }
            }

            /// A tile's accumulators into `y` (`l_out × c_pad`).
            #[inline]
            #[target_feature(enable = $feature)]
            unsafe fn store<const T: usize, const NV: usize>(
                acc: [[$vec; NV]; T],
                y: *mut f64,
                c_pad: usize,
                t0: usize,
                c0: usize,
            ) {
                // SAFETY: the caller keeps the tile inside `y`.
                unsafe {
                    for (tt, row) in acc.iter().enumerate() {
                        for (v, r) in row.iter().enumerate() {
                            $storeu(y.add((t0 + tt) * c_pad + c0 + v * $lanes), *r);
                        }
                    }
                }
            }
        }
    };
}

simd_kernel!(
    avx,
    "[`super::convolve`] with 4-lane AVX registers and fused multiply-adds.",
    "avx2,fma",
    LANES,
    TILES,
    [2, 1],
    __m256d,
    _mm256_setzero_pd,
    _mm256_loadu_pd,
    _mm256_set1_pd,
    _mm256_fmadd_pd,
    _mm256_storeu_pd
);

simd_kernel!(
    avx512,
    "[`super::convolve`] with 8-lane AVX-512 registers and fused multiply-adds.",
    "avx512f",
    LANES_512,
    TILES_512,
    [6, 4, 2, 1],
    __m512d,
    _mm512_setzero_pd,
    _mm512_loadu_pd,
    _mm512_set1_pd,
    _mm512_fmadd_pd,
    _mm512_storeu_pd
);

/// What follows the convolution in a block of the CNN: LayerNorm over the channels of
/// each step (`gamma`, `beta`, `eps`), then LeakyReLU (`slope`).
#[cfg(target_arch = "x86_64")]
pub(super) struct Norm<'a> {
    pub gamma: &'a [f64],
    pub beta: &'a [f64],
    pub eps: f64,
    pub slope: f64,
}

/// Where [`avx512_norm::convolve_norm`] puts a block's activations.
#[cfg(target_arch = "x86_64")]
pub(super) enum Activations<'a> {
    /// Row t (of `c` channels) at `rows[t·c..]`: the next block's input.
    Rows(&'a mut [f64]),
    /// Added up over the steps, in step order, into the `c` channels: the last block's
    /// pooling.
    Pool(&'a mut [f64]),
}

/// Convolution, LayerNorm and LeakyReLU in one pass with AVX-512, for blocks whose
/// output channels fill whole 8-lane vectors, at most 4 of them: each register tile
/// then holds whole steps, normalised before they leave the registers. Every value is
/// computed as the separate passes compute it (the convolution's tile, [`lane_sum`]'s
/// order of additions, the same divisions and square root, no fused multiply-add
/// outside the convolution), so the bits are the same (tested).
#[cfg(target_arch = "x86_64")]
pub(super) mod avx512_norm {
    use super::avx512::{tile, Geometry};
    use super::{
        for_each_tile, lane_total, Activations, Norm, LANES, LANES_512, TILES_512, TILES_NARROW_512,
    };
    use std::arch::x86_64::*;

    /// Whether [`convolve_norm`] takes `c` output channels (padded to `c_pad`).
    pub fn takes(c: usize, c_pad: usize) -> bool {
        c == c_pad && c.is_multiple_of(LANES_512) && c > 0 && c <= 4 * LANES_512
    }

    /// `l_out` steps of the convolution of [`super::convolve`] (its arguments), each
    /// normalised and activated into `out`.
    ///
    /// Panics where the slices do not fit (as [`super::convolve`] does): `a` too short
    /// for `l_out` steps, `w`, `bias`, `norm` or `out` not of `c_pad` channels (`out`:
    /// `l_out` rows, or one row to pool into), or [`takes`] false for `c_pad`.
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[target_feature(enable = "avx512f")]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn convolve_norm(
        a: &[f64],
        step: usize,
        kdim: usize,
        w: &[f64],
        c_pad: usize,
        bias: &[f64],
        l_out: usize,
        norm: &Norm<'_>,
        out: Activations<'_>,
    ) {
        const { assert!(matches!(TILES_512, [6, 4, 2, 1])) };
        const { assert!(matches!(TILES_NARROW_512, [14, 4, 2, 1])) };
        super::assert_operands(a, step, kdim, w, c_pad, bias, l_out);
        assert!(takes(c_pad, c_pad));
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
        let c = c_pad as f64;
        let narrow = c_pad <= 2 * LANES_512;
        let sizes: &[usize] = if narrow {
            &TILES_NARROW_512
        } else {
            &TILES_512
        };
        for_each_tile(l_out, c_pad, LANES_512, sizes, |t0, _, t_n, nv| {
            // SAFETY: the tiles stay inside the slices (asserted above); one channel
            // block of `nv` = c_pad / 8 vectors covers every channel.
            unsafe {
                let at = if pool { dst } else { dst.add(t0 * c_pad) };
                let step = if pool { 0 } else { c_pad };
                macro_rules! conv_norm {
                    ($tt:tt, $nv:tt) => {
                        normalise(&tile::<$tt, $nv>(&g, t0, 0), c, norm, at, step)
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
    /// tile's loop its registers pushed the accumulators to the stack (measured: 10.7
    /// against 6.7 ms per 600 windows).
    #[inline(never)]
    #[target_feature(enable = "avx512f")]
    unsafe fn normalise<const T: usize, const NV: usize>(
        rows: &[[__m512d; NV]; T],
        c: f64,
        norm: &Norm<'_>,
        at: *mut f64,
        step: usize,
    ) {
        // SAFETY (whole body): `norm` has NV vectors of channels and `at` room for the
        // rows (the caller's contract).
        unsafe {
            // each stage over all the tile's steps before the next
            let mut mean = [0.0; T];
            for t in 0..T {
                mean[t] = sum_in_lane_order(&rows[t]) / c;
            }
            let mut rstd = [0.0; T];
            for t in 0..T {
                let m = _mm512_set1_pd(mean[t]);
                let mut squares = rows[t];
                for d in squares.iter_mut() {
                    let centred = _mm512_sub_pd(*d, m);
                    *d = _mm512_mul_pd(centred, centred);
                }
                rstd[t] = sum_in_lane_order(&squares) / c + norm.eps;
            }
            for r in rstd.iter_mut() {
                *r = 1.0 / r.sqrt();
            }
            let (zero, slope) = (_mm512_setzero_pd(), _mm512_set1_pd(norm.slope));
            for (t, row) in rows.iter().enumerate() {
                let (m, r) = (_mm512_set1_pd(mean[t]), _mm512_set1_pd(rstd[t]));
                for (v, &x) in row.iter().enumerate() {
                    let d = _mm512_sub_pd(x, m);
                    let gamma = _mm512_loadu_pd(norm.gamma.as_ptr().add(v * LANES_512));
                    let beta = _mm512_loadu_pd(norm.beta.as_ptr().add(v * LANES_512));
                    let y = _mm512_add_pd(_mm512_mul_pd(_mm512_mul_pd(d, r), gamma), beta);
                    // y where y >= 0 (NaN fails it, as in the scalar `if`), else y·slope
                    let keep = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(y, zero);
                    let act = _mm512_mask_blend_pd(keep, _mm512_mul_pd(y, slope), y);
                    let p = at.add(t * step + v * LANES_512);
                    if step == 0 {
                        _mm512_storeu_pd(p, _mm512_add_pd(_mm512_loadu_pd(p), act));
                    } else {
                        _mm512_storeu_pd(p, act);
                    }
                }
            }
        }
    }

    /// Σ over the lanes of `vectors` in [`super::lane_sum`]'s order: its partial sum j
    /// takes lane j of each half (channels 4k + j), half after half.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn sum_in_lane_order(vectors: &[__m512d]) -> f64 {
        let mut acc = _mm256_setzero_pd();
        for &v in vectors {
            acc = _mm256_add_pd(acc, _mm512_castpd512_pd256(v));
            acc = _mm256_add_pd(acc, _mm512_extractf64x4_pd::<1>(v));
        }
        let mut parts = [0.0; LANES];
        // SAFETY: `parts` holds the 4 lanes.
        unsafe { _mm256_storeu_pd(parts.as_mut_ptr(), acc) };
        lane_total(parts, std::iter::empty::<f64>().sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    type Kernel = unsafe fn(&[f64], usize, usize, &[f64], usize, &[f64], &mut [f64]);

    /// The SIMD kernels this CPU has that take `c_pad` channels, each by name.
    #[cfg(target_arch = "x86_64")]
    fn simd_paths(c_pad: usize) -> Vec<(&'static str, Kernel)> {
        let mut paths: Vec<(&'static str, Kernel)> = Vec::new();
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            paths.push(("AVX2", avx::convolve));
        }
        if c_pad.is_multiple_of(LANES_512) && std::arch::is_x86_feature_detected!("avx512f") {
            paths.push(("AVX-512", avx512::convolve));
        }
        paths
    }

    fn random64(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<f64> {
        (0..n)
            .map(|_| (rng.random::<f64>() - 0.5) * 2.0 * scale)
            .collect()
    }

    #[test]
    fn the_convolution_covers_every_step_and_channel_on_both_paths() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for (c_in, c_out, kernel, stride, l_out) in [
            (1usize, 16usize, 7usize, 1usize, 200usize),
            (16, 32, 5, 2, 100),
            (3, 20, 3, 1, 7),
            (2, 40, 3, 3, 5),
            (32, 32, 5, 2, 50),
            (4, 24, 3, 1, 13),
        ] {
            let c_pad = c_out.div_ceil(LANES) * LANES;
            let kdim = kernel * c_in;
            let a = random64(&mut rng, ((l_out - 1) * stride + kernel) * c_in, 1.0);
            let w = random64(&mut rng, kdim * c_pad, 1.0);
            let bias = random64(&mut rng, c_pad, 1.0);
            let mut y = vec![f64::NAN; l_out * c_pad];
            let mut plain = vec![f64::NAN; l_out * c_pad];
            convolve(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut y);
            convolve_portable(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut plain);
            assert_eq!(y, plain, "the dispatched and portable paths differ");
            #[cfg(target_arch = "x86_64")]
            for (name, path) in simd_paths(c_pad) {
                let mut v = vec![f64::NAN; l_out * c_pad];
                // SAFETY: `simd_paths` lists only what this CPU has, for this `c_pad`.
                unsafe { path(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut v) };
                assert_eq!(v, plain, "the {name} and portable paths differ");
            }
            for t in 0..l_out {
                for o in 0..c_pad {
                    let want: f64 = bias[o]
                        + (0..kdim)
                            .map(|j| a[t * stride * c_in + j] * w[j * c_pad + o])
                            .sum::<f64>();
                    assert!((y[t * c_pad + o] - want).abs() < 1e-12, "{t} {o}");
                }
            }
        }
    }
}
