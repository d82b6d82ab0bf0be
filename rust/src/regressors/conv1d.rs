//! The convolution kernels of the CNN forward pass ([`super::convnet`]): register tiles
//! over time-major im2col rows, with AVX-512 or AVX2 and FMA where the CPU has them and
//! a portable path with the same arithmetic (tested to agree bit for bit).

/// Output channels per SIMD vector (4 float64 lanes of AVX) in the convolution tiles;
/// the channel padding is a multiple of it.
pub(super) const LANES: usize = 4;
/// Output time steps per AVX2 tile (with 4 vectors of channels: 8 accumulators of the
/// 16 registers).
const TILE_T: usize = 2;
/// Output channels per AVX-512 vector (8 float64 lanes).
const LANES_512: usize = 8;
/// Output time steps per AVX-512 tile (with 4 vectors of channels: 24 accumulators of
/// the 32 registers, so that 4 weight loads feed 24 fused multiply-adds).
const TILE_T_512: usize = 6;

/// Σ f(v) over `values`, in [`LANES`] partial sums (so that it vectorises).
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
    assert!(
        l_out == 0 || (l_out - 1) * step + kdim <= a.len(),
        "convolution input too short"
    );
    assert!(w.len() == kdim * c_pad && bias.len() == c_pad && c_pad.is_multiple_of(LANES));
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

/// The channel blocks and time tiles of [`convolve`] for vectors of `lanes` channels and
/// tiles of `tile_t` steps: calls `tile(t0, c0, T, NV)` (T is `tile_t` or, for the last
/// steps, 1; NV is at most 4 vectors). `c_pad` is a multiple of `lanes`.
#[inline(always)]
fn for_each_tile(
    l_out: usize,
    c_pad: usize,
    lanes: usize,
    tile_t: usize,
    mut tile: impl FnMut(usize, usize, usize, usize),
) {
    let mut c0 = 0;
    while c0 < c_pad {
        let nv = ((c_pad - c0) / lanes).min(4);
        let mut t = 0;
        while t + tile_t <= l_out {
            tile(t, c0, tile_t, nv);
            t += tile_t;
        }
        while t < l_out {
            tile(t, c0, 1, nv);
            t += 1;
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
    for_each_tile(y.len() / c_pad, c_pad, LANES, TILE_T, |t0, c0, t_n, nv| {
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
/// lanes, tiles of `$tile_t` steps × up to 4 vectors, compiled for `$feature`; the
/// intrinsics that load, broadcast, fuse-multiply-add and store such a vector.
macro_rules! simd_kernel {
    (
        $name:ident, $doc:literal, $feature:literal, $lanes:ident, $tile_t:ident, $vec:ident,
        $setzero:ident, $loadu:ident, $set1:ident, $fmadd:ident, $storeu:ident
    ) => {
        #[cfg(target_arch = "x86_64")]
        mod $name {
            use super::{for_each_tile, $lanes, $tile_t};
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
                const T: usize = $tile_t;
                let (a, w, bias, yp) = (a.as_ptr(), w.as_ptr(), bias.as_ptr(), y.as_mut_ptr());
                for_each_tile(y.len() / c_pad, c_pad, $lanes, T, |t0, c0, t_n, nv| {
                    // SAFETY: every index below stays inside the slices `convolve` checked.
                    unsafe {
                        match (t_n, nv) {
                            (T, 4) => tile::<T, 4>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (T, 3) => tile::<T, 3>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (T, 2) => tile::<T, 2>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (T, _) => tile::<T, 1>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (_, 4) => tile::<1, 4>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (_, 3) => tile::<1, 3>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            (_, 2) => tile::<1, 2>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                            _ => tile::<1, 1>(a, step, kdim, w, c_pad, bias, yp, t0, c0),
                        }
                    }
                });
            }

            #[inline]
            #[target_feature(enable = $feature)]
            #[allow(clippy::too_many_arguments)]
            unsafe fn tile<const T: usize, const NV: usize>(
                a: *const f64,
                step: usize,
                kdim: usize,
                w: *const f64,
                c_pad: usize,
                bias: *const f64,
                y: *mut f64,
                t0: usize,
                c0: usize,
            ) {
                // SAFETY (whole body): the caller keeps t0 + T <= l_out and
                // c0 + NV·lanes <= c_pad.
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
    TILE_T,
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
    TILE_T_512,
    __m512d,
    _mm512_setzero_pd,
    _mm512_loadu_pd,
    _mm512_set1_pd,
    _mm512_fmadd_pd,
    _mm512_storeu_pd
);

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
