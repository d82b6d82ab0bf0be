//! One simulated run of a scenario, stepped one IMU sample at a time: the sensor
//! simulation, the filter, and the metrics, NIS/NEES and histories it reports.

use crate::attitude::{exp_so3, log_so3};
use crate::earth;
use crate::ekf::{
    Ekf, FilterConfig, Formulation, Matrix15, NisMonitor, UpdateInfo, Vector15, ACC_BIAS, ATT,
    GYRO_BIAS, POS, VEL,
};
use crate::error::Result;
use crate::mechanization::{ImuSample, NavState};
use crate::montecarlo::Scenario;
use crate::noise::{NoiseStrategy, StrategySpec};
use crate::sensors::{normal, stream_rng, AidingSim, DvlMounting, Reading, SensorSim, Stream};
use crate::trajectory::Truth;
use nalgebra::{Vector3, Vector4};

mod aiding;
mod smoothing;
use aiding::AidingTally;
pub use smoothing::SmoothedRecord;
use smoothing::SmootherLog;

/// Per-run scalar metrics. Velocity errors are taken at every IMU epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// `sqrt(mean_k Σ_{N,E,D} δv²)` \[m/s\].
    pub srmse: f64,
    /// `mean_k Σ_{N,E,D} |δv|` \[m/s\].
    pub smae: f64,
    /// Horizontal position error at the end \[m\].
    pub final_horizontal_error: f64,
    /// Largest horizontal position error over the run \[m\].
    pub max_horizontal_error: f64,
    /// Mean NIS over the applied DVL updates.
    pub mean_nis: f64,
    /// DVL updates the innovation gate rejected.
    pub rejected_updates: usize,
    /// DVL readings due but missing (bottom lock lost: [`crate::sensors::DvlDropout`]).
    pub missed_updates: usize,
    /// Depth readings and position fixes applied (the aiding sensors').
    pub depth_updates: usize,
    pub fix_updates: usize,
    /// The sum of the depth and fix updates' NIS, and of their degrees of freedom (its
    /// mean per degree of freedom is 1 when the filter is consistent).
    pub aiding_nis: f64,
    pub aiding_dof: usize,
    /// Time \[s\] at which the NIS showed divergence (see [`NisMonitor`]), if it did.
    pub diverged_at: Option<f64>,
    /// Set when the filter failed numerically; the run's metrics are then NaN.
    pub failure: Option<String>,
    /// With the DVL calibration states: the final `[δk, δμ]` error (estimate minus
    /// the simulated DVL's truth) and its 1σ.
    pub calibration: Option<CalibrationSummary>,
}

/// The DVL calibration states at the end of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationSummary {
    /// `[δk, δμ_x, δμ_y, δμ_z]`, estimate minus truth (scale; rad, body axes).
    pub error: [f64; 4],
    /// The filter's 1σ of the same.
    pub sigma: [f64; 4],
}

/// Recorded histories of one run, at `record_time` epochs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// True estimation error `[δp, δv, ψ, δb_a, δb_g]` (estimate minus truth).
    pub error: Vec<[f64; 15]>,
    /// Filter 1σ of the same states.
    pub sigma: Vec<[f64; 15]>,
    /// IMU variances q the strategy used (NaN where it has none, e.g. Mehra).
    pub imu_variance: Vec<[f64; 6]>,
}

/// Everything one run reports.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRecord {
    pub summary: RunSummary,
    /// NIS at each DVL epoch (gate-rejected updates included).
    pub nis: Vec<f64>,
    /// NEES of the position, velocity, attitude, accelerometer-bias and gyro-bias
    /// blocks after each DVL update (3 dof each).
    pub nees: Vec<[f64; 5]>,
    /// NEES of the DVL calibration states `[δk, δμ]` after each DVL update (4 dof);
    /// empty without them.
    pub calibration_nees: Vec<f64>,
    pub history: Option<History>,
    /// The RTS smoother's metrics of the run, when it was asked for
    /// ([`Run::keep_for_smoother`]) and the filter did not fail.
    pub smoothed: Option<SmoothedRecord>,
}

/// The last N raw IMU samples of a run, as the regressor reads them.
struct ImuWindow {
    buf: Vec<[f32; 6]>,
    head: usize,
}

impl ImuWindow {
    fn new(n: usize) -> Self {
        Self {
            buf: vec![[0.0; 6]; n],
            head: 0,
        }
    }

