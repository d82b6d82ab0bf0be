//! Covariance health of the INS/DVL EKF over long, hostile missions.
//!
//! Every test flies a simulated mission through the public API (trajectory segments →
//! truth and ideal IMU → `SensorSim` noisy IMU/DVL → `Ekf::propagate` / `Ekf::update`,
//! as `Ekf::step` does them) and checks the error covariance P at every DVL epoch
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

use nalgebra::{SymmetricEigen, Vector3};
use pronet::ekf::{Aiding, Ekf, FilterConfig, Matrix15, POS, VEL};
use pronet::mechanization::ImuSample;
use pronet::noise::StrategySpec;
use pronet::sensors::{SensorConfig, SensorSim, VarianceSchedule};
use pronet::trajectory::{paper_origin, Segment, TrajectorySpec, Truth};
use std::time::Instant;

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
// Missions.

/// Builds a segment list while keeping track of time, so that outages can be placed
/// relative to manoeuvres.
#[derive(Default)]
struct Mission {
    segments: Vec<Segment>,
    t: f64,
    /// `[start, end)` of every DVL outage [s].
    outages: Vec<(f64, f64)>,
    /// Start times of the sharp (≥ 30°/s) turns [s].
    sharp_turns: Vec<f64>,
}

impl Mission {
    fn seg(&mut self, duration: f64, accel: f64, yaw_rate_deg: f64, pitch_rate_deg: f64) {
        self.segments.push(Segment::new(
            duration,
            accel,
            deg(yaw_rate_deg),
            deg(pitch_rate_deg),
        ));
        self.t += duration;
    }

    fn straight(&mut self, duration: f64) {
        self.seg(duration, 0.0, 0.0, 0.0);
    }

    /// A 90° heading change (`sign` +1 right, −1 left) in `seconds`.
    fn sharp_turn(&mut self, sign: f64, seconds: f64) {
        self.sharp_turns.push(self.t);
        self.seg(seconds, 0.0, sign * 90.0 / seconds, 0.0);
    }

    /// A DVL outage starting `lead` seconds from now (negative: it began already); no
    /// segment is added.
    fn outage_in(&mut self, lead: f64) {
        let start = self.t + lead;
        self.outages.push((start, start + OUTAGE));
    }

    /// One hour: straight legs, sharp 90° turns both ways (3 s at 30°/s, 2 s at 45°/s),
    /// a zig-zag of sharp turns, speed changes, a 10° dive and climb back, and two 60 s
    /// DVL outages, each over sharp turns (when the attitude error grows fastest).
    fn hour(&mut self) {
        let t0 = self.t;
        self.straight(300.0);
        self.sharp_turn(1.0, 3.0);
        self.straight(297.0);
        self.seg(20.0, 0.05, 0.0, 0.0);
        self.straight(280.0);
        // The outage starts 20 s before a 45°/s left turn and ends 38 s after it.
        self.straight(180.0);
        self.outage_in(0.0);
        self.straight(20.0);
        self.sharp_turn(-1.0, 2.0);
        self.straight(298.0);
        self.seg(2.0, 0.0, 0.0, -5.0);
        self.straight(100.0);
        self.seg(2.0, 0.0, 0.0, 5.0);
        self.seg(20.0, -0.05, 0.0, 0.0);
        self.straight(276.0);
        // Zig-zag: four pairs of sharp turns (26 s a pair). An outage covers the last
        // two pairs: it starts 16 s before the third pair and ends 2 s after the last
        // turn (which ends 42 s into the third pair), so updates resume mid-manoeuvre.
        for pair in 0..4 {
            if pair == 2 {
                self.outage_in(-16.0);
            }
            self.sharp_turn(1.0, 3.0);
            self.straight(10.0);
            self.sharp_turn(-1.0, 3.0);
            self.straight(10.0);
        }
        let used = self.t - t0;
        self.straight(3600.0 - used);
    }

    fn spec(&self, dt: f64) -> TrajectorySpec {
        TrajectorySpec {
            name: "covariance-health".into(),
            lla0: paper_origin(),
            speed0: 1.5,
            rpy0: Vector3::new(deg(2.0), 0.0, deg(30.0)),
            segments: self.segments.clone(),
            dt,
        }
    }

    fn in_outage(&self, t: f64) -> bool {
        self.outages.iter().any(|&(a, b)| t >= a && t < b)
    }
}

