//! Covariance health of the INS/DVL EKF over long, hostile missions.
//!
//! Every test flies a simulated mission through the public API (trajectory segments →
//! truth and ideal IMU → `SensorSim` noisy IMU/DVL → `Ekf::propagate` / `Ekf::apply`,
//! as a pass's epoch does them) and checks the error covariance P at every DVL epoch
//! (1 Hz, whether or not a measurement is applied there, so outage epochs are checked
//! too):
//!
//! - every entry finite;
//! - symmetric: `max |P − Pᵀ| ≤ 1e-12 · max |P|`;
//! - positive semidefinite: the smallest eigenvalue (nalgebra `SymmetricEigen`) is at
//!   least `−1e-9 · trace P`.
//!
//! Rate choice: 10 hours at the paper's 100 Hz IMU is 3.6 M filter steps per run, too
//! slow for several runs in `cargo test`. The 10-hour missions here use a **10 Hz IMU**
//! (`dt = 0.1 s`, `FilterConfig::imu_dt = 0.1` so the filter's white-noise PSD `q·imu_dt`
//! matches the sample rate) and a 1 Hz DVL; 360 000 steps and 36 000 eigen-checks per
//! run. The filter does not care about the rate beyond `Φ = I + FΔt` staying accurate,
//! which it does for the turn rates used (at most 45°/s → 0.08 rad per step).
//! One short test runs at the paper's 100 Hz as well.

use nalgebra::SymmetricEigen;
use pronet::ekf::{Aiding, FilterConfig, Matrix15};
use pronet::noise::StrategySpec;

mod mission;
use mission::*;

/// IMU period of the long missions [s] (10 Hz; see the module comment).
const IMU_DT: f64 = 0.1;
/// DVL period [s].
const DVL_PERIOD: f64 = 1.0;
/// Length of every DVL outage [s].
const OUTAGE: f64 = 60.0;

fn deg(x: f64) -> f64 {
    x.to_radians()
}

// ---------------------------------------------------------------------------------------
// The health check.

/// What one check measured.
#[derive(Clone, Copy, Debug)]
struct Health {
    /// `max |P − Pᵀ| / max |P|`.
    asymmetry: f64,
    /// Smallest eigenvalue over the trace.
    min_eig_over_trace: f64,
}

/// Check P: finite, symmetric to 1e-12 relative, smallest eigenvalue ≥ −1e-9·trace.
fn check_covariance(p: &Matrix15) -> Result<Health, String> {
    if let Some(i) = p.iter().position(|v| !v.is_finite()) {
        return Err(format!(
            "P has a non-finite entry at ({}, {}): {}",
            i % 15,
            i / 15,
            p.as_slice()[i]
        ));
    }
    let scale = p.amax();
    let asym = (p - p.transpose()).amax();
    if asym > 1e-12 * scale {
        return Err(format!(
            "P is not symmetric: max |P - P^T| = {asym:e}, max |P| = {scale:e}"
        ));
    }
    let trace = p.trace();
    let eig = SymmetricEigen::new(*p).eigenvalues;
    let min = eig.min();
    if min < -1e-9 * trace {
        return Err(format!(
            "P is not positive semidefinite: smallest eigenvalue {min:e}, trace {trace:e}, \
             eigenvalues {:?}",
            eig.as_slice()
        ));
    }
    Ok(Health {
        asymmetry: if scale > 0.0 { asym / scale } else { 0.0 },
        min_eig_over_trace: if trace > 0.0 { min / trace } else { 0.0 },
    })
}

// ---------------------------------------------------------------------------------------
// The checker itself can fail.

