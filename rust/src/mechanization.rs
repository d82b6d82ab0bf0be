//! NED strapdown mechanization: one step per IMU sample, its exact inverse (used to
//! synthesize the ideal IMU of a trajectory), and integration of an IMU array.
//!
//! The step is specified in `docs/reference/filter.md` ("Strapdown step"): attitude by rotation
//! vectors, velocity with the mid-step attitude and Coriolis/gravity at the start of the
//! step, position trapezoidal in velocity.

use crate::attitude::{exp_so3, log_so3, orthonormalize};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::earth;
use crate::error::{check, Error, Result};
use crate::memory::Estimate;
use nalgebra::{Matrix3, Vector3};
use std::mem::size_of;

/// Navigation state: geodetic position `[lat, lon, h]` \[rad, rad, m\], NED velocity
/// \[m/s\] and the body(FRD)-to-NED DCM.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavState {
    pub lla: Vector3<f64>,
    pub vel: Vector3<f64>,
    pub dcm: Matrix3<f64>,
}

/// One IMU sample: specific force \[m/s²\] and angular rate \[rad/s\], body frame, each the
/// mean over the sample interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSample {
    pub accel: Vector3<f64>,
    pub gyro: Vector3<f64>,
}

impl ImuSample {
    /// From `[f_x, f_y, f_z, ω_x, ω_y, ω_z]`.
    #[inline]
    pub fn from_array(a: &[f64; 6]) -> Self {
        Self {
            accel: Vector3::new(a[0], a[1], a[2]),
            gyro: Vector3::new(a[3], a[4], a[5]),
        }
    }

    /// As `[f_x, f_y, f_z, ω_x, ω_y, ω_z]`.
    #[inline]
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.accel[0],
            self.accel[1],
            self.accel[2],
            self.gyro[0],
            self.gyro[1],
            self.gyro[2],
        ]
    }
}

/// Rates that the step evaluates at its start: Earth rate and transport rate \[rad/s,
/// NED\] and gravity \[m/s², NED\].
#[derive(Clone, Copy, Debug)]
pub struct FrameRates {
    pub earth: Vector3<f64>,
    pub transport: Vector3<f64>,
    pub gravity: Vector3<f64>,
    /// The latitude terms they came from (radii of curvature for the EKF's Jacobian).
    pub latitude: earth::Latitude,
}

impl FrameRates {
    #[inline]
    pub fn at(state: &NavState) -> Self {
        let latitude = earth::Latitude::new(state.lla[0]);
        let h = state.lla[2];
        Self {
            earth: latitude.earth_rate_ned(),
            transport: latitude.transport_rate_ned(h, &state.vel),
            gravity: Vector3::new(0.0, 0.0, latitude.gravity(h)),
            latitude,
        }
    }

    /// Rotation rate of NED w.r.t. inertial space, `ω_in = ω_ie + ω_en`.
    #[inline]
    pub fn nav_rate(&self) -> Vector3<f64> {
        self.earth + self.transport
    }

    /// Gravity minus Coriolis acceleration for velocity `v`: `g − (2ω_ie + ω_en) × v`.
    #[inline]
    pub fn kinematic_accel(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.gravity - (2.0 * self.earth + self.transport).cross(v)
    }
}

/// Advance geodetic position `lla` by the trapezoid of NED velocities `v0`, `v1` over `dt`.
/// `start` holds the terms of `lla`'s latitude (the caller usually has them).
/// Shared by the mechanization and the trajectory generator, so that truth positions and
/// mechanized positions follow the same rule.
#[inline]
pub fn advance_position(
    lla: &Vector3<f64>,
    start: &earth::Latitude,
    v0: &Vector3<f64>,
    v1: &Vector3<f64>,
    dt: f64,
) -> Vector3<f64> {
    let h1 = lla[2] - 0.5 * (v0[2] + v1[2]) * dt;
    let h_mid = 0.5 * (lla[2] + h1);
    let lat1 = lla[0] + 0.5 * (v0[0] + v1[0]) * dt / (start.r_n + h_mid);
    let mid = start.near(0.5 * (lla[0] + lat1));
    let lon1 = lla[1] + 0.5 * (v0[1] + v1[1]) * dt / ((mid.r_e + h_mid) * mid.cos);
    Vector3::new(lat1, lon1, h1)
}