    fn push(&mut self, s: &[f64; 6]) {
        self.buf[self.head] = s.map(|x| x as f32);
        self.head = (self.head + 1) % self.buf.len();
    }

    /// Write the window channel-major, oldest sample first, into `out` (6·N values).
    fn write_channels(&self, out: &mut [f32]) {
        let n = self.buf.len();
        for c in 0..6 {
            for j in 0..n {
                out[c * n + j] = self.buf[(self.head + j) % n][c];
            }
        }
    }
}

/// One simulated run, stepped one IMU sample at a time.
/// The scenario is passed to every call rather than stored, so stepping touches no
/// shared reference count.
pub struct Run {
    ekf: Ekf,
    strategy: Box<dyn NoiseStrategy>,
    /// Whether the strategy is told the true IMU variance before every step.
    oracle: bool,
    sim: SensorSim,
    /// IMU steps per DVL reading; None without a DVL.
    dvl_every: Option<usize>,
    /// The depth sensor and position fixes; None without them.
    aiding: Option<AidingSim>,
    readings: Vec<Reading>,
    tally: AidingTally,
    record_every: usize,
    k: usize,
    steps_since_update: usize,
    true_bias: [f64; 6],
    sum_sq: f64,
    sum_abs: f64,
    /// North and east position error \[m\] now, and where its norm was largest (the norm
    /// is taken once at the end: `hypot` every step cost ~3 % of a Monte Carlo).
    horizontal: [f64; 2],
    max_horizontal: [f64; 2],
    max_horizontal_sq: f64,
    nis: Vec<f64>,
    rejected_updates: usize,
    missed_updates: usize,
    accepted_nis_sum: f64,
    nis_monitor: NisMonitor,
    nees: Vec<[f64; 5]>,
    calibration_nees: Vec<f64>,
    history: Option<History>,
    window: Option<ImuWindow>,
    failure: Option<String>,
    smoother: Option<Box<SmootherLog>>,
}

fn bias_array(ekf: &Ekf) -> [f64; 6] {
    let (a, g) = (ekf.accel_bias, ekf.gyro_bias);
    [a[0], a[1], a[2], g[0], g[1], g[2]]
}

/// Estimate-minus-truth error of the full state.
fn state_error(ekf: &Ekf, truth: &NavState, true_bias: &[f64; 6]) -> [f64; 15] {
    solution_error(&ekf.nav, &bias_array(ekf), truth, true_bias)
}

/// Estimate-minus-truth error of a solution `nav` with bias estimates `bias`.
fn solution_error(
    nav: &NavState,
    bias: &[f64; 6],
    truth: &NavState,
    true_bias: &[f64; 6],
) -> [f64; 15] {
    let dp = earth::position_error_ned(&nav.lla, &truth.lla);
    let dv = nav.vel - truth.vel;
    // Ĉ = (I − [ψ×]) C ≈ Exp(−ψ) C.
    let psi = -log_so3(&(nav.dcm * truth.dcm.transpose()));
    let ba = Vector3::new(bias[0], bias[1], bias[2])
        - Vector3::new(true_bias[0], true_bias[1], true_bias[2]);
    let bg = Vector3::new(bias[3], bias[4], bias[5])
        - Vector3::new(true_bias[3], true_bias[4], true_bias[5]);
    let mut e = [0.0; 15];
    for (offset, v) in [
        (POS, dp),
        (VEL, dv),
        (ATT, psi),
        (ACC_BIAS, ba),
        (GYRO_BIAS, bg),
    ] {
        e[offset..offset + 3].copy_from_slice(v.as_slice());
    }
    e
}

/// `[δk, δμ]` of the filter's DVL calibration against the simulated DVL's, with its
/// NEES `eᵀ P_cc⁻¹ e` (NaN where P_cc is singular); None without the states.
fn calibration_error(ekf: &Ekf, truth: &DvlMounting) -> Option<([f64; 4], [f64; 4], f64)> {
    let c = ekf.calibration.as_ref()?;
    let e = c.estimate.error_from(truth);
    let v = Vector4::from(e);
    let nees = c.cov.cholesky().map_or(f64::NAN, |ch| v.dot(&ch.solve(&v)));
    Some((e, c.sigma(), nees))
}