#[test]
fn checker_rejects_asymmetric_indefinite_and_non_finite_matrices() {
    let good = FilterConfig::default().p0();
    assert!(check_covariance(&good).is_ok());
    // Positive semidefinite with a zero eigenvalue is fine.
    let mut singular = good;
    singular[(4, 4)] = 0.0;
    assert!(check_covariance(&singular).is_ok());

    let mut asym = good;
    asym[(0, 3)] = 1e-6;
    assert!(check_covariance(&asym)
        .unwrap_err()
        .contains("not symmetric"));

    // A symmetric matrix with a clearly negative eigenvalue: [[1, 2], [2, 1]] has −1.
    let mut indefinite = good;
    indefinite[(0, 0)] = 1.0;
    indefinite[(1, 1)] = 1.0;
    indefinite[(0, 1)] = 2.0;
    indefinite[(1, 0)] = 2.0;
    assert!(check_covariance(&indefinite)
        .unwrap_err()
        .contains("not positive semidefinite"));

    // A negative eigenvalue just past the tolerance is caught, one inside it is not.
    let mut tiny = Matrix15::identity();
    let tol = 1e-9 * 14.0;
    tiny[(14, 14)] = -1.01 * tol;
    assert!(check_covariance(&tiny).is_err());
    tiny[(14, 14)] = -0.5 * tol;
    assert!(check_covariance(&tiny).is_ok());

    let mut nan = good;
    nan[(7, 7)] = f64::NAN;
    assert!(check_covariance(&nan).unwrap_err().contains("non-finite"));
}

#[test]
fn mission_has_sharp_turns_outages_and_lasts_ten_hours() {
    let (m, truth) = ten_hour_truth();
    assert_eq!(truth.len(), 360_000);
    assert_eq!(m.outages.len(), 20);
    assert_eq!(m.sharp_turns.len(), 100);
    // A 90° heading change in 3 s (the first turn of the first hour), from the truth.
    let k0 = (m.sharp_turns[0] / IMU_DT).round() as usize;
    let k1 = k0 + (3.0 / IMU_DT).round() as usize;
    let dyaw = pronet::attitude::wrap_angle(truth.rpy[k1][2] - truth.rpy[k0][2]);
    assert!((dyaw - deg(90.0)).abs() < 1e-9, "heading change {dyaw}");
    // Outages never overlap and lie within the mission.
    for w in m.outages.windows(2) {
        assert!(w[0].1 <= w[1].0, "{:?}", m.outages);
    }
    assert!(m.outages.last().unwrap().1 < truth.duration());
    // Some sharp turn starts inside every hour's first outage.
    for hour in 0..10 {
        let (a, b) = m.outages[2 * hour];
        assert!(m.sharp_turns.iter().any(|&t| t >= a && t < b));
    }
}

// ---------------------------------------------------------------------------------------
// 10-hour missions, one test per constant q (per-sample IMU variances, all channels).

fn ten_hours(label: &str, aiding: Aiding, strategy: StrategySpec) {
    let (m, truth) = ten_hour_truth();
    let cfg = filter_config(IMU_DT, aiding);
    let r = fly(label, m, truth, &cfg, &strategy, false);
    assert_mission_exercised(m, truth, &r);
}

fn ten_hours_with_q(label: &str, q: [f64; 6]) {
    ten_hours(label, Aiding::Body, StrategySpec::Constant { q });
}

#[test]
fn ten_hours_q_1e_minus_12() {
    ten_hours_with_q("q=1e-12", [1e-12; 6]);
}

#[test]
fn ten_hours_q_1e_minus_6() {
    ten_hours_with_q("q=1e-6", [1e-6; 6]);
}

#[test]
fn ten_hours_q_1() {
    ten_hours_with_q("q=1", [1.0; 6]);
}

#[test]
fn ten_hours_q_1e3() {
    ten_hours_with_q("q=1e3", [1e3; 6]);
}

/// Accelerometer q fifteen orders of magnitude above the gyro q: an ill-conditioned P.
#[test]
fn ten_hours_q_accel_1e3_gyro_1e_minus_12() {
    ten_hours_with_q(
        "q=accel 1e3, gyro 1e-12",
        [1e3, 1e3, 1e3, 1e-12, 1e-12, 1e-12],
    );
}

