//! Tests of [`super::stream`]: a stream's checks, its variance rows, and the streams a
//! filter configuration refuses.

use super::data::RecordedData;
use super::filter::filter_recorded;
use super::stream::{velocity_variance, PerRow, Stream, Values};
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::tests::moving_state;
use crate::ekf::{Aiding, FilterConfig};
use crate::error::Error;
use crate::noise::StrategySpec;
use nalgebra::Vector3;

/// The argument an error names.
fn arg(e: Error) -> String {
    match e {
        Error::InvalidArgument { arg, .. } => arg,
        other => panic!("not an argument error: {other}"),
    }
}

/// `stream` with its velocity rows in `frame`.
fn in_frame(mut stream: Stream<'_>, to: Aiding) -> Stream<'_> {
    if let Values::Velocity { frame, .. } = &mut stream.values {
        *frame = to;
    }
    stream
}

#[test]
fn velocity_variance_squares_each_sigma_and_names_a_bad_row() {
    let v = velocity_variance("dvl", &[[0.1, 0.2, 0.3]]).unwrap();
    assert_eq!(v, vec![[0.1 * 0.1, 0.2 * 0.2, 0.3 * 0.3]]);
    // zero, negative (its square would pass), NaN, a square that overflows or underflows
    for bad in [
        [0.1, 0.0, 0.1],
        [0.1, -0.1, 0.1],
        [f64::NAN; 3],
        [1e200; 3],
        [1e-200; 3],
    ] {
        let e = velocity_variance("dvl", &[[0.1; 3], bad]).unwrap_err();
        assert!(e.to_string().starts_with("dvl_sigma: row 1 "), "{e}");
    }
}

#[test]
fn a_stream_s_lever_arm_and_gate_are_checked() {
    let (time, rows) = ([1.0], [[1.0, 0.0, 0.0]]);
    let cfg = FilterConfig::default();
    assert!(Stream::dvl(&rows, &time, &cfg).validate().is_ok());
    for arm in [
        Vector3::new(f64::NAN, 0.0, 0.0),
        Vector3::new(0.0, f64::INFINITY, 0.0),
        Vector3::new(0.0, 0.0, 1.0 + crate::ekf::MAX_LEVER_ARM),
    ] {
        let dvl = Stream {
            lever_arm: arm,
            ..Stream::dvl(&rows, &time, &cfg)
        };
        assert_eq!(arg(dvl.validate().unwrap_err()), "dvl_lever_arm");
        let depth = Stream {
            lever_arm: arm,
            ..Stream::depth(&[5.0], &time, 0.1)
        };
        assert_eq!(arg(depth.validate().unwrap_err()), "depth_lever_arm");
    }
    for gate in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        let gated = FilterConfig {
            innovation_gate: Some(gate),
            ..cfg.clone()
        };
        let dvl = Stream::dvl(&rows, &time, &gated);
        assert_eq!(arg(dvl.validate().unwrap_err()), "dvl_gate");
    }
}

#[test]
fn a_ned_velocity_stream_is_refused_beside_the_calibration_states() {
    let (time, rows) = ([0.05], [[1.0, 0.0, 0.0]]);
    let calibrated = FilterConfig {
        dvl_calibration: Some(CalibrationConfig::default()),
        ..FilterConfig::default()
    };
    let body = Stream::dvl(&rows, &time, &calibrated);
    assert!(body.check_config(&calibrated).is_ok());
    let ned = Stream {
        name: "streams[1]".into(),
        ..in_frame(body.clone(), Aiding::Nav)
    };
    assert_eq!(
        arg(ned.check_config(&calibrated).unwrap_err()),
        "streams[1]"
    );
    assert!(ned.check_config(&FilterConfig::default()).is_ok());
    assert!(Stream::depth(&[5.0], &time, 0.1)
        .check_config(&calibrated)
        .is_ok());
    // a pass refuses it before its first step
    let imu = [[0.0, 0.0, -9.79, 0.0, 0.0, 0.0]; 10];
    let imu_time: Vec<f64> = (1..=10).map(|k| k as f64 * 0.01).collect();
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        streams: vec![body, ned],
        ..RecordedData::default()
    };
    let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(calibrated.bias_psd());
    let e = filter_recorded(
        &data,
        moving_state(),
        [0.0; 6],
        &calibrated,
        strategy.as_mut(),
    );
    assert_eq!(arg(e.unwrap_err()), "streams[1]");
}

/// A heading stream of `rows` \[rad\] with one 1σ `sigma` \[rad\].
fn heading<'a>(rows: &'a [f64], time: &'a [f64], sigma: f64) -> Stream<'a> {
    Stream {
        name: "heading".into(),
        time,
        values: Values::Heading {
            rows,
            sigma: PerRow::One(sigma),
        },
        lever_arm: Vector3::zeros(),
    }
}

