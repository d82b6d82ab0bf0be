//! Tests of the CNN forward pass against a plain float64 network written from the
//! formulas.

use super::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random(rng: &mut ChaCha8Rng, n: usize, scale: f32) -> Vec<f32> {
    (0..n)
        .map(|_| (rng.random::<f32>() - 0.5) * 2.0 * scale)
        .collect()
}

/// The shipped architecture with random weights (kernels 7/5/5, strides 1/2/2).
fn net(
    prepare: Prepare,
    scaling: Scaling,
    seed: u64,
) -> (ConvNet, Vec<ConvBlockWeights>, Vec<DenseWeights>) {
    net_with([16, 32, 32], 200, prepare, scaling, seed)
}

/// [`net`] with these output channels in its three blocks, for windows of `window`
/// samples.
fn net_with(
    channels: [usize; 3],
    window: usize,
    prepare: Prepare,
    scaling: Scaling,
    seed: u64,
) -> (ConvNet, Vec<ConvBlockWeights>, Vec<DenseWeights>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut blocks = Vec::new();
    let mut c_in = 1;
    for (c_out, kernel, stride) in channels
        .into_iter()
        .zip([7, 5, 5])
        .zip([1, 2, 2])
        .map(|((c, k), s)| (c, k, s))
    {
        blocks.push(ConvBlockWeights {
            weight: random(&mut rng, c_out * c_in * kernel, 0.5),
            bias: random(&mut rng, c_out, 0.1),
            c_in,
            c_out,
            kernel,
            stride,
            norm_weight: random(&mut rng, c_out, 1.0)
                .iter()
                .map(|g| 1.0 + g * 0.2)
                .collect(),
            norm_bias: random(&mut rng, c_out, 0.1),
            norm_eps: 1e-5,
        });
        c_in = c_out;
    }
    let mut head = Vec::new();
    for n_out in [64, 32, 16, 1] {
        head.push(DenseWeights {
            weight: random(&mut rng, n_out * c_in, 0.3),
            bias: random(&mut rng, n_out, 0.1),
            n_in: c_in,
            n_out,
        });
        c_in = n_out;
    }
    let built = ConvNet::new(window, prepare, scaling, 0.01, blocks.clone(), head.clone());
    let built = built.unwrap();
    (built, blocks, head)
}

/// The same network written the plain way, in float64 with index loops as the
/// formulas read: Conv1d with zero padding over `(C, L)` activations, LayerNorm,
/// LeakyReLU, mean, Linear layers.
#[allow(clippy::needless_range_loop)]
fn naive(
    x: &[f32],
    prepare: Prepare,
    scaling: Scaling,
    blocks: &[ConvBlockWeights],
    head: &[DenseWeights],
) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n;
    let mut p: Vec<f64> = x.iter().map(|&v| v as f64 - mean).collect();
    if prepare == Prepare::Detrend {
        let t: Vec<f64> = (0..x.len()).map(|i| i as f64 - (n - 1.0) / 2.0).collect();
        let tt: f64 = t.iter().map(|v| v * v).sum();
        let b: f64 = p.iter().zip(&t).map(|(a, b)| a * b).sum::<f64>() / tt;
        p.iter_mut().zip(&t).for_each(|(v, t)| *v -= b * t);
    }
    let s2 = p.iter().map(|v| v * v).sum::<f64>() / n;
    let scale = match scaling {
        Scaling::Fixed { input_scale, .. } => input_scale,
        Scaling::Spread => s2.sqrt(),
    };
    let mut act: Vec<Vec<f64>> = vec![p.iter().map(|v| v / scale).collect()];
    for b in blocks {
        let (l_in, pad) = (act[0].len() as isize, (b.kernel / 2) as isize);
        let l_out = ((l_in + 2 * pad - b.kernel as isize) / b.stride as isize + 1) as usize;
        let mut out = vec![vec![0.0; l_out]; b.c_out];
        for (o, row) in out.iter_mut().enumerate() {
            for (t, y) in row.iter_mut().enumerate() {
                *y = b.bias[o] as f64;
                for ci in 0..b.c_in {
                    for k in 0..b.kernel {
                        let src = (t * b.stride) as isize + k as isize - pad;
                        if (0..l_in).contains(&src) {
                            *y += b.weight[(o * b.c_in + ci) * b.kernel + k] as f64
                                * act[ci][src as usize];
                        }
                    }
                }
            }
        }
        for t in 0..l_out {
            let m = (0..b.c_out).map(|o| out[o][t]).sum::<f64>() / b.c_out as f64;
            let v = (0..b.c_out).map(|o| (out[o][t] - m).powi(2)).sum::<f64>() / b.c_out as f64;
            for o in 0..b.c_out {
                let y = (out[o][t] - m) / (v + b.norm_eps as f64).sqrt() * b.norm_weight[o] as f64
                    + b.norm_bias[o] as f64;
                out[o][t] = if y >= 0.0 { y } else { 0.01 * y };
            }
        }
        act = out;
    }
    let mut h: Vec<f64> = act
        .iter()
        .map(|r| r.iter().sum::<f64>() / r.len() as f64)
        .collect();
    for (i, d) in head.iter().enumerate() {
        h = (0..d.n_out)
            .map(|o| {
                let y = d.bias[o] as f64
                    + (0..d.n_in)
                        .map(|j| d.weight[o * d.n_in + j] as f64 * h[j])
                        .sum::<f64>();
                if i + 1 == head.len() || y >= 0.0 {
                    y
                } else {
                    0.01 * y
                }
            })
            .collect();
    }
    let z = h[0].clamp(-20.0, 20.0);
    match scaling {
        Scaling::Fixed { q_scale, .. } => q_scale * z.exp(),
        Scaling::Spread => s2 * z.exp(),
    }
}