fn ten_hour_mission() -> Mission {
    let mut m = Mission::default();
    for _ in 0..10 {
        m.hour();
    }
    assert!((m.t - 36_000.0).abs() < 1e-6, "mission lasts {} s", m.t);
    m
}

/// Truth of the 10-hour mission at 10 Hz, generated once for all tests.
fn ten_hour_truth() -> &'static (Mission, Truth) {
    static CELL: std::sync::OnceLock<(Mission, Truth)> = std::sync::OnceLock::new();
    CELL.get_or_init(|| {
        let m = ten_hour_mission();
        let truth = m.spec(IMU_DT).generate().expect("mission generates");
        (m, truth)
    })
}

const LEVER_ARM: [f64; 3] = [0.4, -0.1, 0.6];

/// Realistic sensors: the paper's IMU noise, plus a constant bias, a slow bias random
/// walk, a lever arm.
fn sensors() -> SensorConfig {
    let mut s = SensorConfig::paper();
    s.imu.variance = VarianceSchedule::constant([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]);
    s.imu.bias = [2e-3, -1e-3, 1.5e-3, 3e-5, -2e-5, 1e-5];
    s.imu.bias_rw_psd = [1e-10, 1e-10, 1e-10, 1e-14, 1e-14, 1e-14];
    s.dvl.period = DVL_PERIOD;
    s.dvl.lever_arm = Vector3::from(LEVER_ARM);
    s
}

fn filter_config(imu_dt: f64, aiding: Aiding) -> FilterConfig {
    FilterConfig {
        accel_bias_psd: 1e-10,
        gyro_bias_psd: 1e-14,
        lever_arm: Vector3::from(LEVER_ARM),
        aiding,
        imu_dt,
        ..FilterConfig::default()
    }
}

/// What a mission run saw, for the sanity assertions that show the scenario really
/// exercised what it claims to.
#[derive(Debug)]
struct Report {
    checks: usize,
    updates: usize,
    skipped_updates: usize,
    worst_asymmetry: f64,
    worst_min_eig_over_trace: f64,
    /// Per outage: (velocity σ just before it, at its end before the first update,
    /// right after the first update).
    outage_vel_sigma: Vec<(f64, f64, f64)>,
    /// Largest horizontal velocity error [m/s] (for the log only).
    max_vel_error: f64,
    /// Horizontal position σ at the end [m].
    final_pos_sigma: f64,
    /// Time and error of a numerical failure of the filter, when one is allowed.
    failure: Option<(f64, pronet::Error)>,
    seconds: f64,
}

fn horizontal_vel_sigma(ekf: &Ekf) -> f64 {
    (ekf.p[(VEL, VEL)] + ekf.p[(VEL + 1, VEL + 1)]).sqrt()
}

