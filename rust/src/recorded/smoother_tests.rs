//! Tests of [`super`]'s smoother passes: the nodes and intervals the forward pass keeps
//! are rebuilt bit for bit, with and without a covariance step, and a pass without
//! measurements smooths to the forward solution.

use super::data::RecordedData;
use super::epochs::Epochs;
use super::filter::{smooth_recorded_until, Recording};
use super::output::FilterOutput;
use super::stream::Stream;
use super::tests::per_sample;
use crate::cancel::Cancel;
use crate::ekf::tests::moving_state;
use crate::ekf::{Ekf, FilterConfig, Formulation, Vector15};
use crate::noise::StrategySpec;
use crate::smoother::{self, closes, Covariances, Forward, ForwardLog};
use nalgebra::Vector3;

/// A recording's arrays: IMU rows, their times, DVL rows, their times.
type Arrays = (Vec<[f64; 6]>, Vec<f64>, Vec<[f64; 3]>, Vec<f64>);

/// A moving pass of `n` steps with a DVL row every second.
fn moving_pass(n: usize) -> Arrays {
    let imu = (0..n)
        .map(|k| {
            let wobble = (k as f64 * 0.07).sin();
            [0.02 * wobble, -0.01, -9.79, 1e-4, 2e-4 * wobble, 2e-4]
        })
        .collect();
    let imu_time = (1..=n).map(|k| k as f64 * 0.01).collect();
    let dvl_time: Vec<f64> = (1..=n / 100).map(|k| k as f64).collect();
    let dvl = dvl_time
        .iter()
        .map(|t| [0.5 + 0.01 * t, 0.01, -0.002 * t])
        .collect();
    (imu, imu_time, dvl, dvl_time)
}

/// The every-epoch forward pass over `arrays` with the q schedule `q` (times \[s\],
/// rows), keeping the smoother's nodes.
fn forward_keeping_nodes(
    arrays: &Arrays,
    (q_time, q_values): (&[f64], &[[f64; 6]]),
    cfg: &FilterConfig,
    spec: &StrategySpec,
) -> (FilterOutput, Vec<smoother::Node>) {
    let (imu, imu_time, dvl, dvl_time) = arrays;
    let data = RecordedData {
        imu,
        imu_time,
        streams: vec![Stream::dvl(dvl, dvl_time, &FilterConfig::default())],
        q_time,
        q_values,
        ..RecordedData::default()
    };
    let mut strategy = spec.build(cfg.bias_psd());
    let mut log = ForwardLog::default();
    let out = Recording::of(&data, cfg)
        .forward(
            strategy.as_mut(),
            Epochs::All,
            Some(&mut log),
            &Cancel::default(),
        )
        .unwrap();
    (out, log.nodes.0)
}

/// The forward solution `out` over `arrays`, as the backward pass reads it.
fn forward_of<'a>(arrays: &'a Arrays, out: &'a FilterOutput) -> Forward<'a> {
    Forward {
        imu: &arrays.0,
        imu_time: &arrays.1,
        t0: 0.0,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &[],
        sigma: &out.sigma,
        calibration_sigma: &[],
        dt: None,
    }
}

