//! Vehicle trajectories from segment specifications, their truth, and the ideal IMU
//! consistent with them.
//!
//! The vehicle moves along its body x axis (no sideslip) at forward speed u, with roll
//! held at its initial value. Each [`Segment`] holds the forward acceleration, yaw rate
//! and pitch rate constant for its duration, so speed, yaw and pitch are evaluated in
//! closed form at every sample time. NED velocity is `C_b^n [u, 0, 0]`; position is the
//! trapezoid of the velocities (the rule the mechanization uses), and the ideal IMU is
//! the inverse of the strapdown step between consecutive truth states, so mechanizing
//! it reproduces the truth to rounding.

use crate::attitude::{dcm_from_euler, wrap_angle};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::earth;
use crate::error::{check, Error, Result};
use crate::mechanization::{advance_position, invert_step, NavState};
use crate::memory::Estimate;
use nalgebra::Vector3;
use std::mem::size_of;

/// One piece of a trajectory: for `duration` \[s\], forward acceleration `accel` \[m/s²\],
/// yaw rate `yaw_rate` \[rad/s, positive turns right\] and pitch rate `pitch_rate`
/// \[rad/s, positive noses up\] are constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub duration: f64,
    pub accel: f64,
    pub yaw_rate: f64,
    pub pitch_rate: f64,
}

impl Segment {
    pub const fn new(duration: f64, accel: f64, yaw_rate: f64, pitch_rate: f64) -> Self {
        Self {
            duration,
            accel,
            yaw_rate,
            pitch_rate,
        }
    }
}

/// A trajectory: initial conditions plus segments, sampled at `dt`.
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectorySpec {
    pub name: String,
    /// Initial geodetic position `[lat, lon, h]` \[rad, rad, m\].
    pub lla0: Vector3<f64>,
    /// Initial forward speed \[m/s\].
    pub speed0: f64,
    /// Initial `[roll, pitch, yaw]` \[rad\]; roll stays constant.
    pub rpy0: Vector3<f64>,
    pub segments: Vec<Segment>,
    /// Sample period \[s\].
    pub dt: f64,
}

/// Truth of a trajectory at n + 1 epochs and the ideal IMU over the n intervals.
#[derive(Clone, Debug)]
pub struct Truth {
    pub name: String,
    pub dt: f64,
    /// Epoch times \[s\], `time[0] = 0`.
    pub time: Vec<f64>,
    pub states: Vec<NavState>,
    /// `[roll, pitch, yaw]` \[rad\] at each epoch, yaw wrapped to (−π, π].
    pub rpy: Vec<Vector3<f64>>,
    /// Ideal IMU sample k covers `(time[k], time[k+1]]`.
    pub imu: Vec<[f64; 6]>,
    /// Each epoch's scale for position errors in metres ([`earth::NedScale`]), taken
    /// once for every run that reads it.
    pub ned_scale: Vec<earth::NedScale>,
}

impl Truth {
    /// What a truth of `n` samples holds: at every epoch its time, state, attitude
    /// angles, ideal IMU sample and position-error scale (and 64 KiB for its name and
    /// the segments' starts).
    pub fn memory(n: usize) -> Estimate {
        let epoch = size_of::<f64>()
            + size_of::<NavState>()
            + size_of::<Vector3<f64>>()
            + size_of::<[f64; 6]>()
            + size_of::<earth::NedScale>();
        let mut e = Estimate {
            fixed: 64.0 * 1024.0,
            ..Estimate::default()
        };
        e.add(
            "dt",
            "samples",
            (n as f64 + 1.0, epoch as f64),
            "a larger dt, or a shorter trajectory",
        );
        e
    }

    /// Number of IMU samples (epochs minus one).
    pub fn len(&self) -> usize {
        self.imu.len()
    }

    pub fn is_empty(&self) -> bool {
        self.imu.is_empty()
    }

    pub fn duration(&self) -> f64 {
        self.time.last().copied().unwrap_or(0.0)
    }
}

/// Longest trajectory accepted (samples): 10 hours at 100 Hz, with room.
const MAX_SAMPLES: usize = 20_000_000;

/// Largest speed a trajectory may reach \[m/s\].
pub const MAX_SPEED: f64 = 1000.0;

/// Largest yaw or pitch rate of a segment \[rad/s\]: 10 rad/s (573°/s) is far beyond any
/// vehicle (an AUV turns at a few °/s, an agile drone at a few hundred), and keeps a
/// step's rotation far below the half turn at which the ideal gyro would alias (a
/// 1e4 rad/s segment at 100 Hz would read as −53 rad/s).
pub const MAX_TURN_RATE: f64 = 10.0;

