//! Tests of [`super`]: one filter pass over recorded arrays, the smoother's nodes and
//! intervals, the covariances kept at chosen times.

use super::*;
use crate::ekf::tests::moving_state;
use crate::ekf::Formulation;
use crate::noise::StrategySpec;

/// The filter these tests were written for: the covariance propagated at every IMU
/// sample (the default steps it every 0.1 s; `ekf::interval` and the Python tests cover
/// that).
fn per_sample() -> FilterConfig {
    FilterConfig {
        covariance_step: 0.0,
        ..FilterConfig::default()
    }
}

#[test]
fn recorded_data_is_validated() {
    let imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 3];
    let data = |imu_time: &'static [f64], t0: f64| -> Result<()> {
        RecordedData {
            imu: &imu[..imu_time.len().min(3)],
            imu_time,
            dvl: &[],
            dvl_time: &[],
            t0,
            q_time: &[],
            q_values: &[],
            covariance_time: &[],
            ..RecordedData::default()
        }
        .validate()
    };
    assert!(data(&[0.01, 0.02, 0.03], 0.0).is_ok());
    let err = data(&[0.01, 0.01, 0.03], 0.0).unwrap_err();
    assert!(
        matches!(&err, Error::InvalidArgument { arg, .. } if arg == "imu_time"),
        "{err}"
    );
    let err = data(&[0.01, 0.02, 0.03], 0.01).unwrap_err();
    assert!(err.to_string().contains("positive time step"), "{err}");
    let imu4 = [[0.0; 6]; 4];
    let err = RecordedData {
        imu: &imu4,
        imu_time: &[0.1, 0.2],
        dvl: &[],
        dvl_time: &[],
        t0: 0.0,
        q_time: &[],
        q_values: &[],
        covariance_time: &[],
        ..RecordedData::default()
    }
    .validate()
    .unwrap_err();
    assert!(err.to_string().starts_with("imu_time"), "{err}");
}

/// IMU rows alone from `t0` = 0: no DVL, no q schedule.
fn imu_only<'a>(imu: &'a [[f64; 6]], imu_time: &'a [f64]) -> RecordedData<'a> {
    RecordedData {
        imu,
        imu_time,
        dvl: &[],
        dvl_time: &[],
        t0: 0.0,
        q_time: &[],
        q_values: &[],
        covariance_time: &[],
        ..RecordedData::default()
    }
}

#[test]
fn a_set_cancel_flag_stops_a_pass() {
    let imu = vec![[0.01, 0.0, -9.79, 0.0, 1e-4, 0.0]; 10];
    let imu_time: Vec<f64> = (1..=10).map(|k| k as f64 * 0.01).collect();
    let data = imu_only(&imu, &imu_time);
    let cfg = per_sample();
    let pass = |cancel: &Cancel| {
        let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(cfg.bias_psd());
        let bias = [0.0; 6];
        filter_recorded_until(
            &data,
            moving_state(),
            bias,
            &cfg,
            strategy.as_mut(),
            Epochs::All,
            cancel,
        )
    };
    assert_eq!(pass(&Cancel::default()).unwrap().time.len(), 11);
    let cancel = Cancel::default();
    cancel.cancel();
    assert_eq!(pass(&cancel).unwrap_err(), Error::Cancelled);
}

/// A pass that keeps only the last epoch makes the same updates and ends in the same
/// estimate as one that keeps every epoch, with and without the calibration states.
#[test]
fn keeping_the_last_epoch_changes_no_update_and_no_final_estimate() {
    let n = 250;
    let imu = vec![[0.02, -0.01, -9.79, 1e-4, 0.0, 2e-4]; n];
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let dvl = vec![[0.5, 0.01, 0.0]; 4];
    let dvl_time = [0.5, 1.0, 1.5, 2.0];
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        dvl: &dvl,
        dvl_time: &dvl_time,
        t0: 0.0,
        q_time: &[],
        q_values: &[],
        covariance_time: &[],
        ..RecordedData::default()
    };
    for calibration in [
        None,
        Some(super::super::calibration::CalibrationConfig::default()),
    ] {
        let cfg = FilterConfig {
            dvl_calibration: calibration,
            ..per_sample()
        };
        let pass = |epochs| {
            let spec = StrategySpec::Constant { q: [1e-4; 6] };
            let mut strategy = spec.build(cfg.bias_psd());
            filter_recorded_until(
                &data,
                moving_state(),
                [0.0; 6],
                &cfg,
                strategy.as_mut(),
                epochs,
                &Cancel::default(),
            )
            .unwrap()
        };
        let (all, last) = (pass(Epochs::All), pass(Epochs::Last));
        assert_eq!(all.time.len(), n + 1);
        assert_eq!(last.time, [all.time[n]]);
        assert_eq!(last.nav, [all.nav[n]]);
        assert_eq!(last.bias, [all.bias[n]]);
        assert_eq!(last.sigma, [all.sigma[n]]);
        let k = usize::from(calibration.is_some());
        assert_eq!(last.calibration.len(), k);
        assert_eq!(
            last.calibration,
            all.calibration[all.calibration.len() - k..]
        );
        assert_eq!(last.calibration_sigma.len(), k);
        assert_eq!(last.final_covariance, all.final_covariance);
        assert_eq!(last.dvl_epoch, all.dvl_epoch);
        for (a, b) in all.updates.iter().zip(&last.updates) {
            let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
            assert_eq!((a.innovation, a.s, a.nis), (b.innovation, b.s, b.nis));
        }
    }
}

