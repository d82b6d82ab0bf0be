//! The missions the covariance-health tests fly: a segment builder that places DVL
//! outages relative to manoeuvres, the 10-hour mission and its truth, the sensors and
//! filter, and [`fly`], which runs a filter over a mission and checks P at every DVL
//! epoch.

use nalgebra::Vector3;
use pronet::ekf::{Aiding, Applied, Ekf, FilterConfig, POS, VEL};
use pronet::measurement::Velocity;
use pronet::mechanization::ImuSample;
use pronet::noise::StrategySpec;
use pronet::sensors::{SensorConfig, SensorSim, VarianceSchedule};
use pronet::trajectory::{paper_origin, Segment, TrajectorySpec, Truth};
use std::time::Instant;

use super::{check_covariance, deg, DVL_PERIOD, IMU_DT, OUTAGE};

/// Builds a segment list while keeping track of time, so that outages can be placed
/// relative to manoeuvres.
#[derive(Default)]
pub(crate) struct Mission {
    pub(crate) segments: Vec<Segment>,
    pub(crate) t: f64,
    /// `[start, end)` of every DVL outage [s].
    pub(crate) outages: Vec<(f64, f64)>,
    /// Start times of the sharp (≥ 30°/s) turns [s].
    pub(crate) sharp_turns: Vec<f64>,
}

impl Mission {
    pub(crate) fn seg(
        &mut self,
        duration: f64,
        accel: f64,
        yaw_rate_deg: f64,
        pitch_rate_deg: f64,
    ) {
        self.segments.push(Segment::new(
            duration,
            accel,
            deg(yaw_rate_deg),
            deg(pitch_rate_deg),
        ));
        self.t += duration;
    }

    pub(crate) fn straight(&mut self, duration: f64) {
        self.seg(duration, 0.0, 0.0, 0.0);
    }

    /// A 90° heading change (`sign` +1 right, −1 left) in `seconds`.
    pub(crate) fn sharp_turn(&mut self, sign: f64, seconds: f64) {
        self.sharp_turns.push(self.t);
        self.seg(seconds, 0.0, sign * 90.0 / seconds, 0.0);
    }

    /// A DVL outage starting `lead` seconds from now (negative: it began already); no
    /// segment is added.
    pub(crate) fn outage_in(&mut self, lead: f64) {
        let start = self.t + lead;
        self.outages.push((start, start + OUTAGE));
    }

    /// One hour: straight legs, sharp 90° turns both ways (3 s at 30°/s, 2 s at 45°/s),
    /// a zig-zag of sharp turns, speed changes, a 10° dive and climb back, and two 60 s
    /// DVL outages, each over sharp turns (when the attitude error grows fastest).
    pub(crate) fn hour(&mut self) {
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

    pub(crate) fn spec(&self, dt: f64) -> TrajectorySpec {
        TrajectorySpec {
            name: "covariance-health".into(),
            lla0: paper_origin(),
            speed0: 1.5,
            rpy0: Vector3::new(deg(2.0), 0.0, deg(30.0)),
            segments: self.segments.clone(),
            dt,
        }
    }

    pub(crate) fn in_outage(&self, t: f64) -> bool {
        self.outages.iter().any(|&(a, b)| t >= a && t < b)
    }
}

pub(crate) fn ten_hour_mission() -> Mission {
    let mut m = Mission::default();
    for _ in 0..10 {
        m.hour();
    }
    assert!((m.t - 36_000.0).abs() < 1e-6, "mission lasts {} s", m.t);
    m
}

/// Truth of the 10-hour mission at 10 Hz, generated once for all tests.
pub(crate) fn ten_hour_truth() -> &'static (Mission, Truth) {
    static CELL: std::sync::OnceLock<(Mission, Truth)> = std::sync::OnceLock::new();
    CELL.get_or_init(|| {
        let m = ten_hour_mission();
        let truth = m.spec(IMU_DT).generate().expect("mission generates");
        (m, truth)
    })
}

pub(crate) const LEVER_ARM: [f64; 3] = [0.4, -0.1, 0.6];

/// Realistic sensors: the paper's IMU noise, plus a constant bias, a slow bias random
/// walk, a lever arm.
pub(crate) fn sensors() -> SensorConfig {
    let mut s = SensorConfig::paper();
    s.imu.variance = VarianceSchedule::constant([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]);
    s.imu.bias = [2e-3, -1e-3, 1.5e-3, 3e-5, -2e-5, 1e-5];
    s.imu.bias_rw_psd = [1e-10, 1e-10, 1e-10, 1e-14, 1e-14, 1e-14];
    s.dvl.period = DVL_PERIOD;
    s.dvl.lever_arm = Vector3::from(LEVER_ARM);
    s
}

pub(crate) fn filter_config(imu_dt: f64, aiding: Aiding) -> FilterConfig {
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
pub(crate) struct Report {
    pub(crate) checks: usize,
    pub(crate) updates: usize,
    pub(crate) skipped_updates: usize,
    pub(crate) worst_asymmetry: f64,
    pub(crate) worst_min_eig_over_trace: f64,
    /// Per outage: (velocity σ just before it, at its end before the first update,
    /// right after the first update).
    pub(crate) outage_vel_sigma: Vec<(f64, f64, f64)>,
    /// Largest horizontal velocity error [m/s] (for the log only).
    pub(crate) max_vel_error: f64,
    /// Horizontal position σ at the end [m].
    pub(crate) final_pos_sigma: f64,
    /// Time and error of a numerical failure of the filter, when one is allowed.
    pub(crate) failure: Option<(f64, pronet::Error)>,
    pub(crate) seconds: f64,
}

pub(crate) fn horizontal_vel_sigma(ekf: &Ekf) -> f64 {
    (ekf.p[(VEL, VEL)] + ekf.p[(VEL + 1, VEL + 1)]).sqrt()
}

/// Fly `mission` (its truth at the truth's own rate) with a filter and noise strategy
/// and check P at every DVL epoch. Panics with the first failed check, naming the
/// case and the epoch. A filter error panics too, unless `allow_filter_error`: then
/// the run stops there and the error is reported.
pub(crate) fn fly(
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
        // Propagate, then update (what a pass's epoch does), so that σ at the end of an
        // outage can be read between the two.
        match ekf.propagate(&raw, dt, strategy.process_noise()) {
            Ok(_) => {}
            Err(e) if allow_filter_error => {
                report.failure = Some((t, e));
                break;
            }
            Err(e) => fail(t, &format!("prediction failed: {e}")),
        }
        let sigma_end_of_outage = horizontal_vel_sigma(&ekf);
        if let Some(z) = z {
            let cfg = ekf.config();
            let reading = Velocity {
                z,
                variance: cfg.dvl_variance,
                lever_arm: cfg.lever_arm,
                frame: cfg.aiding,
                gate: cfg.innovation_gate,
            };
            match ekf.apply(&reading) {
                Ok(Applied {
                    report: Some(info), ..
                }) => strategy.after_update(&info, steps_since_update),
                Ok(_) => unreachable!("a velocity update reports"),
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
pub(crate) fn assert_mission_exercised(mission: &Mission, truth: &Truth, r: &Report) {
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