/// The reverse: gyro q 1e3 (a 31 rad/s per-sample σ, attitude all but unknown) with a
/// near-perfect accelerometer. The linearization is meaningless here. In the classic
/// formulation the estimate diverges (|v̂| ~ 1e9 m/s after 6 h) until the update finds
/// S not positive definite and returns `Error::Numerical` (t ≈ 19251 s); the invariant
/// one, whose velocity feedback is a rotation, flies the 10 hours
/// (`ten_hours_q_gyro_1e3_accel_1e_minus_12`). What must hold in either: P is healthy
/// at every epoch up to the end or a clean error, never a panic or NaN.
#[test]
fn q_gyro_1e3_accel_1e_minus_12_keeps_p_healthy_until_a_clean_error() {
    let (m, truth) = ten_hour_truth();
    let cfg = filter_config(IMU_DT, Aiding::Body);
    let q = [1e-12, 1e-12, 1e-12, 1e3, 1e3, 1e3];
    let r = fly(
        "q=accel 1e-12, gyro 1e3",
        m,
        truth,
        &cfg,
        &StrategySpec::Constant { q },
        true,
    );
    assert!(
        r.checks >= 3600,
        "P checked for at least an hour: {}",
        r.checks
    );
    if let Some((t, e)) = &r.failure {
        assert!(
            matches!(e, pronet::Error::Numerical(_)),
            "t = {t}: a numerical failure, not {e:?}"
        );
    }
}

/// Same case in the default (invariant) formulation, demanding the full 10 hours.
#[test]
fn ten_hours_q_gyro_1e3_accel_1e_minus_12() {
    ten_hours_with_q(
        "q=accel 1e-12, gyro 1e3",
        [1e-12, 1e-12, 1e-12, 1e3, 1e3, 1e3],
    );
}

#[test]
fn ten_hours_nav_frame_aiding() {
    ten_hours(
        "nav aiding, q=1e-6",
        Aiding::Nav,
        StrategySpec::Constant { q: [1e-6; 6] },
    );
}

const MEHRA: StrategySpec = StrategySpec::Mehra {
    window: 5,
    prior_q: [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6],
};

/// Mehra's adaptive Q̂ = K C Kᵀ replaces the constant Q_d once its window is full. On
/// this mission the adaptive loop diverges: the accelerometer-bias estimate wanders to
/// ~100 m/s² and the height to ~1e6 m over six hours, the velocity error reaches 1e3
/// m/s in the outages, and (depending on rounding) P grows to ~1e54 until the update
/// finds S not positive definite (t ≈ 23838 s classic; the invariant formulation's
/// prediction fails at t ≈ 24492 s). What must hold: P is healthy at every
/// epoch up to the end or to that clean `Error::Numerical`.
#[test]
fn mehra_adaptive_q_keeps_p_healthy_until_the_end_or_a_clean_error() {
    let (m, truth) = ten_hour_truth();
    let cfg = filter_config(IMU_DT, Aiding::Body);
    let r = fly("mehra(5)", m, truth, &cfg, &MEHRA, true);
    assert!(
        r.checks >= 3600,
        "P checked for at least an hour: {}",
        r.checks
    );
    match &r.failure {
        None => assert_mission_exercised(m, truth, &r),
        Some((t, e)) => assert!(
            matches!(e, pronet::Error::Numerical(_)),
            "t = {t}: a numerical failure, not {e:?}"
        ),
    }
}

/// Same, demanding the full 10 hours without a filter error. Ignored: see above.
#[test]
#[ignore = "Mehra(5) diverges on this mission (b_a estimate ~100 m/s², h ~1e6 m) and the \
            filter fails at t ≈ 24492 s (P itself stays PSD)"]
fn ten_hours_mehra_adaptive_q() {
    ten_hours("mehra(5)", Aiding::Body, MEHRA);
}

/// The first hour of the mission at the paper's 100 Hz IMU, tuned to the true noise.
#[test]
fn one_hour_at_100_hz() {
    let mut m = Mission::default();
    m.hour();
    let truth = m.spec(0.01).generate().unwrap();
    assert_eq!(truth.len(), 360_000);
    let cfg = filter_config(0.01, Aiding::Body);
    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let r = fly(
        "100 Hz, q=true",
        &m,
        &truth,
        &cfg,
        &StrategySpec::Constant { q },
        false,
    );
    assert_mission_exercised(&m, &truth, &r);
}