#[test]
fn a_heading_stream_refuses_degrees_a_bad_sigma_and_a_lever_arm() {
    let time = [1.0, 2.0];
    assert!(heading(&[0.5, -6.0], &time, 0.01).validate().is_ok());
    let e = heading(&[0.5, 270.0], &time, 0.01).validate().unwrap_err();
    assert!(e.to_string().starts_with("heading: row 1 "), "{e}");
    assert!(e.to_string().contains("degrees?"), "{e}");
    // NaN is no slip of unit: not asked whether it is in degrees
    let e = heading(&[0.5, f64::NAN], &time, 0.01)
        .validate()
        .unwrap_err();
    assert!(!e.to_string().contains("degrees?"), "{e}");
    assert_eq!(arg(e), "heading");
    for sigma in [0.0, -0.1, 5.0, f64::NAN, f64::INFINITY] {
        let e = heading(&[0.5, 0.6], &time, sigma).validate().unwrap_err();
        assert_eq!(e.to_string().contains("degrees?"), sigma > 3.2, "{e}");
        assert_eq!(arg(e), "heading_sigma", "{sigma}");
    }
    let each = [0.01, 0.0];
    let per_row = Stream {
        values: Values::Heading {
            rows: &[0.5, 0.6],
            sigma: PerRow::Each(&each),
        },
        ..heading(&[], &time, 0.01)
    };
    assert!(per_row
        .validate()
        .unwrap_err()
        .to_string()
        .starts_with("heading_sigma: row 1 "));
    let short = Stream {
        values: Values::Heading {
            rows: &[0.5, 0.6],
            sigma: PerRow::Each(&each[..1]),
        },
        ..heading(&[], &time, 0.01)
    };
    assert_eq!(arg(short.validate().unwrap_err()), "heading_sigma");
    let armed = Stream {
        lever_arm: Vector3::new(0.0, 0.0, 1.0),
        ..heading(&[0.5, 0.6], &time, 0.01)
    };
    assert_eq!(arg(armed.validate().unwrap_err()), "heading_lever_arm");
}

#[test]
fn a_pass_with_headings_pulls_the_yaw_to_them_and_records_their_nis() {
    // At rest, level, the estimate's yaw 0.8 rad; a compass reads 0.9 rad at 10 Hz.
    let g = crate::earth::gravity(0.55, -10.0);
    let imu = vec![[0.0, 0.0, -g, 0.0, 0.0, 0.0]; 2000];
    let imu_time: Vec<f64> = (1..=2000).map(|k| k as f64 * 0.01).collect();
    let time: Vec<f64> = (1..=200).map(|k| k as f64 * 0.1).collect();
    let rows = vec![0.9; 200];
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        streams: vec![heading(&rows, &time, 0.01)],
        ..RecordedData::default()
    };
    let mut start = moving_state();
    start.vel = Vector3::zeros();
    start.dcm = crate::attitude::dcm_from_euler(0.0, 0.0, 0.8);
    // Yaw unknown to 0.2 rad (1σ), biases that barely wander.
    let mut cfg = FilterConfig {
        accel_bias_psd: 1e-10,
        gyro_bias_psd: 1e-14,
        ..FilterConfig::default()
    };
    cfg.p0_sigma[8] = 0.2;
    let mut strategy = StrategySpec::Constant { q: [1e-8; 6] }.build(cfg.bias_psd());
    let out = filter_recorded(&data, start, [0.0; 6], &cfg, strategy.as_mut()).unwrap();
    let yaw = out.rpy.last().unwrap()[2];
    assert!((yaw - 0.9).abs() < 2e-3, "{yaw}");
    let record = &out.streams[0];
    assert_eq!(record.epoch.len(), 200);
    assert_eq!(record.epoch[0], Some(10)); // epoch 0 is t0
    assert!(record.nis.iter().all(|n| n.is_finite() && *n >= 0.0));
    // The first reading is 0.1 rad off the estimate whose yaw σ is 0.2 rad:
    // NIS = 0.1² / (0.2² + 0.01²); the last ones agree with it.
    let first = 0.01 / (0.04 + 1e-4);
    assert!(
        (record.nis[0] / first - 1.0).abs() < 0.01,
        "{}",
        record.nis[0]
    );
    assert!(record.nis[199] < 0.1 * first);
    // 200 readings of 0.01 rad: the yaw's σ well under one reading's.
    let yaw_sigma = out.sigma.last().unwrap()[8];
    assert!(yaw_sigma < 0.005 && yaw_sigma > 0.0, "{yaw_sigma}");
}