/// The smoother's nodes: for every strategy (the noise changing at updates, and at
/// q schedule rows between them), each interval rebuilt from its first node goes
/// through the forward pass's covariances, bit for bit (its σ at every epoch).
#[test]
fn smoother_intervals_rebuild_the_forward_covariances_exactly() {
    let arrays = moving_pass(600);
    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let cases = [
        (StrategySpec::Constant { q }, vec![], vec![]),
        (
            StrategySpec::Mehra {
                window: 2,
                prior_q: q,
            },
            vec![],
            vec![],
        ),
        (
            StrategySpec::Adaptive {
                window: 2,
                prior_q: q,
            },
            vec![],
            vec![],
        ),
        (
            StrategySpec::External { prior_q: q },
            vec![1.504, 3.0, 4.25],
            vec![[4e-4; 6], q, [2e-4; 6]],
        ),
    ];
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        let cfg = FilterConfig {
            formulation,
            ..per_sample()
        };
        for (spec, q_time, q_values) in &cases {
            let (out, nodes) = forward_keeping_nodes(&arrays, (q_time, q_values), &cfg, spec);
            // A node at the start, at each of the 6 DVL epochs (the last one the
            // end), and at each q row that fell between them.
            assert_eq!(nodes.first().unwrap().epoch, 0);
            assert_eq!(nodes.last().unwrap().epoch, 600);
            let updates = nodes
                .iter()
                .filter(|n| n.correction != Vector15::zeros())
                .count();
            assert_eq!(updates, 6, "{spec:?}");
            assert_eq!(
                nodes.len(),
                7 + usize::from(!q_time.is_empty()) * 2,
                "{spec:?}"
            );
            let forward = forward_of(&arrays, &out);
            let mut closes = Vec::new();
            for pair in nodes.windows(2) {
                let (a, b) = (&pair[0], &pair[1]);
                let (every, vel_b) = (|_| true, out.nav[b.epoch]);
                let c = &Cancel::default();
                closes::samples::<15>(
                    &forward,
                    &cfg,
                    (a, b.epoch),
                    (0, cfg.coordinates().at(&vel_b)),
                    &every,
                    &mut closes,
                    c,
                )
                .unwrap();
                assert_eq!(closes.len(), b.epoch - a.epoch);
                for close in &closes {
                    let at = close.epoch;
                    if at == b.epoch && b.correction != Vector15::zeros() {
                        continue; // σ after the update there
                    }
                    let zero = Vector3::zeros();
                    let mut ekf = Ekf::new(&cfg, out.nav[at], zero, zero).unwrap();
                    ekf.p = close.p_prior.unwrap();
                    assert_eq!(ekf.sigma(), out.sigma[at], "{spec:?} {formulation:?} {at}");
                }
            }
        }
    }
}

/// Under a covariance step the smoother's grid is the steps' closes: for every
/// strategy and both formulations (q rows falling inside steps, where a node carries
/// the step under way), each stretch between nodes rebuilt from its first node closes
/// where the forward pass closed, with its covariances bit for bit.
#[test]
fn covariance_step_closes_are_rebuilt_exactly() {
    let arrays = moving_pass(600);
    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let cases = [
        (StrategySpec::Constant { q }, vec![], vec![]),
        (
            StrategySpec::Mehra {
                window: 2,
                prior_q: q,
            },
            vec![],
            vec![],
        ),
        (
            StrategySpec::External { prior_q: q },
            vec![1.504, 3.0, 4.25],
            vec![[4e-4; 6], q, [2e-4; 6]],
        ),
    ];
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        let cfg = FilterConfig {
            formulation,
            covariance_step: 0.07,
            ..per_sample()
        };
        for (spec, q_time, q_values) in &cases {
            let (out, nodes) = forward_keeping_nodes(&arrays, (q_time, q_values), &cfg, spec);
            let inside = nodes.iter().filter(|n| n.step.is_some()).count();
            assert_eq!(inside, 2 * usize::from(!q_time.is_empty()), "{spec:?}");
            let forward = forward_of(&arrays, &out);
            let (mut closes, mut rebuilt) = (vec![0], Vec::new());
            for pair in nodes.windows(2) {
                let (a, b) = (&pair[0], &pair[1]);
                closes::steps::<15>(&forward, &cfg, (a, b), &mut rebuilt, &Cancel::default())
                    .unwrap();
                for close in &rebuilt {
                    closes.push(close.epoch);
                    if close.epoch == b.epoch && b.correction != Vector15::zeros() {
                        continue; // σ after the update there
                    }
                    let zero = Vector3::zeros();
                    let at = close.epoch;
                    let mut ekf = Ekf::new(&cfg, out.nav[at], zero, zero).unwrap();
                    ekf.p = close.p_prior.unwrap();
                    assert_eq!(ekf.sigma(), out.sigma[at], "{spec:?} {formulation:?} {at}");
                }
            }
            // Closes every 7 samples, restarting at each DVL epoch (100, 200, ...).
            let want: Vec<usize> = (0..=600)
                .filter(|k| k % 100 == 0 || (k % 100) % 7 == 0)
                .collect();
            assert_eq!(closes, want, "{spec:?}");
        }
    }
}

