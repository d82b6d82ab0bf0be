//! One filter pass over recorded (or user-simulated) IMU and DVL arrays.

use super::interval::StaleSigma;
pub use super::recorded_data::RecordedData;
pub use super::recorded_epochs::Epochs;
use super::recorded_epochs::Thinning;
use super::recorded_rows::{apply_dvl_rows, apply_position_rows, keep_covariances, Cursor};
use super::smoother::thinned::{self, NodeStates, Thinned};
use super::smoother::{self, Covariances, Forward, Nodes, Smoothed};
use super::{Ekf, FilterConfig, Matrix15, NisMonitor, UpdateInfo};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::earth;
use crate::error::{check, Error, Result};
use crate::mechanization::{ImuSample, NavState};
use crate::noise::NoiseStrategy;
use nalgebra::Vector3;

/// Output of [`filter_recorded`]: the estimate after every IMU epoch (or some of them,
/// see [`Epochs`]) and the updates.
#[derive(Clone, Debug, Default)]
pub struct FilterOutput {
    /// Epoch times \[s\]: `t0` then every IMU sample time (the last one only with
    /// [`Epochs::Last`], the kept ones with [`Epochs::Step`]); the per-epoch vectors
    /// below follow them.
    pub time: Vec<f64>,
    /// With [`Epochs::Step`]: the index of each kept epoch among all (0 for `t0`, k for
    /// IMU sample k − 1); empty otherwise (every epoch, or the last).
    pub epoch: Vec<usize>,
    pub nav: Vec<NavState>,
    /// `[b_a, b_g]` estimates per epoch.
    pub bias: Vec<[f64; 6]>,
    /// 1σ of the 15 errors per epoch. With a covariance step
    /// ([`super::FilterConfig::covariance_step`]), an epoch inside a step reads σ
    /// interpolated linearly in variance between the last up-to-date epoch (after its
    /// updates) and the close that ends the step (before the updates there); steps close
    /// when due, at every DVL update and at the last epoch.
    pub sigma: Vec<[f64; 15]>,
    /// For each DVL row: the epoch index it was applied at (None if outside the run).
    pub dvl_epoch: Vec<Option<usize>>,
    pub updates: Vec<Option<UpdateInfo>>,
    /// For each DVL row: the per-IMU-step Q_d the strategy set after that update, where
    /// it sets one directly (Mehra); boxed, so that a row without one costs 8 bytes,
    /// not 1,808.
    pub adaptive_q: Vec<Option<Box<Matrix15>>>,
    /// `[k̂, roll, pitch, yaw]` of the DVL calibration states per epoch: the scale
    /// error and the DVL's mounting angles \[rad\] (empty without the states).
    pub calibration: Vec<[f64; 4]>,
    /// 1σ of `[δk, δμ]` per epoch (empty without the calibration states).
    pub calibration_sigma: Vec<[f64; 4]>,
    /// Covariance at the last epoch.
    pub final_covariance: Matrix15,
    /// For each of [`RecordedData::covariance_time`]: the epoch index it was kept at
    /// (None if outside the run) and the full covariance there, classic coordinates.
    pub covariance_epoch: Vec<Option<usize>>,
    pub covariances: Vec<Option<Matrix15>>,
    /// Divergence watch over every update's NIS.
    pub nis_monitor: NisMonitor,
    /// The RTS-smoothed solution at the kept epochs, from [`smooth_recorded_until`].
    pub smoothed: Option<Smoothed>,
    /// For each depth reading and each position fix: the epoch it was applied at
    /// (None if outside the run) and its NIS (NaN there).
    pub depth_epoch: Vec<Option<usize>>,
    pub depth_nis: Vec<f64>,
    pub fix_epoch: Vec<Option<usize>>,
    pub fix_nis: Vec<f64>,
}

impl FilterOutput {
    /// Room for `n` epochs and `m` DVL rows.
    fn with_capacity(n: usize, m: usize) -> Self {
        Self {
            time: Vec::with_capacity(n),
            epoch: Vec::new(),
            nav: Vec::with_capacity(n),
            bias: Vec::with_capacity(n),
            sigma: Vec::with_capacity(n),
            dvl_epoch: vec![None; m],
            updates: vec![None; m],
            adaptive_q: vec![None; m],
            calibration: Vec::new(),
            calibration_sigma: Vec::new(),
            final_covariance: Matrix15::zeros(),
            covariance_epoch: Vec::new(),
            covariances: Vec::new(),
            nis_monitor: NisMonitor::default(),
            smoothed: None,
            depth_epoch: Vec::new(),
            depth_nis: Vec::new(),
            fix_epoch: Vec::new(),
            fix_nis: Vec::new(),
        }
    }