/// `eᵀ P⁻¹ e` of one 3-block (NaN where the block is singular).
fn nees3(e: &Vector3<f64>, p: &Matrix15, block: usize) -> f64 {
    match p.fixed_view::<3, 3>(block, block).into_owned().cholesky() {
        Some(ch) => e.dot(&ch.solve(e)),
        None => f64::NAN,
    }
}

/// NEES of each 3-block, each in the coordinates where its error is linear in the
/// state (see `docs/filter.md`, "Metrics"): position, attitude and biases in the
/// classic ones, velocity as the body-frame velocity error rotated to NED,
/// `δV = v̂ − Ĉ Cᵀ v` (the invariant velocity error, exact), against the invariant
/// covariance. The classic `δv` carries `[v̂×]ψ`, which is second-order wrong once
/// heading errors reach degrees; `δV` is what the DVL reads in either formulation.
fn block_nees(ekf: &Ekf, truth: &NavState, error: &[f64; 15]) -> [f64; 5] {
    let p = ekf.covariance();
    let mut nees = [POS, VEL, ATT, ACC_BIAS, GYRO_BIAS]
        .map(|b| nees3(&Vector3::new(error[b], error[b + 1], error[b + 2]), &p, b));
    let dv = ekf.nav.vel - ekf.nav.dcm * (truth.dcm.transpose() * truth.vel);
    nees[1] = nees3(&dv, &ekf.covariance_in(Formulation::Invariant), VEL);
    nees
}

/// Run `run_index`'s start: the filter's initial navigation solution and the IMU's
/// true turn-on bias `[b_a, b_g]`. The filter starts from its prior mean, the bias
/// estimates at zero; the turn-on bias is the configured one, less a draw from the
/// prior when initial errors are sampled, so that every initial error (the biases'
/// too) is a draw from P0 about the configured offset.
pub(crate) fn initial_state(
    scenario: &Scenario,
    filter: &FilterConfig,
    seed: u64,
    run_index: u64,
) -> (NavState, [f64; 6]) {
    let mut nav = scenario.truth.states[0];
    let mut bias = scenario.sensors.imu.bias;
    if scenario.sample_initial_error {
        let mut rng = stream_rng(seed, run_index, Stream::InitialError);
        let dx: [f64; 15] = std::array::from_fn(|i| filter.p0_sigma[i] * normal(&mut rng));
        let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
        nav.lla += earth::ned_delta_to_lla_delta(&nav.lla, &block(POS));
        nav.vel += block(VEL);
        nav.dcm = exp_so3(&(-block(ATT))) * nav.dcm;
        for (i, b) in bias.iter_mut().enumerate() {
            *b -= dx[ACC_BIAS + i];
        }
    }
    (nav, bias)
}

impl Run {
    pub fn new(
        scenario: &Scenario,
        filter: &FilterConfig,
        strategy: &StrategySpec,
        seed: u64,
        run_index: u64,
        record_every: usize,
        window: Option<usize>,
    ) -> Result<Self> {
        let dvl_every = scenario.dvl_every()?;
        let (nav, true_bias) = initial_state(scenario, filter, seed, run_index);
        let mut ekf = Ekf::new(filter, nav, Vector3::zeros(), Vector3::zeros())?;
        let strategy = strategy.build(filter.bias_psd());
        if let Some(q) = strategy.sensitivity_q() {
            ekf.track_sensitivity(q);
        }
        let n_epochs = dvl_every.map_or(0, |every| scenario.truth.len() / every);
        let sensors = &scenario.sensors;
        let aiding = AidingSim::new(
            sensors.depth.as_ref(),
            &sensors.fixes,
            &scenario.truth,
            seed,
            run_index,
        )?;
        let mut run = Self {
            sim: SensorSim::new(&scenario.sensors, seed, run_index).with_turn_on_bias(true_bias),
            ekf,
            oracle: strategy.wants_true_variance(),
            strategy,
            dvl_every,
            aiding,
            readings: Vec::new(),
            tally: AidingTally::default(),
            record_every,
            k: 0,
            steps_since_update: 0,
            true_bias,
            sum_sq: 0.0,
            sum_abs: 0.0,
            horizontal: [0.0; 2],
            max_horizontal: [0.0; 2],
            max_horizontal_sq: 0.0,
            nis: Vec::with_capacity(n_epochs),
            rejected_updates: 0,
            missed_updates: 0,
            accepted_nis_sum: 0.0,
            nis_monitor: NisMonitor::default(),
            nees: Vec::with_capacity(n_epochs),
            calibration_nees: Vec::new(),
            history: (record_every > 0).then(History::default),
            window: window.map(ImuWindow::new),
            failure: None,
            smoother: None,
        };
        if run.oracle {
            // the q in force at the start, as the histories report it
            let q = run
                .sim
                .variance(&scenario.sensors.imu, scenario.truth.time[0]);
            run.strategy.set_true_variance(&q);
        }
        run.record_history(&scenario.truth);
        Ok(run)
    }

