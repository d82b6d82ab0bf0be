//! Tests of [`super`]: one filter pass over recorded arrays and the covariances kept at
//! chosen times (the smoother's nodes and intervals: `smoother_tests.rs`).

use super::data::RecordedData;
use super::epochs::Epochs;
use super::filter::{filter_recorded, filter_recorded_until};
use super::stream::Stream;
use crate::cancel::Cancel;
use crate::ekf::tests::moving_state;
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};
use crate::mechanization::NavState;
use crate::noise::StrategySpec;
use nalgebra::Vector3;

/// The filter these tests were written for: the covariance propagated at every IMU
/// sample (the default steps it every 0.1 s; `ekf::step` and the Python tests cover
/// that).
pub(super) fn per_sample() -> FilterConfig {
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
            t0,
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
        streams: vec![Stream::dvl(&[], &[], &FilterConfig::default())],
        ..RecordedData::default()
    }
    .validate()
    .unwrap_err();
    assert!(err.to_string().starts_with("imu_time"), "{err}");
    // A row not finite, or beyond any IMU's range (1e4 m/s², 1e3 rad/s), is refused
    // by its index before anything is integrated.
    for (col, value, said) in [
        (1, f64::NAN, "row 2 is not finite"),
        (0, 1e300, "row 2 is beyond any IMU's range"),
        (5, -2e3, "row 2 is beyond any IMU's range"),
    ] {
        let mut bad = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 3];
        bad[2][col] = value;
        let err = RecordedData {
            imu: &bad,
            imu_time: &[0.01, 0.02, 0.03],
            ..RecordedData::default()
        }
        .validate()
        .unwrap_err();
        assert!(
            err.to_string().starts_with(&format!("imu: {said}")),
            "{err}"
        );
    }
    let mut edge = [[0.0; 6]; 3];
    edge[0] = [1e4, -1e4, 0.0, 1e3, -1e3, 0.0]; // at the bounds: a reading
    let at_bounds = RecordedData {
        imu: &edge,
        imu_time: &[0.01, 0.02, 0.03],
        ..RecordedData::default()
    };
    assert!(at_bounds.validate().is_ok());
}

#[test]
fn a_non_finite_imu_value_is_named_by_its_row() {
    let time = [0.01, 0.02, 0.03, 0.04];
    for (row, col, bad) in [
        (0, 0, f64::NAN),
        (2, 5, f64::INFINITY),
        (3, 2, f64::NEG_INFINITY),
    ] {
        let mut imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 4];
        imu[row][col] = bad;
        let err = imu_only(&imu, &time).validate().unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with(&format!("imu: row {row} is not finite: ")),
            "{text}"
        );
    }
}

/// IMU rows alone from `t0` = 0: no DVL, no q schedule.
fn imu_only<'a>(imu: &'a [[f64; 6]], imu_time: &'a [f64]) -> RecordedData<'a> {
    RecordedData {
        imu,
        imu_time,
        streams: vec![Stream::dvl(&[], &[], &FilterConfig::default())],
        ..RecordedData::default()
    }
}