#[test]
fn the_tiled_pass_equals_the_plain_network() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let fixed = Scaling::Fixed {
        input_scale: 0.1,
        q_scale: 0.01,
    };
    for (seed, prepare, scaling) in [
        (1, Prepare::Centre, fixed),
        (2, Prepare::Detrend, fixed),
        (3, Prepare::Centre, Scaling::Spread),
        (4, Prepare::Detrend, Scaling::Spread),
    ] {
        let (built, blocks, head) = net(prepare, scaling, seed);
        let mut windows = Vec::new();
        for i in 0..20 {
            let amp = 10f32.powi(-(i % 5));
            let drift: f32 = rng.random::<f32>();
            let w = random(&mut rng, 200, amp);
            windows.extend(
                w.iter()
                    .enumerate()
                    .map(|(k, v)| v + 9.8 + drift * k as f32 * 1e-3),
            );
        }
        let q = built.predict(&windows).unwrap();
        for (w, q) in windows.chunks_exact(200).zip(&q) {
            let want = naive(w, prepare, scaling, &blocks, &head);
            assert!(
                (q / want - 1.0).abs() < 1e-11,
                "{prepare:?} {scaling:?}: {q} vs {want}"
            );
        }
    }
}

#[test]
fn the_spread_net_scales_with_its_input_and_the_detrending_ignores_a_line() {
    let (built, _, _) = net(Prepare::Detrend, Scaling::Spread, 5);
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let w = random(&mut rng, 200, 0.01);
    let scaled: Vec<f32> = w.iter().map(|v| v * 4.0).collect();
    let tilted: Vec<f32> = w
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.5 + 1e-3 * k as f32)
        .collect();
    let q = built
        .predict(&[w.clone(), scaled, tilted].concat())
        .unwrap();
    assert!((q[1] / q[0] / 16.0 - 1.0).abs() < 1e-5, "{q:?}");
    assert!((q[2] / q[0] - 1.0).abs() < 1e-3, "{q:?}");
}

#[test]
fn a_stored_ramp_replaces_the_exact_one() {
    let (built, _, _) = net(Prepare::Detrend, Scaling::Spread, 13);
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let w = random(&mut rng, 200, 0.01);
    let exact = built.ramp.clone();
    let ramp32: Vec<f32> = exact.iter().map(|&t| t as f32).collect();
    let stored = built.clone().with_ramp(&ramp32).unwrap();
    let (a, b) = (
        built.predict(&w).unwrap()[0],
        stored.predict(&w).unwrap()[0],
    );
    assert!(a != b && (a / b - 1.0).abs() < 1e-5, "{a} {b}");
    let err = built
        .clone()
        .with_ramp(&ramp32[..10])
        .unwrap_err()
        .to_string();
    assert_eq!(err, "ramp: ramp has 10 values, expected 200");
}