    fn record_history(&mut self, truth: &Truth) {
        if let Some(h) = self.history.as_mut() {
            if self.k.is_multiple_of(self.record_every) {
                let truth = &truth.states[self.k];
                h.error.push(state_error(&self.ekf, truth, &self.true_bias));
                h.sigma.push(self.ekf.sigma_up_to_date());
                h.imu_variance
                    .push(self.strategy.imu_variance().unwrap_or([f64::NAN; 6]));
            }
        }
    }

    /// Advance by one IMU sample (and a DVL update when one is due).
    pub fn step(&mut self, scenario: &Scenario) {
        let truth = &*scenario.truth;
        let ideal = &truth.imu[self.k];
        self.true_bias = *self.sim.bias();
        if self.oracle {
            let q = self.sim.variance(&scenario.sensors.imu, truth.time[self.k]);
            self.strategy.set_true_variance(&q);
        }
        let raw = self
            .sim
            .imu(&scenario.sensors.imu, ideal, truth.time[self.k], truth.dt);
        if let Some(w) = self.window.as_mut() {
            w.push(&raw);
        }
        if let Some(log) = self.smoother.as_mut() {
            log.nodes
                .before_step(self.k, &self.ekf, self.strategy.process_noise());
            if log.closes.is_none() {
                // Read only where the backward pass rebuilds the closes.
                log.imu.push(raw);
            }
        }
        self.k += 1;
        self.steps_since_update += 1;
        let state = &truth.states[self.k];
        if self.failure.is_none() {
            let dvl = &scenario.sensors.dvl;
            let due = self
                .dvl_every
                .is_some_and(|every| self.k.is_multiple_of(every))
                && dvl.available(truth.time[self.k]);
            let z = due.then(|| {
                let gyro = Vector3::new(ideal[3], ideal[4], ideal[5]);
                self.sim.dvl(dvl, state, &gyro)
            });
            // A reading lost with the bottom lock: no update, its epoch recorded as NaN
            // (its noise was drawn all the same: the stream stays aligned).
            let z = match z {
                Some(_) if !self.sim.dvl_locked(dvl) => {
                    self.missed_update();
                    if let Some(log) = self.smoother.as_mut() {
                        log.update_epochs.push(None);
                    }
                    None
                }
                z => z,
            };
            let mut dvl_correction: Option<aiding::Fed> = None;
            match self.ekf.step(
                &ImuSample::from_array(&raw),
                truth.dt,
                self.strategy.as_mut(),
                z.as_ref(),
                self.steps_since_update,
            ) {
                Ok(Some(info)) => {
                    self.after_update(
                        &info,
                        state,
                        truth.time[self.k],
                        &scenario.sensors.dvl.mounting,
                    );
                    if let Some(log) = self.smoother.as_mut() {
                        log.update_epochs.push(Some(self.k));
                    }
                    dvl_correction = Some((
                        info.correction.unwrap_or_else(Vector15::zeros),
                        info.calibration_correction.unwrap_or_default(),
                    ));
                }
                Ok(None) => {}
                Err(e) => self.failure = Some(format!("t = {} s: {e}", truth.time[self.k])),
            }
            let aiding = match self.failure {
                None => self.apply_aiding(scenario, state, truth.time[self.k]),
                Some(_) => None,
            };
            let correction = match (dvl_correction, aiding) {
                (Some((a, ca)), Some((b, cb))) => {
                    Some((a + b, std::array::from_fn(|i| ca[i] + cb[i])))
                }
                (a, b) => a.or(b),
            };
            let prior = self.ekf.take_prior();
            if let (Some(log), Some(fed)) = (self.smoother.as_mut(), correction) {
                let noise = self.strategy.process_noise();
                log.nodes
                    .after_updates(self.k, &self.ekf, fed, noise, prior);
            }
            if let Some(log) = self.smoother.as_mut() {
                let recorded = self.record_every > 0 && self.k.is_multiple_of(self.record_every);
                log.push(self.k, &mut self.ekf, self.true_bias, recorded);
            }
        }
        let dv = self.ekf.nav.vel - state.vel;
        self.sum_sq += dv.norm_squared();
        self.sum_abs += dv.abs().sum();
        let dp = truth.ned_scale[self.k].error(&self.ekf.nav.lla, &state.lla);
        self.horizontal = [dp[0], dp[1]];
        let sq = dp[0] * dp[0] + dp[1] * dp[1];
        if sq > self.max_horizontal_sq {
            // a NaN never compares greater: skipped, as f64::max skips it
            self.max_horizontal_sq = sq;
            self.max_horizontal = self.horizontal;
        }
        self.record_history(truth);
    }