/// Fly `mission` (its truth at the truth's own rate) with a filter and noise strategy
/// and check P at every DVL epoch. Panics with the first failed check, naming the
/// case and the epoch. A filter error panics too, unless `allow_filter_error`: then
/// the run stops there and the error is reported.
fn fly(
    label: &str,
    mission: &Mission,
    truth: &Truth,
    cfg: &FilterConfig,
    strategy: &StrategySpec,
    allow_filter_error: bool,
) -> Report {
    let start = Instant::now();
    let sensors = sensors();
    let dt = truth.dt;
    let dvl_every = (DVL_PERIOD / dt).round() as usize;
    assert!((dvl_every as f64 * dt - DVL_PERIOD).abs() < 1e-9);
    let mut sim = SensorSim::new(&sensors, 7, 0);
    let mut ekf = Ekf::new(cfg, truth.states[0], Vector3::zeros(), Vector3::zeros())
        .expect("valid filter config");
    let mut strategy = strategy.build(cfg.bias_psd());
    let mut report = Report {
        checks: 0,
        updates: 0,
        skipped_updates: 0,
        worst_asymmetry: 0.0,
        worst_min_eig_over_trace: f64::INFINITY,
        outage_vel_sigma: Vec::new(),
        max_vel_error: 0.0,
        final_pos_sigma: f64::NAN,
        failure: None,
        seconds: 0.0,
    };
    let mut steps_since_update = 0;
    let mut was_in_outage = false;
    let mut sigma_before_outage = horizontal_vel_sigma(&ekf);
    let fail = |t: f64, what: &str| -> ! {
        panic!("[{label}] t = {t} s: {what}");
    };
    for k in 0..truth.len() {
        let raw = ImuSample::from_array(&sim.imu(&sensors.imu, &truth.imu[k], truth.time[k], dt));
        let k1 = k + 1;
        let t = truth.time[k1];
        let due = k1 % dvl_every == 0;
        // Outages are decided on the DVL epoch's exact time (a whole number of periods).
        let outage = due && mission.in_outage((k1 / dvl_every) as f64 * DVL_PERIOD);
        steps_since_update += 1;
        if outage && !was_in_outage {
            sigma_before_outage = horizontal_vel_sigma(&ekf);
        }
        let z = (due && !outage).then(|| {
            let ideal = &truth.imu[k];
            let gyro = Vector3::new(ideal[3], ideal[4], ideal[5]);
            sim.dvl(&sensors.dvl, &truth.states[k1], &gyro)
        });
        // Propagate, then update (what `Ekf::step` does), so that σ at the end of an
        // outage can be read between the two.
        match ekf.propagate(&raw, dt, strategy.process_noise()) {
            Ok(()) => {}
            Err(e) if allow_filter_error => {
                report.failure = Some((t, e));
                break;
            }
            Err(e) => fail(t, &format!("prediction failed: {e}")),
        }
        let sigma_end_of_outage = horizontal_vel_sigma(&ekf);
        if let Some(z) = z {
            match ekf.update(&z) {
                Ok(info) => strategy.after_update(&info, steps_since_update),
                Err(e) if allow_filter_error => {
                    report.failure = Some((t, e));
                    break;
                }
                Err(e) => fail(t, &format!("update failed: {e}")),
            }
        }
        let dv = ekf.nav.vel - truth.states[k1].vel;
        report.max_vel_error = report.max_vel_error.max(dv[0].hypot(dv[1]));
        if due {
            if outage {
                report.skipped_updates += 1;
            } else {
                report.updates += 1;
                steps_since_update = 0;
                if was_in_outage {
                    report.outage_vel_sigma.push((
                        sigma_before_outage,
                        sigma_end_of_outage,
                        horizontal_vel_sigma(&ekf),
                    ));
                }
            }
            was_in_outage = outage;
            let h = check_covariance(&ekf.p).unwrap_or_else(|e| fail(t, &e));
            report.checks += 1;
            report.worst_asymmetry = report.worst_asymmetry.max(h.asymmetry);
            report.worst_min_eig_over_trace =
                report.worst_min_eig_over_trace.min(h.min_eig_over_trace);
        }
    }
    if report.failure.is_none() {
        let nav = ekf.nav;
        let values = nav.lla.iter().chain(nav.vel.iter()).chain(nav.dcm.iter());
        let values = values
            .chain(ekf.accel_bias.iter())
            .chain(ekf.gyro_bias.iter());
        assert!(
            values.copied().all(f64::is_finite),
            "[{label}] non-finite final state {ekf:?}"
        );
    }
    report.final_pos_sigma = (ekf.p[(POS, POS)] + ekf.p[(POS + 1, POS + 1)]).sqrt();
    report.seconds = start.elapsed().as_secs_f64();
    eprintln!("[{label}] {report:?}");
    report
}

/// The sanity assertions every complete mission run must meet: the checks ran at every
/// DVL epoch, the outages happened and behaved like outages.
fn assert_mission_exercised(mission: &Mission, truth: &Truth, r: &Report) {
    assert!(r.failure.is_none(), "{:?}", r.failure);
    let epochs = (truth.duration() / DVL_PERIOD).round() as usize;
    assert_eq!(r.checks, epochs, "one check per DVL epoch");
    let outage_epochs = (mission.outages.len() as f64 * OUTAGE / DVL_PERIOD).round() as usize;
    assert_eq!(
        r.skipped_updates, outage_epochs,
        "every outage epoch skipped"
    );
    assert_eq!(r.updates + r.skipped_updates, epochs);
    assert_eq!(r.outage_vel_sigma.len(), mission.outages.len());
    for (i, &(before, end, after)) in r.outage_vel_sigma.iter().enumerate() {
        // Without aiding the velocity uncertainty grows; the first update shrinks it.
        assert!(
            end > before,
            "outage {i}: velocity σ did not grow ({before} -> {end})"
        );
        assert!(
            after < end,
            "outage {i}: first update did not shrink velocity σ ({end} -> {after})"
        );
    }
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