#[test]
fn a_non_finite_sample_gives_nan_and_bad_shapes_are_named() {
    let (built, blocks, head) = net(Prepare::Centre, Scaling::Spread, 6);
    let mut w = vec![0.1f32; 400];
    w[3] = f32::NAN;
    w[250] = f32::INFINITY;
    let q = built.predict(&w).unwrap();
    assert!(q[0].is_nan() && q[1].is_nan());
    let q = built
        .clone()
        .with_precision(Precision::F32)
        .predict(&w)
        .unwrap();
    assert!(q[0].is_nan() && q[1].is_nan());
    let err = built.predict(&w[..399]).unwrap_err().to_string();
    assert!(err.starts_with("windows: 399 samples"), "{err}");
    let mut bad = blocks.clone();
    bad[1].c_in = 8;
    let err = ConvNet::new(
        200,
        Prepare::Centre,
        Scaling::Spread,
        0.01,
        bad,
        head.clone(),
    );
    assert!(err
        .unwrap_err()
        .to_string()
        .starts_with("blocks[1]: takes 8 channels"));
    let mut bad = head.clone();
    bad[3].bias.push(0.0);
    let err = ConvNet::new(
        200,
        Prepare::Centre,
        Scaling::Spread,
        0.01,
        blocks.clone(),
        bad,
    );
    assert!(err
        .unwrap_err()
        .to_string()
        .starts_with("head[3]: bias has 2 values"));
    let err = ConvNet::new(2, Prepare::Centre, Scaling::Spread, 0.01, blocks, head);
    assert!(err
        .unwrap_err()
        .to_string()
        .starts_with("window: must be >= 3"));
}

#[test]
fn the_fused_avx512_avx_and_portable_builds_agree_bit_for_bit() {
    builds_agree(Precision::F64);
    builds_agree(Precision::F32);
}

/// The fused AVX-512 blocks against the separate passes (whose convolution's every
/// path `conv1d`'s tests compare with the portable one), bit for bit, in `precision`.
fn builds_agree(precision: Precision) {
    match precision {
        Precision::F64 => builds_agree_in(|net| &net.blocks),
        Precision::F32 => builds_agree_in(|net| &net.blocks32),
    }
}

fn builds_agree_in<T: Real>(blocks: impl Fn(&ConvNet) -> &[Block<T>]) {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let fixed = Scaling::Fixed {
        input_scale: 0.1,
        q_scale: 0.01,
    };
    // the shipped nets' 16 and 32 channels (2 and 4 vectors: fused), 8 and 24 (1 and
    // 3), 40 and 12 (too many vectors, not whole vectors: the separate passes)
    #[cfg(target_arch = "x86_64")]
    {
        use super::avx512_norm::takes;
        assert!(takes::<f64>(8, 8) && takes::<f64>(16, 16) && takes::<f64>(32, 32));
        assert!(!takes::<f64>(40, 40) && !takes::<f64>(12, 12) && !takes::<f64>(12, 16));
        // float32: 16 lanes a vector, so 8 and 24 take the separate passes
        assert!(takes::<f32>(16, 16) && takes::<f32>(32, 32) && takes::<f32>(64, 64));
        assert!(!takes::<f32>(8, 8) && !takes::<f32>(24, 24) && !takes::<f32>(80, 80));
    }
    // windows of 200 samples (blocks of 200, 100 and 50 steps), 217 (217, 109, 55) and
    // 45 (45, 23, 12): the fused blocks' tiles of 14 or 6 steps, then every tile of
    // 4, 2 and 1 step for the steps left over
    let cases = [
        (10, [16, 32, 32], Prepare::Detrend, Scaling::Spread),
        (11, [16, 32, 32], Prepare::Centre, fixed),
        (12, [8, 24, 40], Prepare::Detrend, Scaling::Spread),
        (13, [12, 24, 8], Prepare::Centre, Scaling::Spread),
    ];
    for ((seed, channels, prepare, scaling), n) in cases
        .into_iter()
        .flat_map(|case| [200, 217, 45].map(|n| (case, n)))
    {
        let (built, _, _) = net_with(channels, n, prepare, scaling, seed);
        let blocks = blocks(&built);
        let mut s = built.scratch(blocks);
        // random windows over ten decades, a constant one, one with a NaN sample
        let mut windows: Vec<Vec<f32>> = (0..200)
            .map(|k| random(&mut rng, n, 10f32.powi(k % 11 - 7)))
            .collect();
        windows.push(vec![0.25; n]);
        windows.push(random(&mut rng, n, 0.3));
        windows.last_mut().unwrap()[n / 3] = f32::NAN;
        for w in &windows {
            // with AVX-512: the fused blocks; without: the AVX or portable pass again
            let fast = built.forward(blocks, w, &mut s);
            assert_eq!(
                fast.to_bits(),
                built.forward_body(blocks, w, &mut s, false).to_bits()
            );
        }
        assert!(built.forward(blocks, &windows[201], &mut s).is_nan());
    }
}