    /// Record a due DVL epoch whose reading is missing: NaN NIS and NEES.
    fn missed_update(&mut self) {
        self.missed_updates += 1;
        self.nis.push(f64::NAN);
        self.nees.push([f64::NAN; 5]);
        if self.ekf.calibration.is_some() {
            self.calibration_nees.push(f64::NAN);
        }
    }

    fn after_update(
        &mut self,
        info: &UpdateInfo,
        state: &NavState,
        t: f64,
        mounting: &DvlMounting,
    ) {
        self.nis_monitor.push(info.nis, t);
        if info.accepted {
            self.steps_since_update = 0;
            self.accepted_nis_sum += info.nis;
        } else {
            self.rejected_updates += 1;
        }
        // Every epoch is recorded, applied or not, so that the histories stay aligned.
        self.nis.push(info.nis);
        let e = state_error(&self.ekf, state, &self.true_bias);
        self.nees.push(block_nees(&self.ekf, state, &e));
        if let Some((_, _, nees)) = calibration_error(&self.ekf, mounting) {
            self.calibration_nees.push(nees);
        }
    }

    /// Write the last `window` raw IMU samples channel-major, oldest first, into `out`
    /// (6·window values); nothing for a run made without a window.
    pub(crate) fn write_window(&self, out: &mut [f32]) {
        if let Some(w) = self.window.as_ref() {
            w.write_channels(out);
        }
    }

    /// Steps taken so far.
    pub fn steps(&self) -> usize {
        self.k
    }

    pub fn strategy_mut(&mut self) -> &mut dyn NoiseStrategy {
        self.strategy.as_mut()
    }

    /// The run's record (the DVL calibration judged against the scenario's DVL).
    pub fn finish(mut self, scenario: &Scenario) -> RunRecord {
        self.ekf.bring_up_to_date();
        let smoothed = self.smoothed_record(scenario);
        let mounting = &scenario.sensors.dvl.mounting;
        let n = self.k.max(1) as f64;
        let failed = self.failure.is_some();
        let nan_if_failed = |x: f64| if failed { f64::NAN } else { x };
        let accepted = self.nis.len() - self.rejected_updates - self.missed_updates;
        // No applied update (none made, or every one rejected by the gate): no NIS to
        // average; 0 would look healthy.
        let mean_nis = if accepted == 0 {
            f64::NAN
        } else {
            self.accepted_nis_sum / accepted.max(1) as f64
        };
        RunRecord {
            summary: RunSummary {
                srmse: nan_if_failed((self.sum_sq / n).sqrt()),
                smae: nan_if_failed(self.sum_abs / n),
                final_horizontal_error: nan_if_failed(self.horizontal[0].hypot(self.horizontal[1])),
                max_horizontal_error: nan_if_failed(
                    self.max_horizontal[0].hypot(self.max_horizontal[1]),
                ),
                mean_nis: nan_if_failed(mean_nis),
                rejected_updates: self.rejected_updates,
                missed_updates: self.missed_updates,
                depth_updates: self.tally.depth_updates,
                fix_updates: self.tally.fix_updates,
                aiding_nis: nan_if_failed(self.tally.nis_sum),
                aiding_dof: self.tally.dof,
                diverged_at: self.nis_monitor.diverged_at,
                calibration: calibration_error(&self.ekf, mounting)
                    .filter(|_| !failed)
                    .map(|(error, sigma, _)| CalibrationSummary { error, sigma }),
                failure: self.failure,
            },
            nis: self.nis,
            nees: self.nees,
            calibration_nees: self.calibration_nees,
            history: self.history,
            smoothed,
        }
    }
}