/// The Monte Carlo's way to the smoothed covariance (σ where asked) gives the σ of the
/// way that computes it everywhere and the same mean; epochs it is not asked for stay
/// NaN. Every sample (Λ carried as the product of the transitions where it is not read:
/// to rounding) and under a covariance step (σ interpolated inside a step from the
/// closes on either side, which are then computed where asked: bit for bit), with q
/// schedule rows that put nodes inside a step.
#[test]
fn covariances_where_asked_equal_the_step_by_step_ones() {
    let arrays = moving_pass(400);
    let q = [1e-4; 6];
    let (q_time, q_values) = (vec![0.554, 1.5, 2.873], vec![[4e-4; 6], q, [2e-4; 6]]);
    for (covariance_step, external) in [(0.0, false), (0.07, false), (0.1, true), (0.07, true)] {
        let cfg = FilterConfig {
            covariance_step,
            ..per_sample()
        };
        let (spec, q_time, q_values) = if external {
            (
                StrategySpec::External { prior_q: q },
                &q_time[..],
                &q_values[..],
            )
        } else {
            (StrategySpec::Constant { q }, &[][..], &[][..])
        };
        let (out, nodes) = forward_keeping_nodes(&arrays, (q_time, q_values), &cfg, &spec);
        let (forward, cancel) = (forward_of(&arrays, &out), Cancel::default());
        let every = smoother::smooth(&forward, &cfg, &nodes, Covariances::Every, &cancel);
        let odd = |k: usize| k % 13 == 3;
        let some = smoother::smooth(&forward, &cfg, &nodes, Covariances::Where(&odd), &cancel);
        let (every, some) = (every.unwrap(), some.unwrap());
        assert_eq!(every.nav, some.nav);
        let inside_a_step = nodes.iter().any(|n| n.step.is_some());
        assert_eq!(inside_a_step, external, "{covariance_step}");
        for (k, (a, b)) in every.sigma.iter().zip(&some.sigma).enumerate() {
            if covariance_step > 0.0 && odd(k) {
                assert_eq!(a, b, "{covariance_step} {k}");
            } else if odd(k) {
                for (x, y) in a.iter().zip(b) {
                    assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-12), "{k}: {x} {y}");
                }
            } else {
                assert!(b.iter().all(|y| y.is_nan()), "{covariance_step} {k}");
            }
        }
    }
}

/// The smoothed pass of constant q over the IMU rows and times `imu`, with the DVL
/// rows and times `dvl` (none: a pass without measurements), from `moving_state`.
fn smoothed_pass(
    (imu, imu_time): (&[[f64; 6]], &[f64]),
    (dvl, dvl_time): (&[[f64; 3]], &[f64]),
    cfg: &FilterConfig,
) -> crate::error::Result<FilterOutput> {
    let data = RecordedData {
        imu,
        imu_time,
        streams: vec![Stream::dvl(dvl, dvl_time, &FilterConfig::default())],
        ..RecordedData::default()
    };
    let spec = StrategySpec::Constant { q: [1e-4; 6] };
    smooth_recorded_until(
        &data,
        moving_state(),
        [0.0; 6],
        cfg,
        spec.build(cfg.bias_psd()).as_mut(),
        Epochs::All,
        &Cancel::default(),
    )
}