/// One pass over `data` from [`moving_state`] with zero biases, the filter `cfg` and a
/// constant `q`, keeping `epochs`.
fn pass_with(
    data: &RecordedData<'_>,
    cfg: &FilterConfig,
    q: [f64; 6],
    epochs: Epochs,
) -> super::FilterOutput {
    let mut strategy = StrategySpec::Constant { q }.build(cfg.bias_psd());
    let (state, cancel) = (moving_state(), Cancel::default());
    filter_recorded_until(
        data,
        state,
        [0.0; 6],
        cfg,
        strategy.as_mut(),
        epochs,
        &cancel,
    )
    .unwrap()
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
        streams: vec![Stream::dvl(&dvl, &dvl_time, &FilterConfig::default())],
        ..RecordedData::default()
    };
    for calibration in [
        None,
        Some(crate::ekf::calibration::CalibrationConfig::default()),
    ] {
        let cfg = FilterConfig {
            dvl_calibration: calibration,
            ..per_sample()
        };
        let pass = |epochs| pass_with(&data, &cfg, [1e-4; 6], epochs);
        let (all, last) = (pass(Epochs::All), pass(Epochs::Last));
        assert_eq!(all.time.len(), n + 1);
        assert_eq!(last.time, [all.time[n]]);
        assert_eq!(last.solution(0), all.solution(n));
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
        let (dvl_all, dvl_last) = (&all.streams[0], &last.streams[0]);
        assert_eq!(dvl_last.epoch, dvl_all.epoch);
        for (a, b) in dvl_all.updates.iter().zip(&dvl_last.updates) {
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
            streams: vec![Stream::dvl(&dvl, &dvl_time, &FilterConfig::default())],
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
            streams: vec![Stream::dvl(&dvl, &dvl_time, &FilterConfig::default())],
            t0: 0.0,
            q_time,
            q_values,
            covariance_time: &[],
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

/// The heading is watched at every epoch where P stands, kept or not: a pass that
/// keeps only its last epoch tells the same largest heading σ and the same first time
/// past 5° as one that keeps every epoch, never less than any kept σ, and, with P
/// propagated at every sample, the kept σ's.
#[test]
fn the_heading_is_watched_at_every_epoch_kept_or_not() {
    let n = 2000;
    let imu = vec![[0.02, -0.01, -9.79, 1e-4, 0.0, 2e-4]; n];
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let data = imu_only(&imu, &imu_time);
    let limit = crate::pass::MAX_LINEAR_HEADING_SIGMA_DEG.to_radians();
    for step in [0.0, 0.1] {
        let mut cfg = FilterConfig {
            covariance_step: step,
            ..FilterConfig::default()
        };
        cfg.p0_sigma[14] = 0.005; // 1,000 °/h of vertical gyro bias: 5° within 20 s
        let pass = |epochs| pass_with(&data, &cfg, [1e-6; 6], epochs);
        let (all, last) = (pass(Epochs::All), pass(Epochs::Last));
        assert_eq!(all.extent.heading2, last.extent.heading2);
        assert_eq!(all.extent.heading_over, last.extent.heading_over);
        let kept2 = all.sigma.iter().map(|s| s[8] * s[8]).fold(0.0, f64::max);
        let first = all.sigma.iter().position(|s| s[8] > limit).unwrap();
        let over = all.extent.heading_over;
        assert!(all.time[first] > 0.0 && over < 20.0, "{step}: {over}");
        if step == 0.0 {
            assert!((all.extent.heading2 - kept2).abs() <= 1e-14 * kept2); // σ squared back
            assert_eq!(over, all.time[first]);
        } else {
            assert!(all.extent.heading2 >= kept2 * (1.0 - 1e-14));
            assert!(all.time[first] <= over && over < all.time[first] + step);
            // named at the close (every tenth epoch, no readings) whose σ passed, the
            // close before it under
            let close = all.time.iter().position(|&t| t == over).unwrap();
            assert_eq!(close % 10, 0);
            assert!(all.sigma[close][8] > limit && all.sigma[close - 10][8] <= limit);
        }
    }
}

/// A solution that leaves a bound (an accelerometer 5 m/s² off forward: 100 m/s after
/// 20 s) is watched at every epoch: the pass that keeps its last epoch only names the
/// same first epoch and bound as the one that keeps every epoch, the first whose speed
/// is over the bound.
#[test]
fn the_first_epoch_out_of_bounds_is_watched_kept_or_not() {
    let n = 3000;
    let imu = vec![[5.0, 0.0, -9.79, 0.0, 0.0, 0.0]; n];
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let data = imu_only(&imu, &imu_time);
    let cfg = FilterConfig::default();
    let pass = |epochs| pass_with(&data, &cfg, [1e-6; 6], epochs);
    let (all, last) = (pass(Epochs::All), pass(Epochs::Last));
    let speed = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let first = all
        .vel
        .iter()
        .position(|v| speed(v) > crate::pass::MAX_SPEED);
    let first = first.expect("the speed passes 100 m/s");
    assert!(all.time[first] > 10.0 && all.time[first] < 25.0);
    assert_eq!(
        all.extent.diverged,
        Some((all.time[first], crate::pass::Bound::Speed))
    );
    assert_eq!(last.extent.diverged, all.extent.diverged);
}