/// One strapdown step over `dt` \[s\] with IMU sample `imu`.
#[inline]
pub fn step(state: &NavState, imu: &ImuSample, dt: f64) -> NavState {
    let rates = FrameRates::at(state);
    step_with_rates(state, imu, dt, &rates)
}

/// [`step`] with the frame rates at the start of the step already computed (the EKF
/// needs them for its Jacobian too).
#[inline]
pub fn step_with_rates(state: &NavState, imu: &ImuSample, dt: f64, rates: &FrameRates) -> NavState {
    // C_{k+1} = Exp(−ω_in Δt) C_k Exp(Δθ), split at mid-step where the specific force
    // is resolved: both half-turns are small-angle series, no trigonometry.
    let body_half = exp_so3(&(imu.gyro * (0.5 * dt)));
    let nav_half = exp_so3(&(rates.nav_rate() * (-0.5 * dt)));
    let c_mid = nav_half * state.dcm * body_half;
    let dcm = orthonormalize(&(nav_half * c_mid * body_half));
    let vel = state.vel + c_mid * imu.accel * dt + rates.kinematic_accel(&state.vel) * dt;
    let lla = advance_position(&state.lla, &rates.latitude, &state.vel, &vel, dt);
    NavState { lla, vel, dcm }
}

/// The IMU sample that [`step`] needs to take `s0` to `s1` in `dt` \[s\]: the exact inverse
/// of the attitude and velocity updates. (Position follows from the velocities.)
pub fn invert_step(s0: &NavState, s1: &NavState, dt: f64) -> ImuSample {
    let rates = FrameRates::at(s0);
    let delta = log_so3(&(s0.dcm.transpose() * exp_so3(&(rates.nav_rate() * dt)) * s1.dcm));
    let c_mid = exp_so3(&(rates.nav_rate() * (-0.5 * dt))) * s0.dcm * exp_so3(&(delta * 0.5));
    let accel = c_mid.transpose() * ((s1.vel - s0.vel) / dt - rates.kinematic_accel(&s0.vel));
    ImuSample {
        accel,
        gyro: delta / dt,
    }
}

/// [`integrate`] for outside callers, with the rules of the `mechanize` entry point:
/// finite IMU rows, `dt > 0` \[s\], a start within [`earth::MAX_LATITUDE_DEG`] of the
/// equator, and no overflow: finite but absurd inputs (1e300 m/s², a 1e10 s step) are an
/// error, never NaN states.
pub fn mechanize(initial: &NavState, imu: &[[f64; 6]], dt: f64) -> Result<Vec<NavState>> {
    mechanize_until(initial, imu, dt, &Cancel::default())
}

/// [`mechanize`] that stops with [`Error::Cancelled`] soon after `cancel` is set (it is
/// checked every [`STEPS_PER_CHECK`] samples); the states are [`integrate`]'s.
pub fn mechanize_until(
    initial: &NavState,
    imu: &[[f64; 6]],
    dt: f64,
    cancel: &Cancel,
) -> Result<Vec<NavState>> {
    if let Some(i) = imu.iter().position(|r| r.iter().any(|x| !x.is_finite())) {
        return Err(Error::invalid("imu", format!("row {i} is not finite")));
    }
    check::positive("dt", dt)?;
    earth::check_latitude("lla0", initial.lla[0])?;
    memory(imu.len()).check("this mechanization")?;
    let mut states = Vec::with_capacity(imu.len() + 1);
    states.push(*initial);
    for chunk in imu.chunks(STEPS_PER_CHECK) {
        cancel.check()?;
        let last = states[states.len() - 1];
        states.extend(integrate(&last, chunk, dt).into_iter().skip(1));
    }
    if let Some(k) = states.iter().position(|s| {
        !(s.lla.iter().chain(s.vel.iter()).chain(s.dcm.iter())).all(|x| x.is_finite())
    }) {
        return Err(Error::invalid(
            "imu, dt, lla0, vel0",
            format!("the mechanization overflows to non-finite values at sample {k}; the inputs are far outside any vehicle's range"),
        ));
    }
    Ok(states)
}