/// The covariance is kept at the epoch nearest each asked-for time, after that
/// epoch's update (its diagonal is the σ recorded there), the pass otherwise
/// unchanged; times outside the run are None, and a time that is not increasing
/// is refused by name.
#[test]
fn covariances_are_kept_at_the_epochs_nearest_the_times_asked_for() {
    let n = 250;
    let imu = vec![[0.02, -0.01, -9.79, 1e-4, 0.0, 2e-4]; n];
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let dvl = vec![[0.5, 0.01, 0.0]; 4];
    let dvl_time = [0.5, 1.0, 1.5, 2.0];
    let times = [-0.1, -0.004, 0.004, 0.996, 1.0, 1.2449, 2.504, 2.6];
    let cfg = per_sample();
    let pass = |covariance_time: &[f64]| {
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl: &dvl,
            dvl_time: &dvl_time,
            covariance_time,
            ..RecordedData::default()
        };
        let spec = StrategySpec::Constant { q: [1e-4; 6] };
        filter_recorded(
            &data,
            moving_state(),
            [0.0; 6],
            &cfg,
            spec.build(cfg.bias_psd()).as_mut(),
        )
    };
    let plain = pass(&[]).unwrap();
    let kept = pass(&times).unwrap();
    assert!(plain.covariances.is_empty() && plain.covariance_epoch.is_empty());
    assert_eq!(kept.sigma, plain.sigma);
    assert_eq!(kept.final_covariance, plain.final_covariance);
    let epochs = [
        None,
        Some(0),
        Some(0),
        Some(100),
        Some(100),
        Some(124),
        Some(250),
        None,
    ];
    assert_eq!(kept.covariance_epoch, epochs);
    for (p, epoch) in kept.covariances.iter().zip(epochs) {
        let Some(k) = epoch else {
            assert!(p.is_none());
            continue;
        };
        let p = p.unwrap();
        assert_eq!(p, p.transpose());
        let sigma: [f64; 15] = std::array::from_fn(|i| p[(i, i)].sqrt());
        assert_eq!(sigma, plain.sigma[k], "epoch {k}");
    }
    // Epoch 100 (t = 1.0 s) holds the covariance after its DVL update.
    let p100 = kept.covariances[3].unwrap();
    assert!(p100[(3, 3)].sqrt() < plain.sigma[99][3]);
    assert_eq!(kept.covariances[6].unwrap(), plain.final_covariance);
    let err = pass(&[1.0, 1.0]).unwrap_err();
    assert!(err.to_string().starts_with("covariance_time"), "{err}");
    let err = pass(&[f64::NAN]).unwrap_err();
    assert!(err.to_string().starts_with("covariance_time"), "{err}");
}