    /// Append the estimate at epoch time `t` \[s\].
    fn record(&mut self, ekf: &Ekf, t: f64) {
        self.time.push(t);
        self.nav.push(ekf.nav);
        let (a, g) = (ekf.accel_bias, ekf.gyro_bias);
        self.bias.push([a[0], a[1], a[2], g[0], g[1], g[2]]);
        self.sigma.push(ekf.sigma());
        if let Some(c) = &ekf.calibration {
            self.calibration.push(c.reported());
            self.calibration_sigma.push(c.sigma());
        }
    }
}

/// Run the filter over recorded arrays from an initial state. A DVL row is applied after
/// the IMU step that reaches the epoch nearest to its time (first epoch with
/// `t ≥ t_dvl − Δt/2`); rows outside the run are skipped and reported as `None`.
/// A q schedule row takes effect from the epoch nearest to its time on (it is set
/// before the step that starts there), so it needs a strategy that takes q from outside.
/// The initial latitude obeys [`earth::check_latitude`] (named `lla0`).
pub fn filter_recorded(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
) -> Result<FilterOutput> {
    filter_recorded_until(
        data,
        initial,
        initial_bias,
        cfg,
        strategy,
        Epochs::All,
        &Cancel::default(),
    )
}

/// [`filter_recorded`] that keeps `epochs` and stops with [`Error::Cancelled`] soon
/// after `cancel` is set: it is checked every [`STEPS_PER_CHECK`] IMU samples.
pub fn filter_recorded_until(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    epochs: Epochs,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    let pass = Pass {
        data,
        initial,
        initial_bias,
        cfg,
    };
    pass.forward(strategy, epochs, None, cancel)
}

/// [`filter_recorded_until`] keeping `epochs` (all, or [`Epochs::Step`]), then the
/// RTS smoother's backward pass ([`smoother`]): the output's `smoothed` holds the
/// smoothed solution at the kept epochs (with the DVL calibration states, theirs too).
pub fn smooth_recorded_until(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    epochs: Epochs,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    let pass = Pass {
        data,
        initial,
        initial_bias,
        cfg,
    };
    match epochs {
        Epochs::All => pass.smooth_every(strategy, cancel),
        Epochs::Last => Err(Error::invalid(
            "epochs",
            "the smoother corrects the kept epochs: keep all, or some (an output step)",
        )),
        Epochs::Step(_) => pass.smooth_thinned(strategy, epochs, cancel),
    }
}

/// What the node-only backward pass reads of a forward pass `out` over `data` that
/// kept the node states `states` and the epochs `epochs` (`out.epoch`, or every one).
fn thinned_source<'a>(
    data: &'a RecordedData<'a>,
    states: &'a NodeStates,
    out: &'a FilterOutput,
    epochs: &'a [usize],
) -> Thinned<'a> {
    Thinned {
        imu: data.imu,
        imu_time: data.imu_time,
        t0: data.t0,
        states,
        epochs,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &out.calibration,
        sigma: &out.sigma,
        calibration_sigma: &out.calibration_sigma,
    }
}

/// What a smoothed forward pass keeps: the nodes and, for the node-only backward pass,
/// the solution at each of them.
type Keep<'a> = Option<(&'a mut Nodes, Option<&'a mut NodeStates>)>;

/// What one pass starts from: the recording, the initial state and bias estimates
/// (`[b_a, b_g]`), and the filter's configuration.
struct Pass<'a> {
    data: &'a RecordedData<'a>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &'a FilterConfig,
}

impl<'a> Pass<'a> {
    /// A pass from the moving test state with zero bias estimates.
    #[cfg(test)]
    fn of(data: &'a RecordedData<'a>, cfg: &'a FilterConfig) -> Self {
        Pass {
            data,
            initial: super::tests::moving_state(),
            initial_bias: [0.0; 6],
            cfg,
        }
    }

    /// Every epoch kept, then the backward pass over them.
    fn smooth_every(
        &self,
        strategy: &mut dyn NoiseStrategy,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        let mut nodes = Nodes::default();
        let keep = Some((&mut nodes, None));
        let mut out = self.forward(strategy, Epochs::All, keep, cancel)?;
        let data = self.data;
        let forward = Forward {
            imu: data.imu,
            imu_time: data.imu_time,
            t0: data.t0,
            nav: &out.nav,
            bias: &out.bias,
            calibration: &out.calibration,
            sigma: &out.sigma,
            calibration_sigma: &out.calibration_sigma,
            dt: None,
        };
        let smoothed = smoother::smooth(&forward, self.cfg, &nodes.0, Covariances::Every, cancel)?;
        out.smoothed = Some(smoothed);
        Ok(out)
    }