/// What [`mechanize`] of `n` samples holds: the n + 1 states, their position, velocity
/// and attitude as arrays, and one block of states integrated at a time (and 4 KiB).
pub fn memory(n: usize) -> Estimate {
    let states = n as f64 + 1.0;
    let remedy = "mechanize fewer samples at once (blocks, each from the last state of the one \
                  before)";
    let mut e = Estimate {
        fixed: ((STEPS_PER_CHECK + 1) * size_of::<NavState>() + 4096) as f64,
        ..Estimate::default()
    };
    e.add(
        "imu",
        "states",
        (states, size_of::<NavState>() as f64),
        remedy,
    );
    e.add(
        "imu",
        "states' arrays",
        (states, size_of::<[f64; 9]>() as f64),
        remedy,
    );
    e
}

/// Mechanize `imu` (samples at a constant step `dt` \[s\]) from `initial`. Returns n + 1
/// states: the initial one, then the state after each sample.
pub fn integrate(initial: &NavState, imu: &[[f64; 6]], dt: f64) -> Vec<NavState> {
    let mut out = Vec::with_capacity(imu.len() + 1);
    out.push(*initial);
    let mut s = *initial;
    for sample in imu {
        s = step(&s, &ImuSample::from_array(sample), dt);
        out.push(s);
    }
    out
}

/// Beyond these a sample is no reading of any IMU (a high-g accelerometer reads up to a
/// few hundred g, a gyro up to tens of rad/s), per axis: a specific force \[m/s²\] and
/// an angular rate \[rad/s\]. A recorded pass and the online navigator refuse a sample
/// beyond them, or not finite, before it is integrated: past them the solution would
/// overflow later, or stay finite and wrong.
pub const MAX_SPECIFIC_FORCE: f64 = 1.0e4;
pub const MAX_ANGULAR_RATE: f64 = 1.0e3;

/// Whether the IMU row `[f (m/s²), ω (rad/s)]` is finite and within
/// [`MAX_SPECIFIC_FORCE`] and [`MAX_ANGULAR_RATE`] (NaN is not).
pub fn imu_row_in_range(row: &[f64; 6]) -> bool {
    row[..3].iter().all(|f| f.abs() <= MAX_SPECIFIC_FORCE)
        && row[3..].iter().all(|w| w.abs() <= MAX_ANGULAR_RATE)
}