/// A q schedule switches an external strategy's q at the epoch nearest each row's
/// time, and nothing else: before the switch the run equals the prior's constant
/// run bit for bit, from it on the new q's constant run's covariance growth.
#[test]
fn q_schedule_sets_external_q_from_its_epoch_on() {
    let n = 300;
    let imu = vec![[0.01, 0.0, -9.79, 0.0, 1e-4, 0.0]; n];
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let dvl = vec![[0.0; 3]; 3];
    let dvl_time = [0.995, 2.0, 3.004];
    let cfg = per_sample();
    let init = moving_state();
    let (qa, qb) = ([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6], [4e-4; 6]);
    let run = |spec: StrategySpec, q_time: &[f64], q_values: &[[f64; 6]]| {
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl: &dvl,
            dvl_time: &dvl_time,
            t0: 0.0,
            q_time,
            q_values,
            covariance_time: &[],
            ..RecordedData::default()
        };
        filter_recorded(
            &data,
            init,
            [0.0; 6],
            &cfg,
            spec.build(cfg.bias_psd()).as_mut(),
        )
    };
    let constant_a = run(StrategySpec::Constant { q: qa }, &[], &[]).unwrap();
    let external = |q_time: &[f64], q_values: &[[f64; 6]]| {
        run(StrategySpec::External { prior_q: qa }, q_time, q_values).unwrap()
    };
    // Setting the prior's own q at t0 changes nothing.
    assert_eq!(external(&[0.0], &[qa]).sigma, constant_a.sigma);
    // Switching at 1.504 s (nearest epoch 1.50): the first 150 steps are the prior's.
    let switched = external(&[1.504], &[qb]);
    assert_eq!(switched.sigma[..=150], constant_a.sigma[..=150]);
    assert!(switched.sigma[151][3] > constant_a.sigma[151][3]);
    // A schedule with a strategy that does not take q from outside is refused.
    let err = run(StrategySpec::Constant { q: qa }, &[0.0], &[qa]).unwrap_err();
    assert!(err.to_string().starts_with("strategy"), "{err}");
    let err = run(
        StrategySpec::External { prior_q: qa },
        &[1.0, 0.5],
        &[qa, qb],
    )
    .unwrap_err();
    assert!(err.to_string().starts_with("q_time"), "{err}");
    let err = run(StrategySpec::External { prior_q: qa }, &[1.0], &[[-1.0; 6]]).unwrap_err();
    assert!(err.to_string().starts_with("q: row 0"), "{err}");
}

/// IMU rows, their times, DVL rows, their times.
type Pass = (Vec<[f64; 6]>, Vec<f64>, Vec<[f64; 3]>, Vec<f64>);