    /// With an [`Epochs::Step`]: the forward pass keeps its solution at the nodes and
    /// the kept epochs only ([`smoother::thinned`]).
    fn smooth_thinned(
        &self,
        strategy: &mut dyn NoiseStrategy,
        epochs: Epochs,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        let mut nodes = Nodes::default();
        let mut states = NodeStates::default();
        let keep = Some((&mut nodes, Some(&mut states)));
        let mut out = self.forward(strategy, epochs, keep, cancel)?;
        let forward = thinned_source(self.data, &states, &out, &out.epoch);
        let smoothed = thinned::smooth(&forward, self.cfg, &nodes.0, cancel)?;
        out.smoothed = Some(smoothed);
        Ok(out)
    }

    /// The forward pass keeping `epochs`; with `keep`, what the smoother needs (the
    /// nodes, and with `states` the solution at each).
    fn forward(
        &self,
        strategy: &mut dyn NoiseStrategy,
        epochs: Epochs,
        mut keep: Keep<'_>,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        epochs.validate()?;
        let data = self.data;
        let mut ekf = self.start(strategy)?;
        let every = epochs == Epochs::All;
        let mut thinning = Thinning::of(epochs, data.t0, data.imu_time[0] - data.t0);
        let n = data.imu.len();
        let mut out = output_for(data, epochs, ekf.calibration.is_some());
        let mut stale = StaleSigma::default();
        let some = every || thinning.is_some();
        if some {
            out.record(&ekf, data.t0);
            if thinning.is_some() {
                out.epoch.push(0);
            }
            stale.after_epoch(&mut ekf, &mut out, data.t0, true);
        }
        let mut at = Cursor::default();
        let first_dt = data.imu_time[0] - data.t0;
        keep_covariances(data, &ekf, &mut out, &mut at, 0, data.t0, first_dt);
        let mut t_prev = data.t0;
        for (k, (sample, &t)) in data.imu.iter().zip(data.imu_time).enumerate() {
            if k % STEPS_PER_CHECK == 0 {
                cancel.check()?;
            }
            let dt = t - t_prev;
            // DVL rows that fell before the first epoch cannot be used.
            while at.next_dvl < data.dvl.len() && data.dvl_time[at.next_dvl] < data.t0 - 0.5 * dt {
                at.next_dvl += 1;
            }
            set_scheduled_q(data, strategy, &mut at, t_prev + 0.5 * dt)?;
            if let Some((nodes, states)) = keep.as_mut() {
                nodes.before_step(k, &ekf, strategy.process_noise());
                sync(states, nodes, &ekf);
            }
            ekf.propagate(&ImuSample::from_array(sample), dt, strategy.process_noise())
                .map_err(|e| match e {
                    Error::Numerical(m) => Error::Numerical(format!("{m} (t = {t} s)")),
                    other => other,
                })?;
            at.steps_since_update += 1;
            if k + 1 == n {
                ekf.bring_up_to_date(); // the end of the pass
            }
            let dvl = apply_dvl_rows(data, &mut ekf, strategy, &mut out, &mut at, k + 1, t, dt)?;
            let aiding = apply_position_rows(data, &mut ekf, &mut out, &mut at, k + 1, t, dt)?;
            let fed = match (dvl, aiding) {
                (None, None) => None,
                (a, b) => Some(a.unwrap_or_default().plus(&b.unwrap_or_default())),
            };
            if let (Some((nodes, states)), Some(fed)) = (keep.as_mut(), fed) {
                let noise = strategy.process_noise();
                nodes.after_updates(k + 1, &ekf, (fed.nav, fed.calibration), noise, None);
                sync(states, nodes, &ekf);
            }
            let next_dt = data.imu_time.get(k + 1).map_or(dt, |&next| next - t);
            keep_covariances(data, &ekf, &mut out, &mut at, k + 1, t, next_dt);
            if some {
                let recorded = match thinning.as_mut() {
                    None => true,
                    Some(thin) => thin.keeps(t, next_dt) || k + 1 == n,
                };
                if recorded {
                    out.record(&ekf, t);
                    if thinning.is_some() {
                        out.epoch.push(k + 1);
                    }
                }
                stale.after_epoch(&mut ekf, &mut out, t, recorded);
            }
            t_prev = t;
        }
        if !some {
            out.record(&ekf, t_prev);
        }
        if let Some((nodes, mut states)) = keep {
            nodes.finish(n, &ekf);
            sync(&mut states, nodes, &ekf);
        }
        out.final_covariance = ekf.covariance();
        out.close_rows(data);
        Ok(out)
    }

