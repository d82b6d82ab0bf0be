//! Trajectories.

use super::*;

fn valid_segment() -> impl Strategy<Value = Segment> {
    (0.05..30.0f64, -0.2..0.2f64, -0.5..0.5f64, -0.01..0.01f64)
        .prop_map(|(d, a, y, p)| Segment::new(d, a, y, p))
}

fn set_segment_field(s: &mut Segment, field: usize, v: f64) {
    match field {
        // A huge duration is pushed past the sample limit (always refused): one that is
        // merely large (1e6 s at dt = 0.1 s, 1e7 samples) is valid, only slow and big.
        0 if v.is_finite() && v > 1e3 => s.duration = 1e12,
        0 => s.duration = v,
        1 => s.accel = v,
        2 => s.yaw_rate = v,
        _ => s.pitch_rate = v,
    }
}

/// A trajectory spec and whether a wild value was put into it.
fn trajectory_spec() -> impl Strategy<Value = (TrajectorySpec, bool)> {
    (
        prop::collection::vec(valid_segment(), 0..6),
        corruptions(4, 2),
        prop::sample::select(vec![0.01, 0.02, 0.05, 0.1, 0.25]),
        0.0..3.0f64,
        prop_oneof![3 => Just(paper_origin()[0]), 1 => -1.6..1.6f64],
        (-3.2..3.2f64, -0.5..0.5f64, -3.2..3.2f64),
        // Corruptions of the scalars: 0 dt, 1 speed0, 2..5 lla0, 5..8 rpy0.
        rarely((0..8usize, wild()), 1),
    )
        .prop_map(
            |(mut segments, seg_bad, dt, speed0, lat, rpy, scalar_bad)| {
                let corrupted =
                    (!seg_bad.is_empty() && !segments.is_empty()) || !scalar_bad.is_empty();
                if !segments.is_empty() {
                    for (i, field, v) in &seg_bad {
                        let i = i.index(segments.len());
                        set_segment_field(&mut segments[i], *field, *v);
                    }
                }
                let mut spec = TrajectorySpec {
                    name: "prop".into(),
                    lla0: Vector3::new(lat, paper_origin()[1], paper_origin()[2]),
                    speed0,
                    rpy0: Vector3::new(rpy.0, rpy.1, rpy.2),
                    segments,
                    dt,
                };
                for (field, v) in scalar_bad {
                    match field {
                        0 => spec.dt = v,
                        1 => spec.speed0 = v,
                        2..=4 => spec.lla0[field - 2] = v,
                        _ => spec.rpy0[field - 5] = v,
                    }
                }
                (spec, corrupted)
            },
        )
}

/// The documented rules a spec must meet (see `TrajectorySpec::validate`), computed
/// independently: `Some(reason)` if it must be refused.
fn must_refuse(spec: &TrajectorySpec) -> Option<&'static str> {
    let scalars = [
        spec.dt,
        spec.speed0,
        spec.lla0[0],
        spec.lla0[1],
        spec.lla0[2],
    ];
    if !all_finite(scalars.iter().chain(spec.rpy0.iter())) {
        return Some("non-finite scalar");
    }
    if spec.dt <= 0.0 {
        return Some("dt <= 0");
    }
    if spec.lla0[0].abs() > 89f64.to_radians() {
        return Some("latitude beyond 89°");
    }
    if spec.segments.is_empty() {
        return Some("no segments");
    }
    for s in &spec.segments {
        if !all_finite(&[s.duration, s.accel, s.yaw_rate, s.pitch_rate]) {
            return Some("non-finite segment value");
        }
        if s.duration <= 0.0 {
            return Some("duration <= 0");
        }
    }
    None
}

/// Whether a spec is modest enough that it must be accepted: no wild values, speed and
/// pitch within the documented limits with margin, at least one sample.
fn must_accept(spec: &TrajectorySpec, corrupted: bool) -> bool {
    if corrupted || must_refuse(spec).is_some() {
        return false;
    }
    let top_speed = spec.speed0.abs()
        + spec
            .segments
            .iter()
            .map(|s| (s.accel * s.duration).abs())
            .sum::<f64>();
    let mut pitch = spec.rpy0[1];
    let mut max_pitch = pitch.abs();
    for s in &spec.segments {
        pitch += s.pitch_rate * s.duration;
        max_pitch = max_pitch.max(pitch.abs());
    }
    top_speed < 0.99 * MAX_SPEED
        && max_pitch < 79f64.to_radians()
        && spec.duration() >= 1.01 * spec.dt
}

/// Everything a generated truth must satisfy.
pub(super) fn check_truth(spec: &TrajectorySpec, truth: &Truth) -> Result<(), TestCaseError> {
    let n = truth.len();
    prop_assert!(n >= 1, "an Ok truth has at least one IMU sample");
    prop_assert_eq!(n, (spec.duration() / spec.dt + 1e-9).floor() as usize);
    prop_assert_eq!(truth.time.len(), n + 1);
    prop_assert_eq!(truth.states.len(), n + 1);
    prop_assert_eq!(truth.rpy.len(), n + 1);
    prop_assert!(all_finite(&truth.time), "non-finite time");
    prop_assert!(
        truth.time.windows(2).all(|w| w[1] > w[0]),
        "time not increasing"
    );
    for (k, s) in truth.states.iter().enumerate() {
        prop_assert!(
            nav_finite(s),
            "non-finite truth state {} of {}: {:?}",
            k,
            n,
            s
        );
        prop_assert!(
            s.vel.norm() <= MAX_SPEED * (1.0 + 1e-9),
            "speed {} m/s at epoch {} beyond the {} m/s limit",
            s.vel.norm(),
            k,
            MAX_SPEED
        );
    }
    for (k, r) in truth.rpy.iter().enumerate() {
        prop_assert!(all_finite(r.iter()), "non-finite rpy at {}: {:?}", k, r);
    }
    for (k, m) in truth.imu.iter().enumerate() {
        prop_assert!(all_finite(m), "non-finite ideal IMU sample {}: {:?}", k, m);
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// A random segment list either generates a finite truth of the documented length
    /// or is refused; clearly invalid lists are refused, modest valid ones accepted.
    #[test]
    fn trajectory_generates_finite_truth_or_err((spec, corrupted) in trajectory_spec()) {
        // Known: a huge finite initial height overflows gravity, a huge finite yaw rate
        // overflows the yaw angle (both pinned below).
        let huge = |v: f64| v.is_finite() && v.abs() >= HUGE;
        prop_assume!(!huge(spec.lla0[2]));
        prop_assume!(!spec.segments.iter().any(|s| huge(s.yaw_rate)));
        let result = spec.generate();
        if let Some(reason) = must_refuse(&spec) {
            prop_assert!(result.is_err(), "{} must be refused: {:?}", reason, spec);
        }
        if must_accept(&spec, corrupted) {
            prop_assert!(result.is_ok(), "valid spec refused: {:?} {:?}", result.as_ref().err(), spec);
        }
        match result {
            Ok(truth) => check_truth(&spec, &truth)?,
            Err(e) => prop_assert!(
                matches!(e, pronet::Error::InvalidArgument { .. }),
                "a spec is refused as an invalid argument, not {:?}",
                e
            ),
        }
    }
}