/// A moving pass of `n` steps with a DVL row every second.
fn moving_pass(n: usize) -> Pass {
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

/// The smoother's nodes: for every strategy (the noise changing at updates, and at
/// q schedule rows between them), each interval rebuilt from its first node goes
/// through the forward pass's covariances, bit for bit (its σ at every epoch).
#[test]
fn smoother_intervals_rebuild_the_forward_covariances_exactly() {
    let (imu, imu_time, dvl, dvl_time) = moving_pass(600);
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
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl: &dvl,
                dvl_time: &dvl_time,
                q_time,
                q_values,
                ..RecordedData::default()
            };
            let mut strategy = spec.build(cfg.bias_psd());
            let mut nodes = Nodes::default();
            let out = forward_pass(
                &data,
                moving_state(),
                [0.0; 6],
                &cfg,
                strategy.as_mut(),
                Epochs::All,
                Some(&mut nodes),
                &Cancel::default(),
            )
            .unwrap();
            let nodes = nodes.0;
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
            let forward = Forward {
                imu: &imu,
                imu_time: &imu_time,
                t0: 0.0,
                nav: &out.nav,
                bias: &out.bias,
                calibration: &[],
                dt: None,
            };
            for pair in nodes.windows(2) {
                let interval = smoother::Interval::rebuild(
                    &forward,
                    &cfg,
                    &pair[0],
                    pair[1].epoch,
                    None,
                    &Cancel::default(),
                )
                .unwrap();
                let (a, b) = (pair[0].epoch, pair[1].epoch);
                assert_eq!(interval.p.len(), b - a);
                for (k, p) in interval.p.iter().enumerate() {
                    let zero = Vector3::zeros();
                    let mut ekf = Ekf::new(&cfg, out.nav[a + k], zero, zero).unwrap();
                    ekf.p = *p;
                    let at = a + k;
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
    let (imu, imu_time, dvl, dvl_time) = moving_pass(600);
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
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl: &dvl,
                dvl_time: &dvl_time,
                q_time,
                q_values,
                ..RecordedData::default()
            };
            let mut strategy = spec.build(cfg.bias_psd());
            let mut nodes = Nodes::default();
            let out = forward_pass(
                &data,
                moving_state(),
                [0.0; 6],
                &cfg,
                strategy.as_mut(),
                Epochs::All,
                Some(&mut nodes),
                &Cancel::default(),
            )
            .unwrap();
            let nodes = nodes.0;
            let inside = nodes.iter().filter(|n| n.interval.is_some()).count();
            assert_eq!(inside, 2 * usize::from(!q_time.is_empty()), "{spec:?}");
            let forward = Forward {
                imu: &imu,
                imu_time: &imu_time,
                t0: 0.0,
                nav: &out.nav,
                bias: &out.bias,
                calibration: &[],
                dt: None,
            };
            let mut closes = vec![0];
            for pair in nodes.windows(2) {
                let (a, b) = (&pair[0], &pair[1]);
                let rebuilt =
                    smoother::steps::rebuild(&forward, &cfg, a, b, &Cancel::default()).unwrap();
                for close in &rebuilt {
                    closes.push(close.epoch);
                    if close.epoch == b.epoch && b.correction != Vector15::zeros() {
                        continue; // σ after the update there
                    }
                    let zero = Vector3::zeros();
                    let at = close.epoch;
                    let mut ekf = Ekf::new(&cfg, out.nav[at], zero, zero).unwrap();
                    ekf.p = close.p_prior;
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

/// The Monte Carlo's way to the smoothed covariance (the interval's forward product,
/// inverted where read) gives the σ of the step-by-step way, to rounding, and the
/// same mean; epochs it is not asked for stay NaN.
#[test]
fn covariances_where_asked_equal_the_step_by_step_ones() {
    let (imu, imu_time, dvl, dvl_time) = moving_pass(400);
    let cfg = per_sample();
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        dvl: &dvl,
        dvl_time: &dvl_time,
        ..RecordedData::default()
    };
    let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(cfg.bias_psd());
    let mut nodes = Nodes::default();
    let cancel = Cancel::default();
    let out = forward_pass(
        &data,
        moving_state(),
        [0.0; 6],
        &cfg,
        strategy.as_mut(),
        Epochs::All,
        Some(&mut nodes),
        &cancel,
    )
    .unwrap();
    let forward = Forward {
        imu: &imu,
        imu_time: &imu_time,
        t0: 0.0,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &[],
        dt: None,
    };
    let every = smoother::smooth(&forward, &cfg, &nodes.0, Covariances::Every, &cancel);
    let odd = |k: usize| k % 7 == 3;
    let some = smoother::smooth(&forward, &cfg, &nodes.0, Covariances::Where(&odd), &cancel);
    let (every, some) = (every.unwrap(), some.unwrap());
    assert_eq!(every.nav, some.nav);
    let nodes: Vec<usize> = nodes.0.iter().map(|n| n.epoch).collect();
    for (k, (a, b)) in every.sigma.iter().zip(&some.sigma).enumerate() {
        if odd(k) || nodes.contains(&k) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-12), "{k}: {x} {y}");
            }
        } else {
            assert!(b.iter().all(|y| y.is_nan()), "{k}");
        }
    }
}

/// Without a measurement there is nothing to smooth: the smoothed solution is the
/// forward one. With them, the smoothed σ is below the forward σ inside the pass
/// and equal at its end, the DVL calibration states' too.
#[test]
fn smoothing_without_measurements_changes_nothing() {
    let (imu, imu_time, dvl, dvl_time) = moving_pass(300);
    let cfg = per_sample();
    let spec = StrategySpec::Constant { q: [1e-4; 6] };
    let pass = |dvl: &[[f64; 3]], dvl_time: &[f64], cfg: &FilterConfig| {
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl,
            dvl_time,
            ..RecordedData::default()
        };
        smooth_recorded_until(
            &data,
            moving_state(),
            [0.0; 6],
            cfg,
            spec.build(cfg.bias_psd()).as_mut(),
            &Cancel::default(),
        )
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
        dvl_calibration: Some(super::super::calibration::CalibrationConfig::default()),
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

/// The text `tests/test_core_rules.py` expects from `pronet.run_filter`.
#[test]
fn a_start_beyond_89_degrees_is_refused_naming_lla0() {
    let imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 2];
    let data = imu_only(&imu, &[0.01, 0.02]);
    let cfg = per_sample();
    let init = NavState {
        lla: Vector3::new(-1.56, 0.0, 0.0),
        vel: Vector3::zeros(),
        dcm: nalgebra::Matrix3::identity(),
    };
    let spec = crate::noise::StrategySpec::Constant { q: [1e-4; 6] };
    let err = filter_recorded(
        &data,
        init,
        [0.0; 6],
        &cfg,
        spec.build(cfg.bias_psd()).as_mut(),
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "lla0: latitude must be within ±89° (given in radians; NED is singular at the poles)"
    );
}
