//! Tests of [`super::stream`]: a stream's checks, its variance rows, and the streams a
//! filter configuration refuses.

use super::data::RecordedData;
use super::filter::filter_recorded;
use super::stream::{velocity_variance, Stream, Values};
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
