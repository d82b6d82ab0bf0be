//! The convolution kernels of the CNN forward pass ([`super::convnet`]), in float64 or
//! float32 ([`Real`]): register tiles over time-major im2col rows ([`tiles`]), with
//! AVX-512 or AVX2 and FMA where the CPU has them ([`simd`]) and a portable path with
//! the same arithmetic (tested to agree bit for bit); with AVX-512, the fused
//! convolution, LayerNorm and LeakyReLU of [`avx512_norm`].

use super::element::Real;
use tiles::{assert_operands, convolve_portable};

#[path = "conv1d_tiles.rs"]
pub(super) mod tiles;

#[cfg(target_arch = "x86_64")]
#[path = "conv1d_simd.rs"]
pub(super) mod simd;

#[cfg(target_arch = "x86_64")]
#[path = "conv1d_fused.rs"]
pub(super) mod avx512_norm;

/// `y[t, o] = bias[o] + Σ_j a[t·step + j]·w[j, o]` for every output step t and every
/// column o of `w` (`kdim × c_pad`, `c_pad` a multiple of [`Real::LANES`]); `y` is
/// `l_out × c_pad`. Tiles of a few steps × up to four vectors of channels accumulate in
/// registers: with AVX-512 where the CPU has it and `c_pad` is a multiple of its lanes,
/// else with AVX2 and FMA where it has those. Every path adds the products of an output
/// in the same order, each with one fused multiply-add ([`Real::mul_add`] in the
/// portable path: correctly rounded, slow only on a CPU without FMA), so they agree bit
/// for bit.
pub(super) fn convolve<T: Real>(
    a: &[T],
    step: usize,
    kdim: usize,
    w: &[T],
    c_pad: usize,
    bias: &[T],
    y: &mut [T],
) {
    let l_out = y.len() / c_pad;
    assert_operands(a, step, kdim, w, c_pad, bias, l_out);
    #[cfg(target_arch = "x86_64")]
    if c_pad.is_multiple_of(T::LANES_512) && std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F (checked just above), `c_pad` is a whole number of
        // its vectors, and the slices are long enough for every tile (asserted above).
        unsafe { simd::avx512::<T::V512>(a, step, kdim, w, c_pad, bias, y) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (checked just above), and the slices are long
        // enough for every tile (asserted above).
        unsafe { simd::avx2::<T::V256>(a, step, kdim, w, c_pad, bias, y) };
        return;
    }
    convolve_portable(a, step, kdim, w, c_pad, bias, y);
}

#[cfg(test)]
mod tests {
    use super::tiles::convolve_portable;
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    type Kernel<T> = unsafe fn(&[T], usize, usize, &[T], usize, &[T], &mut [T]);

    /// The SIMD kernels this CPU has that take `c_pad` channels of `T`, each by name.
    #[cfg(target_arch = "x86_64")]
    fn simd_paths<T: Real>(c_pad: usize) -> Vec<(&'static str, Kernel<T>)> {
        let mut paths: Vec<(&'static str, Kernel<T>)> = Vec::new();
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            paths.push(("AVX2", simd::avx2::<T::V256>));
        }
        if c_pad.is_multiple_of(T::LANES_512) && std::arch::is_x86_feature_detected!("avx512f") {
            paths.push(("AVX-512", simd::avx512::<T::V512>));
        }
        paths
    }

    fn random<T: Real>(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<T> {
        (0..n)
            .map(|_| T::from_f64((rng.random::<f64>() - 0.5) * 2.0 * scale))
            .collect()
    }

    /// Every path of [`convolve`] in `T` against the portable one, bit for bit, and
    /// against the sum in float64 to `tol` relative to the sum of |products|.
    fn every_path_agrees<T: Real>(tol: f64) {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for (c_in, c_out, kernel, stride, l_out) in [
            (1usize, 16usize, 7usize, 1usize, 200usize),
            (16, 32, 5, 2, 100),
            (3, 20, 3, 1, 7),
            (2, 40, 3, 3, 5),
            (32, 32, 5, 2, 50),
            (4, 24, 3, 1, 13),
            (5, 72, 3, 1, 9),
        ] {
            let c_pad = c_out.div_ceil(T::LANES) * T::LANES;
            let kdim = kernel * c_in;
            let a: Vec<T> = random(&mut rng, ((l_out - 1) * stride + kernel) * c_in, 1.0);
            let w: Vec<T> = random(&mut rng, kdim * c_pad, 1.0);
            let bias: Vec<T> = random(&mut rng, c_pad, 1.0);
            let nan = T::from_f64(f64::NAN);
            let mut y = vec![nan; l_out * c_pad];
            let mut plain = vec![nan; l_out * c_pad];
            convolve(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut y);
            convolve_portable(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut plain);
            let bits = |v: &[T]| v.iter().map(|x| x.to_f64().to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&y),
                bits(&plain),
                "the dispatched and portable paths differ"
            );
            #[cfg(target_arch = "x86_64")]
            for (name, path) in simd_paths::<T>(c_pad) {
                let mut v = vec![nan; l_out * c_pad];
                // SAFETY: `simd_paths` lists only what this CPU has, for this `c_pad`.
                unsafe { path(&a, stride * c_in, kdim, &w, c_pad, &bias, &mut v) };
                assert_eq!(
                    bits(&v),
                    bits(&plain),
                    "the {name} and portable paths differ"
                );
            }
            for t in 0..l_out {
                for o in 0..c_pad {
                    let products = (0..kdim)
                        .map(|j| a[t * stride * c_in + j].to_f64() * w[j * c_pad + o].to_f64());
                    let want = bias[o].to_f64() + products.clone().sum::<f64>();
                    let size = bias[o].to_f64().abs() + products.map(f64::abs).sum::<f64>();
                    let got = y[t * c_pad + o].to_f64();
                    assert!((got - want).abs() <= tol * size, "{t} {o}");
                }
            }
        }
    }

    #[test]
    fn the_convolution_covers_every_step_and_channel_on_both_paths() {
        every_path_agrees::<f64>(1e-14);
    }

    #[test]
    fn the_float32_convolution_covers_every_step_and_channel_on_every_path() {
        // one rounding per product added: at most ~kdim·2⁻²⁴ of the sum of |products|
        every_path_agrees::<f32>(2e-5);
    }
}