/// Without a measurement there is nothing to smooth: the smoothed solution is the
/// forward one. With them, the smoothed σ is below the forward σ inside the pass
/// and equal at its end, the DVL calibration states' too.
#[test]
fn smoothing_without_measurements_changes_nothing() {
    let (imu, imu_time, dvl, dvl_time) = moving_pass(300);
    let cfg = per_sample();
    let pass = |dvl: &[[f64; 3]], dvl_time: &[f64], cfg: &FilterConfig| {
        smoothed_pass((&imu, &imu_time), (dvl, dvl_time), cfg)
    };
    let bare = pass(&[], &[], &cfg).unwrap();
    let s = bare.smoothed.unwrap();
    assert_eq!(s.nav, bare.nav);
    assert_eq!(s.bias, bare.bias);
    for (a, b) in s.sigma.iter().zip(&bare.sigma) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12 * y, "{x} {y}");
        }
    }
    let aided = pass(&dvl, &dvl_time, &cfg).unwrap();
    let s = aided.smoothed.unwrap();
    assert_eq!(s.sigma[300], aided.sigma[300]);
    assert!(s.sigma[150][3] < 0.99 * aided.sigma[150][3]);
    assert!(s
        .sigma
        .iter()
        .zip(&aided.sigma)
        .all(|(a, b)| a.iter().zip(b).all(|(x, y)| *x <= y * (1.0 + 1e-12))));
    // With the DVL calibration states the 19 are smoothed: their σ too, never above
    // the forward one, and equal at the end.
    let calibrated = FilterConfig {
        dvl_calibration: Some(crate::ekf::calibration::CalibrationConfig::default()),
        ..per_sample()
    };
    let aided = pass(&dvl, &dvl_time, &calibrated).unwrap();
    let s = aided.smoothed.unwrap();
    assert_eq!(s.calibration.len(), aided.calibration.len());
    assert_eq!(s.calibration_sigma[300], aided.calibration_sigma[300]);
    assert!(s.calibration[150] != aided.calibration[150]);
    assert!(s
        .calibration_sigma
        .iter()
        .zip(&aided.calibration_sigma)
        .all(|(a, b)| a.iter().zip(b).all(|(x, y)| *x <= y * (1.0 + 1e-12))));
}

/// The second-order heading term (`FilterConfig::heading_second_order`) is rebuilt
/// between nodes as the forward pass carried it: without measurements the smoothed σ
/// is the forward σ (it would not be with the term missing from the rebuilt priors),
/// with and without a covariance step; aided, never above the forward σ and equal at
/// the end. The term widens the horizontal position σ where the heading is uncertain.
#[test]
fn the_second_order_heading_term_is_rebuilt_as_the_forward_pass_carried_it() {
    let (imu, imu_time, dvl, dvl_time) = moving_pass(300);
    let pass = |dvl: &[[f64; 3]], dvl_time: &[f64], cfg: &FilterConfig| {
        smoothed_pass((&imu, &imu_time), (dvl, dvl_time), cfg).unwrap()
    };
    let mut p0_sigma = crate::ekf::DEFAULT_P0_SIGMA;
    p0_sigma[8] = 0.3; // 17° of heading σ
    for covariance_step in [0.0, 0.1] {
        let linear = FilterConfig {
            covariance_step,
            p0_sigma,
            ..FilterConfig::default()
        };
        let cfg = FilterConfig {
            heading_second_order: true,
            ..linear.clone()
        };
        let bare = pass(&[], &[], &cfg);
        let s = bare.smoothed.as_ref().unwrap();
        for (a, b) in s.sigma.iter().zip(&bare.sigma) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 1e-12 * y, "{covariance_step}: {x} {y}");
            }
        }
        let without = pass(&[], &[], &linear);
        let (end, end_linear) = (bare.sigma[300], without.sigma[300]);
        assert!(end[1] > 1.01 * end_linear[1], "{end:?} {end_linear:?}");
        let aided = pass(&dvl, &dvl_time, &cfg);
        let s = aided.smoothed.unwrap();
        assert_eq!(s.sigma[300], aided.sigma[300]);
        assert!(s
            .sigma
            .iter()
            .zip(&aided.sigma)
            .all(|(a, b)| a.iter().zip(b).all(|(x, y)| *x <= y * (1.0 + 1e-12))));
    }
}