    /// The filter at the start of the pass, once the data, the initial state and the
    /// strategy have been checked for it.
    fn start(&self, strategy: &dyn NoiseStrategy) -> Result<Ekf> {
        let (data, initial, bias) = (self.data, &self.initial, &self.initial_bias);
        earth::check_latitude("lla0", initial.lla[0])?;
        data.validate()?;
        if !data.q_time.is_empty() && !strategy.takes_outside_q() {
            return Err(Error::invalid(
                "strategy",
                "a q schedule needs an external strategy (Strategy.external)",
            ));
        }
        if strategy.wants_true_variance() {
            return Err(Error::invalid(
                "strategy",
                "oracle needs the simulated IMU's true variance, which recorded data does not have",
            ));
        }
        check::finite("initial state", initial.lla.as_slice())?;
        check::finite("initial state", initial.vel.as_slice())?;
        check::finite("initial bias", bias)?;
        let mut ekf = Ekf::new(
            self.cfg,
            *initial,
            Vector3::new(bias[0], bias[1], bias[2]),
            Vector3::new(bias[3], bias[4], bias[5]),
        )?;
        if let Some(q) = strategy.sensitivity_q() {
            ekf.track_sensitivity(q);
        }
        Ok(ekf)
    }
}

/// The solution at each node, where the node-only backward pass wants it.
fn sync(states: &mut Option<&mut NodeStates>, nodes: &Nodes, ekf: &Ekf) {
    if let Some(states) = states {
        states.sync(nodes, ekf);
    }
}

/// An empty output with room for the epochs `epochs` keeps of `data` and its DVL rows.
fn output_for(data: &RecordedData<'_>, epochs: Epochs, calibrated: bool) -> FilterOutput {
    let n = data.imu.len();
    let kept = match epochs {
        Epochs::All => n + 1,
        Epochs::Last => 1,
        Epochs::Step(step) => {
            let span = data.imu_time[n - 1] - data.t0;
            ((span / step) as usize).saturating_add(2).min(n + 1)
        }
    };
    let mut out = FilterOutput::with_capacity(kept, data.dvl.len());
    if calibrated {
        out.calibration.reserve_exact(kept);
        out.calibration_sigma.reserve_exact(kept);
    }
    if matches!(epochs, Epochs::Step(_)) {
        out.epoch.reserve_exact(kept);
    }
    out
}

/// Set the last q schedule row stamped at or before `until` \[s\] (the epoch's start
/// plus half its step) not yet set: a row takes effect from the epoch nearest to it.
fn set_scheduled_q(
    data: &RecordedData<'_>,
    strategy: &mut dyn NoiseStrategy,
    at: &mut Cursor,
    until: f64,
) -> Result<()> {
    let mut q_in_force: Option<[f64; 6]> = None;
    while at.next_q < data.q_time.len() && data.q_time[at.next_q] <= until {
        q_in_force = Some(data.q_values[at.next_q]);
        at.next_q += 1;
    }
    if let Some(q) = q_in_force {
        strategy.set_imu_variance(&q)?;
    }
    Ok(())
}

impl FilterOutput {
    /// At the end of a pass: the rows of the asked-for covariances, depth readings and
    /// fixes beyond the last epoch's half step are outside the run.
    fn close_rows(&mut self, data: &RecordedData<'_>) {
        self.covariance_epoch
            .resize(data.covariance_time.len(), None);
        self.covariances.resize(data.covariance_time.len(), None);
        self.depth_epoch.resize(data.depth.len(), None);
        self.depth_nis.resize(data.depth.len(), f64::NAN);
        self.fix_epoch.resize(data.fix.len(), None);
        self.fix_nis.resize(data.fix.len(), f64::NAN);
    }
}

#[cfg(test)]
#[path = "recorded_tests.rs"]
mod tests;

#[cfg(test)]
#[path = "recorded_smoother_tests.rs"]
mod smoother_tests;

#[cfg(test)]
#[path = "recorded_thinned_tests.rs"]
mod thinned_tests;