impl TrajectorySpec {
    pub fn validate(&self) -> Result<()> {
        check::finite("lla0", self.lla0.as_slice())?;
        earth::check_latitude("lla0", self.lla0[0])?;
        check::finite("speed0", &[self.speed0])?;
        check::finite("rpy0", self.rpy0.as_slice())?;
        check::positive("dt", self.dt)?;
        if self.segments.is_empty() {
            return Err(Error::invalid("segments", "at least one segment is needed"));
        }
        for (i, s) in self.segments.iter().enumerate() {
            let arr = [s.duration, s.accel, s.yaw_rate, s.pitch_rate];
            check::finite("segments", &arr).map_err(|_| {
                Error::invalid("segments", format!("row {i} is not finite: {arr:?}"))
            })?;
            if s.duration <= 0.0 {
                return Err(Error::invalid(
                    "segments",
                    format!("row {i}: duration must be > 0, got {}", s.duration),
                ));
            }
            for (what, rate) in [("yaw", s.yaw_rate), ("pitch", s.pitch_rate)] {
                if rate.abs() > MAX_TURN_RATE {
                    return Err(Error::invalid(
                        "segments",
                        format!(
                            "row {i}: a {what} rate of {rate} rad/s ({:.0}°/s) is beyond any \
                             vehicle; at most {MAX_TURN_RATE} rad/s ({:.0}°/s) is supported",
                            rate.to_degrees(),
                            MAX_TURN_RATE.to_degrees()
                        ),
                    ));
                }
            }
        }
        // Beyond this the NED kinematics and the Earth model stop describing a vehicle
        // (and huge speeds overflow the ideal IMU).
        let top_speed = self.speed0.abs()
            + self
                .segments
                .iter()
                .map(|s| (s.accel * s.duration).abs())
                .sum::<f64>();
        if top_speed > MAX_SPEED {
            return Err(Error::invalid(
                "speed0",
                format!(
                    "speed0 and the segments' accelerations can reach {top_speed:e} m/s; \
                     at most {MAX_SPEED} m/s is supported"
                ),
            ));
        }
        let total: f64 = self.segments.iter().map(|s| s.duration).sum();
        if total / self.dt > MAX_SAMPLES as f64 {
            return Err(Error::invalid(
                "segments",
                format!(
                    "total duration {total:.4e} s at dt {} s exceeds {MAX_SAMPLES} samples",
                    self.dt
                ),
            ));
        }
        if total < self.dt {
            return Err(Error::invalid(
                "segments",
                "total duration is shorter than dt",
            ));
        }
        // Pitch must stay away from ±90° where ZYX Euler angles are singular.
        let mut pitch = self.rpy0[1];
        for (i, s) in self.segments.iter().enumerate() {
            pitch += s.pitch_rate * s.duration;
            if pitch.abs().max(self.rpy0[1].abs()) > 80f64.to_radians() {
                return Err(Error::invalid(
                    "segments",
                    format!(
                        "pitch reaches {:.1}° in row {i}; keep |pitch| <= 80°",
                        pitch.to_degrees()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Total duration \[s\] (the sum of the segment durations).
    pub fn duration(&self) -> f64 {
        self.segments.iter().map(|s| s.duration).sum()
    }

    /// Generate the truth and the ideal IMU. Samples are taken at `k·dt` for
    /// `k = 0..=floor(duration/dt)`.
    pub fn generate(&self) -> Result<Truth> {
        self.generate_until(&Cancel::default())
    }

    /// [`Self::generate`] that stops with [`Error::Cancelled`] soon after `cancel` is set
    /// (checked every [`STEPS_PER_CHECK`] samples).
    pub fn generate_until(&self, cancel: &Cancel) -> Result<Truth> {
        self.validate()?;
        let n = (self.duration() / self.dt + 1e-9).floor() as usize;
        Truth::memory(n).check("this trajectory")?;
        // Closed-form speed, pitch and yaw at the start of each segment.
        let mut starts = Vec::with_capacity(self.segments.len());
        let (mut t0, mut u, mut pitch, mut yaw) = (0.0, self.speed0, self.rpy0[1], self.rpy0[2]);
        for s in &self.segments {
            starts.push((t0, u, pitch, yaw));
            t0 += s.duration;
            u += s.accel * s.duration;
            pitch += s.pitch_rate * s.duration;
            yaw += s.yaw_rate * s.duration;
        }
        let roll = self.rpy0[0];
        let mut seg = 0;
        let mut time = Vec::with_capacity(n + 1);
        let mut states: Vec<NavState> = Vec::with_capacity(n + 1);
        let mut rpy = Vec::with_capacity(n + 1);
        for k in 0..=n {
            if k % STEPS_PER_CHECK == 0 {
                cancel.check()?;
            }
            let t = k as f64 * self.dt;
            while seg + 1 < self.segments.len() && t >= starts[seg + 1].0 {
                seg += 1;
            }
            let (ts, us, ps, ys) = starts[seg];
            let s = &self.segments[seg];
            let tau = t - ts;
            let speed = us + s.accel * tau;
            let p = ps + s.pitch_rate * tau;
            let y = ys + s.yaw_rate * tau;
            let dcm = dcm_from_euler(roll, p, y);
            let vel = dcm * Vector3::new(speed, 0.0, 0.0);
            let lla = match states.last() {
                None => self.lla0,
                Some(prev) => {
                    let start = earth::Latitude::new(prev.lla[0]);
                    advance_position(&prev.lla, &start, &prev.vel, &vel, self.dt)
                }
            };
            time.push(t);
            states.push(NavState { lla, vel, dcm });
            rpy.push(Vector3::new(roll, p, wrap_angle(y)));
        }
        let mut imu: Vec<[f64; 6]> = Vec::with_capacity(n);
        for (k, w) in states.windows(2).enumerate() {
            if k % STEPS_PER_CHECK == 0 {
                cancel.check()?;
            }
            imu.push(invert_step(&w[0], &w[1], self.dt).to_array());
        }
        // Finite inputs can still overflow (a yaw rate near f64::MAX, a height of 1e300 m).
        let bad_state = states.iter().position(|s| {
            !(s.lla.iter().chain(s.vel.iter()).chain(s.dcm.iter())).all(|x| x.is_finite())
        });
        let bad_imu = imu.iter().position(|r| !r.iter().all(|x| x.is_finite()));
        if let Some(k) = bad_state.or(bad_imu) {
            return Err(Error::invalid(
                "segments",
                format!(
                    "the trajectory overflows to non-finite values at t = {} s",
                    time[k]
                ),
            ));
        }
        let ned_scale = states.iter().map(|s| earth::NedScale::at(&s.lla)).collect();
        Ok(Truth {
            name: self.name.clone(),
            dt: self.dt,
            time,
            states,
            rpy,
            imu,
            ned_scale,
        })
    }
}

fn deg(x: f64) -> f64 {
    x.to_radians()
}

/// Names of the built-in trajectories.
pub const BUILTIN_NAMES: [&str; 5] = [
    "paper",
    "train-straight",
    "train-turns",
    "train-zigzag",
    "train-helix",
];

/// Names of the four training trajectories (400 s each).
pub const TRAINING_NAMES: [&str; 4] = [
    "train-straight",
    "train-turns",
    "train-zigzag",
    "train-helix",
];

/// The paper's start point: 32° N, 34° E, 5 m deep.
pub fn paper_origin() -> Vector3<f64> {
    Vector3::new(deg(32.0), deg(34.0), -5.0)
}

/// A built-in trajectory by name, sampled at `dt` \[s\] (0.01 s in the paper).
///
/// - `paper`: the evaluation trajectory, 330 s: straight legs, a left and a right 90°
///   turn, a 10° dive and level-off, a further right turn and a speed-up;
///   v0 = [1, 0, 0] m/s, p0 = (32°, 34°, −5 m).
/// - `train-straight`: straight legs with speed changes (400 s).
/// - `train-turns`: constant-rate turns both ways (400 s).
/// - `train-zigzag`: zig-zag with alternating dives and climbs (400 s).
/// - `train-helix`: a steady turn while diving, then climbing (400 s).
pub fn builtin(name: &str, dt: f64) -> Result<TrajectorySpec> {
    let seg = Segment::new;
    let (speed0, segments) = match name {
        "paper" => (
            1.0,
            vec![
                seg(40.0, 0.0, 0.0, 0.0),
                seg(30.0, 0.0, deg(-3.0), 0.0),
                seg(40.0, 0.0, 0.0, 0.0),
                seg(30.0, 0.0, deg(3.0), 0.0),
                seg(30.0, 0.0, 0.0, 0.0),
                seg(5.0, 0.0, 0.0, deg(-2.0)),
                seg(40.0, 0.0, 0.0, 0.0),
                seg(5.0, 0.0, 0.0, deg(2.0)),
                seg(30.0, 0.0, 0.0, 0.0),
                seg(30.0, 0.0, deg(3.0), 0.0),
                seg(10.0, 0.05, 0.0, 0.0),
                seg(40.0, 0.0, 0.0, 0.0),
            ],
        ),
        "train-straight" => (
            1.0,
            vec![
                seg(40.0, 0.0, 0.0, 0.0),
                seg(20.0, 0.025, 0.0, 0.0),
                seg(60.0, 0.0, 0.0, 0.0),
                seg(20.0, -0.025, 0.0, 0.0),
                seg(40.0, 0.0, 0.0, 0.0),
                seg(10.0, 0.05, 0.0, 0.0),
                seg(50.0, 0.0, 0.0, 0.0),
                seg(20.0, -0.04, 0.0, 0.0),
                seg(60.0, 0.0, 0.0, 0.0),
                seg(30.0, 0.03, 0.0, 0.0),
                seg(50.0, 0.0, 0.0, 0.0),
            ],
        ),
        "train-turns" => (
            1.5,
            vec![
                seg(30.0, 0.0, 0.0, 0.0),
                seg(60.0, 0.0, deg(3.0), 0.0),
                seg(20.0, 0.0, 0.0, 0.0),
                seg(45.0, 0.0, deg(-4.0), 0.0),
                seg(25.0, 0.0, 0.0, 0.0),
                seg(90.0, 0.0, deg(2.0), 0.0),
                seg(20.0, 0.0, 0.0, 0.0),
                seg(60.0, 0.0, deg(-6.0), 0.0),
                seg(50.0, 0.0, 0.0, 0.0),
            ],
        ),
        "train-zigzag" => (1.2, {
            let mut v = Vec::new();
            for i in 0..10 {
                // Alternate dives and climbs; each 40 s block returns to level and course.
                let s = if i % 2 == 0 { -1.0 } else { 1.0 };
                v.push(seg(10.0, 0.0, deg(5.0), s * deg(1.0)));
                v.push(seg(20.0, 0.0, deg(-5.0), 0.0));
                v.push(seg(10.0, 0.0, deg(5.0), -s * deg(1.0)));
            }
            v
        }),
        "train-helix" => (
            1.0,
            vec![
                seg(5.0, 0.0, deg(3.0), deg(-2.0)),
                seg(140.0, 0.0, deg(3.0), 0.0),
                seg(10.0, 0.0, deg(3.0), deg(2.0)),
                seg(140.0, 0.0, deg(3.0), 0.0),
                seg(5.0, 0.0, deg(3.0), deg(-2.0)),
                seg(100.0, 0.02, deg(3.0), 0.0),
            ],
        ),
        other => {
            return Err(Error::invalid(
                "name",
                format!("unknown trajectory {other:?}; built-in names are {BUILTIN_NAMES:?}"),
            ))
        }
    };
    Ok(TrajectorySpec {
        name: name.to_string(),
        lla0: paper_origin(),
        speed0,
        rpy0: Vector3::zeros(),
        segments,
        dt,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::euler_from_dcm;
    use crate::mechanization::integrate;

    #[test]
    fn builtin_durations() {
        assert_eq!(builtin("paper", 0.01).unwrap().duration(), 330.0);
        for name in TRAINING_NAMES {
            assert_eq!(builtin(name, 0.01).unwrap().duration(), 400.0, "{name}");
        }
        assert!(builtin("nope", 0.01).is_err());
    }

    #[test]
    fn a_set_cancel_flag_stops_the_generation() {
        let spec = builtin("paper", 0.01).unwrap();
        let cancel = Cancel::default();
        assert_eq!(spec.generate_until(&cancel).unwrap().time.len(), 33_001);
        cancel.cancel();
        assert_eq!(spec.generate_until(&cancel).unwrap_err(), Error::Cancelled);
    }

    #[test]
    fn paper_trajectory_initial_conditions() {
        let t = builtin("paper", 0.01).unwrap().generate().unwrap();
        assert_eq!(t.len(), 33_000);
        let s0 = t.states[0];
        assert!((s0.vel - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-15);
        assert_eq!(s0.lla, paper_origin());
        // The dive takes it deeper; the turns end 90° right of the start (−90 + 90 + 90).
        let last = t.rpy.last().unwrap();
        assert!((last[2] - deg(90.0)).abs() < 1e-9, "final yaw {}", last[2]);
        let deepest = t
            .states
            .iter()
            .map(|s| s.lla[2])
            .fold(f64::INFINITY, f64::min);
        assert!(deepest < -10.0, "deepest {deepest}");
    }

    /// Mechanizing the ideal IMU of every built-in trajectory from the true initial state
    /// reproduces the truth over the whole run.
    #[test]
    fn round_trip_every_builtin() {
        for name in BUILTIN_NAMES {
            let truth = builtin(name, 0.01).unwrap().generate().unwrap();
            let nav = integrate(&truth.states[0], &truth.imu, truth.dt);
            let (mut dp, mut dv, mut da) = (0f64, 0f64, 0f64);
            for (est, tru) in nav.iter().zip(&truth.states) {
                dp = dp.max(earth::position_error_ned(&est.lla, &tru.lla).norm());
                dv = dv.max((est.vel - tru.vel).norm());
                let e = crate::attitude::log_so3(&(est.dcm * tru.dcm.transpose()));
                da = da.max(e.norm());
            }
            assert!(
                dp < 0.1 && dv < 1e-3 && da < 1e-5,
                "{name}: {dp} m, {dv} m/s, {da} rad"
            );
        }
    }

    /// The ideal IMU agrees with the continuous kinematics: in a steady level turn at
    /// speed u and yaw rate r the accelerometers read the centripetal u·r on y and −g on
    /// z, and the gyro z reads r plus the Earth rate's body component.
    #[test]
    fn ideal_imu_matches_continuous_kinematics_in_a_turn() {
        let spec = TrajectorySpec {
            name: "turn".into(),
            lla0: paper_origin(),
            speed0: 2.0,
            rpy0: Vector3::zeros(),
            segments: vec![Segment::new(20.0, 0.0, deg(5.0), 0.0)],
            dt: 0.01,
        };
        let t = spec.generate().unwrap();
        let k = 1000;
        let s = &t.states[k];
        let r = deg(5.0);
        let w_ie_b = s.dcm.transpose() * earth::earth_rate_ned(s.lla[0]);
        let imu = t.imu[k];
        let g = earth::gravity(s.lla[0], s.lla[2]);
        // Coriolis and transport terms are below 1e-3 m/s² at 2 m/s.
        assert!(
            (imu[1] - 2.0 * r).abs() < 1e-3,
            "f_y {} vs {}",
            imu[1],
            2.0 * r
        );
        assert!((imu[2] + g).abs() < 1e-3, "f_z {}", imu[2]);
        assert!(imu[0].abs() < 1e-3, "f_x {}", imu[0]);
        assert!((imu[5] - r - w_ie_b[2]).abs() < 1e-6, "w_z {}", imu[5]);
        // Euler angles of the truth agree with the DCM.
        let e = euler_from_dcm(&s.dcm);
        assert!((e - t.rpy[k]).abs().max() < 1e-12);
    }

    #[test]
    fn forward_acceleration_reads_on_the_x_accelerometer() {
        let spec = TrajectorySpec {
            name: "accel".into(),
            lla0: paper_origin(),
            speed0: 1.0,
            rpy0: Vector3::zeros(),
            segments: vec![Segment::new(10.0, 0.1, 0.0, 0.0)],
            dt: 0.01,
        };
        let t = spec.generate().unwrap();
        assert!((t.imu[500][0] - 0.1).abs() < 1e-4, "{}", t.imu[500][0]);
    }

    #[test]
    fn invalid_specs_are_rejected_with_the_argument_name() {
        let mut spec = builtin("paper", 0.01).unwrap();
        spec.dt = 0.0;
        assert!(matches!(spec.generate(), Err(Error::InvalidArgument { arg, .. }) if arg == "dt"));
        let mut spec = builtin("paper", 0.01).unwrap();
        spec.segments[2].duration = -1.0;
        assert!(
            matches!(spec.generate(), Err(Error::InvalidArgument { arg, .. }) if arg == "segments")
        );
        let mut spec = builtin("paper", 0.01).unwrap();
        spec.segments[0].pitch_rate = 1.0;
        assert!(spec.generate().is_err(), "pitch beyond 80° is refused");
        for rate in [1e4, -10.5] {
            let mut spec = builtin("paper", 0.01).unwrap();
            spec.segments[1].yaw_rate = rate;
            let err = spec.generate().unwrap_err().to_string();
            assert!(err.starts_with("segments: row 1: a yaw rate of"), "{err}");
        }
        let mut spec = builtin("paper", 0.01).unwrap();
        spec.segments[1].yaw_rate = MAX_TURN_RATE;
        spec.segments[1].duration = 0.5;
        assert!(spec.generate().is_ok(), "the bound itself is allowed");
    }
}