/// The largest |q₃₂ / q₆₄ - 1| over `windows` (`(n, 200)`) for `built`.
fn float32_error(built: &ConvNet, windows: &[f32]) -> f64 {
    let q64 = built.predict(windows).unwrap();
    let f32_net = built.clone().with_precision(Precision::F32);
    assert_eq!(f32_net.precision(), Precision::F32);
    let q32 = f32_net.predict(windows).unwrap();
    q64.iter()
        .zip(&q32)
        .map(|(a, b)| (b / a - 1.0).abs())
        .fold(0.0, f64::max)
}

/// `count` windows of white noise of per-sample variance q over 1e-10…1e-1 (nine
/// decades, as the shipped nets are trained on), around 0 or around an accelerometer's
/// 9.8 m/s² with a slow drift.
fn decades(rng: &mut ChaCha8Rng, count: usize, raw: bool) -> Vec<f32> {
    let mut windows = Vec::with_capacity(count * 200);
    for i in 0..count {
        let sigma = 10f64.powf(-5.0 + 4.5 * i as f64 / (count - 1) as f64);
        let (mean, drift) = if raw { (9.8, 1e-4) } else { (0.0, 0.0) };
        windows.extend((0..200).map(|k| {
            let u: f64 = rng.random::<f64>() - 0.5;
            (mean + drift * k as f64 + u * sigma * 12f64.sqrt()) as f32
        }));
    }
    windows
}

#[test]
fn the_float32_blocks_stay_within_1e_5_of_float64_over_nine_decades() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let fixed = Scaling::Fixed {
        input_scale: 0.1,
        q_scale: 0.01,
    };
    let mut worst = 0.0f64;
    for (seed, prepare, scaling) in [
        (1, Prepare::Centre, Scaling::Spread),
        (2, Prepare::Detrend, Scaling::Spread),
        (3, Prepare::Centre, fixed),
    ] {
        let (built, _, _) = net(prepare, scaling, seed);
        for raw in [false, true] {
            let windows = decades(&mut rng, 60, raw);
            let err = float32_error(&built, &windows);
            assert!(err < 1e-5, "{prepare:?} {scaling:?} raw {raw}: {err:e}");
            worst = worst.max(err);
        }
    }
    // not equal: the blocks do round in float32
    assert!(worst > 1e-9, "{worst:e}");
}

#[test]
fn the_float32_bits_do_not_depend_on_the_batch_or_the_threads() {
    let (built, _, _) = net(Prepare::Detrend, Scaling::Spread, 22);
    let built = built.with_precision(Precision::F32);
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let windows = decades(&mut rng, 37, true);
    let bits = |q: Vec<f64>| q.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    let whole = bits(built.predict(&windows).unwrap());
    let one_by_one: Vec<f64> = windows
        .chunks_exact(200)
        .map(|w| built.predict(w).unwrap()[0])
        .collect();
    assert_eq!(bits(one_by_one), whole);
    let tail = bits(built.predict(&windows[200 * 30..]).unwrap());
    assert_eq!(tail, whole[30..]);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let q = pool.install(|| built.predict(&windows).unwrap());
        assert_eq!(bits(q), whole, "{threads} threads");
    }
}