/// Why the IMU row is refused, as the end of a sentence naming it ("is not finite",
/// "is beyond any IMU's range …"); None where it is not.
pub fn imu_row_problem(row: &[f64; 6]) -> Option<String> {
    if !row.iter().all(|x| x.is_finite()) {
        Some("is not finite".into())
    } else if !imu_row_in_range(row) {
        Some(format!(
            "is beyond any IMU's range (|f| ≤ {MAX_SPECIFIC_FORCE:e} m/s², |ω| ≤ \
             {MAX_ANGULAR_RATE:e} rad/s per axis; another unit?)"
        ))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::{dcm_from_euler, euler_from_dcm};

    fn at_rest(lat_deg: f64) -> (NavState, [f64; 6]) {
        let s = NavState {
            lla: Vector3::new(lat_deg.to_radians(), 34f64.to_radians(), -5.0),
            vel: Vector3::zeros(),
            dcm: dcm_from_euler(0.02, -0.03, 1.1),
        };
        let rates = FrameRates::at(&s);
        let f = -(s.dcm.transpose() * rates.gravity);
        let w = s.dcm.transpose() * rates.earth;
        (s, [f[0], f[1], f[2], w[0], w[1], w[2]])
    }

    #[test]
    fn inverse_of_a_resting_state_is_earth_rate_and_minus_gravity() {
        let (s, ideal) = at_rest(32.0);
        let imu = invert_step(&s, &s, 0.01).to_array();
        for i in 0..6 {
            assert!(
                (imu[i] - ideal[i]).abs() < 1e-12,
                "channel {i}: {imu:?} vs {ideal:?}"
            );
        }
    }

    /// Chunked for cancellation, `mechanize` gives `integrate`'s states bit for bit; a
    /// set flag stops it before the first chunk.
    #[test]
    fn mechanize_equals_integrate_and_stops_when_cancelled() {
        let (s0, ideal) = at_rest(32.0);
        let imu: Vec<[f64; 6]> = (0..2 * STEPS_PER_CHECK + 7)
            .map(|k| {
                let mut row = ideal;
                row[0] += 1e-3 * (k as f64 * 0.01).sin();
                row
            })
            .collect();
        let whole = integrate(&s0, &imu, 0.01);
        let states = mechanize(&s0, &imu, 0.01).unwrap();
        assert_eq!(states.len(), whole.len());
        for (a, b) in states.iter().zip(&whole) {
            assert_eq!((a.lla, a.vel, a.dcm), (b.lla, b.vel, b.dcm));
        }
        let cancel = Cancel::default();
        cancel.cancel();
        let err = mechanize_until(&s0, &imu, 0.01, &cancel).unwrap_err();
        assert_eq!(err, Error::Cancelled);
    }

    #[test]
    fn one_hour_at_rest_stays_put() {
        let (s0, ideal) = at_rest(32.0);
        let n = 360_000;
        let mut s = s0;
        let sample = ImuSample::from_array(&ideal);
        for _ in 0..n {
            s = step(&s, &sample, 0.01);
        }
        let dp = earth::position_error_ned(&s.lla, &s0.lla);
        assert!(dp.norm() < 0.01, "position drift {dp:?} m");
        assert!(s.vel.norm() < 1e-5, "velocity drift {:?}", s.vel);
        let de = euler_from_dcm(&s.dcm) - euler_from_dcm(&s0.dcm);
        assert!(de.abs().max() < 1e-9, "attitude drift {de:?}");
    }

    #[test]
    fn step_then_invert_recovers_the_sample() {
        let s0 = NavState {
            lla: Vector3::new(0.5, 0.6, -20.0),
            vel: Vector3::new(1.2, -0.4, 0.1),
            dcm: dcm_from_euler(0.1, -0.05, 0.7),
        };
        let sample = ImuSample::from_array(&[0.3, -0.2, -9.7, 0.01, -0.02, 0.05]);
        let s1 = step(&s0, &sample, 0.01);
        let back = invert_step(&s0, &s1, 0.01).to_array();
        let want = sample.to_array();
        for i in 0..6 {
            assert!((back[i] - want[i]).abs() < 1e-10, "{back:?} vs {want:?}");
        }
    }

    #[test]
    fn integrate_returns_initial_plus_one_state_per_sample() {
        let (s0, ideal) = at_rest(10.0);
        let out = integrate(&s0, &[ideal; 5], 0.01);
        assert_eq!(out.len(), 6);
        assert_eq!(out[0], s0);
    }

    #[test]
    fn mechanize_checks_its_inputs_and_overflow() {
        let (s0, ideal) = at_rest(10.0);
        assert_eq!(
            mechanize(&s0, &[ideal; 5], 0.01).unwrap(),
            integrate(&s0, &[ideal; 5], 0.01)
        );
        let mut bad = [ideal; 3];
        bad[2][4] = f64::NAN;
        let err = mechanize(&s0, &bad, 0.01).unwrap_err().to_string();
        assert_eq!(err, "imu: row 2 is not finite");
        let err = mechanize(&s0, &[ideal], 0.0).unwrap_err().to_string();
        assert_eq!(err, "dt: must be finite and > 0, got 0");
        let polar = NavState {
            lla: Vector3::new(89.5f64.to_radians(), 0.0, 0.0),
            ..s0
        };
        let err = mechanize(&polar, &[ideal], 0.01).unwrap_err().to_string();
        assert_eq!(
            err,
            "lla0: latitude must be within ±89° (given in radians; NED is singular at the poles)"
        );
        let err = mechanize(&s0, &[[1e300; 6]; 3], 0.01)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("imu, dt, lla0, vel0: the mechanization overflows"),
            "{err}"
        );
    }
}
