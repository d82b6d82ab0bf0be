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
    /// Epoch times [s]: `t0` then every IMU sample time (the last one only with
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
    /// ([`super::FilterConfig::covariance_step`]), an epoch inside a step repeats the
    /// σ of the last closed one; steps close when due, at every DVL update and at the
    /// last epoch.
    pub sigma: Vec<[f64; 15]>,
    /// For each DVL row: the epoch index it was applied at (None if outside the run).
    pub dvl_epoch: Vec<Option<usize>>,
    pub updates: Vec<Option<UpdateInfo>>,
    /// For each DVL row: the per-IMU-step Q_d the strategy set after that update, where
    /// it sets one directly (Mehra); boxed, so that a row without one costs 8 bytes,
    /// not 1,808.
    pub adaptive_q: Vec<Option<Box<Matrix15>>>,
    /// `[k̂, roll, pitch, yaw]` of the DVL calibration states per epoch: the scale
    /// error and the DVL's mounting angles [rad] (empty without the states).
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

    /// Append the estimate at epoch time `t` [s].
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
    forward_pass(
        data,
        initial,
        initial_bias,
        cfg,
        strategy,
        epochs,
        None,
        cancel,
    )
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
    match epochs {
        Epochs::All => {}
        Epochs::Last => {
            return Err(Error::invalid(
                "epochs",
                "the smoother corrects the kept epochs: keep all, or some (an output step)",
            ))
        }
        Epochs::Step(_) => {
            return smooth_thinned(data, initial, initial_bias, cfg, strategy, epochs, cancel)
        }
    }
    let mut nodes = Nodes::default();
    let mut out = forward_pass(
        data,
        initial,
        initial_bias,
        cfg,
        strategy,
        Epochs::All,
        Some(&mut nodes),
        cancel,
    )?;
    let forward = Forward {
        imu: data.imu,
        imu_time: data.imu_time,
        t0: data.t0,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &out.calibration,
        dt: None,
    };
    let smoothed = smoother::smooth(&forward, cfg, &nodes.0, Covariances::Every, cancel)?;
    out.smoothed = Some(smoothed);
    Ok(out)
}

/// [`smooth_recorded_until`] with an [`Epochs::Step`]: the forward pass keeps its
/// solution at the nodes and the kept epochs only ([`smoother::thinned`]).
fn smooth_thinned(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    epochs: Epochs,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    let mut nodes = Nodes::default();
    let mut states = NodeStates::default();
    let keep = Some((&mut nodes, Some(&mut states)));
    let mut out = forward_pass_keeping(
        data,
        initial,
        initial_bias,
        cfg,
        strategy,
        epochs,
        keep,
        cancel,
    )?;
    let forward = Thinned {
        imu: data.imu,
        imu_time: data.imu_time,
        t0: data.t0,
        states: &states,
        epochs: &out.epoch,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &out.calibration,
    };
    let smoothed = thinned::smooth(&forward, cfg, &nodes.0, cancel)?;
    out.smoothed = Some(smoothed);
    Ok(out)
}

/// The forward pass; with `nodes`, keeping what the smoother needs.
#[allow(clippy::too_many_arguments)]
fn forward_pass(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    epochs: Epochs,
    nodes: Option<&mut Nodes>,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    let keep = nodes.map(|n| (n, None));
    forward_pass_keeping(
        data,
        initial,
        initial_bias,
        cfg,
        strategy,
        epochs,
        keep,
        cancel,
    )
}

/// What a smoothed forward pass keeps: the nodes and, for the node-only backward pass,
/// the solution at each of them.
type Keep<'a> = Option<(&'a mut Nodes, Option<&'a mut NodeStates>)>;

/// [`forward_pass`] keeping the nodes, and with `states` the solution at each.
#[allow(clippy::too_many_arguments)]
fn forward_pass_keeping(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    epochs: Epochs,
    mut keep: Keep<'_>,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    epochs.validate()?;
    let mut ekf = start(data, initial, initial_bias, cfg, strategy)?;
    let every = epochs == Epochs::All;
    let mut thinning = Thinning::of(epochs, data.t0, data.imu_time[0] - data.t0);
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
    if ekf.calibration.is_some() {
        out.calibration.reserve_exact(kept);
        out.calibration_sigma.reserve_exact(kept);
    }
    let mut stale = StaleSigma::default();
    let some = every || thinning.is_some();
    if some {
        out.record(&ekf, data.t0);
        if thinning.is_some() {
            out.epoch.reserve_exact(kept);
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
        let mut q_in_force: Option<[f64; 6]> = None;
        while at.next_q < data.q_time.len() && data.q_time[at.next_q] <= t_prev + 0.5 * dt {
            q_in_force = Some(data.q_values[at.next_q]);
            at.next_q += 1;
        }
        if let Some(q) = q_in_force {
            strategy.set_imu_variance(&q)?;
        }
        if let Some((nodes, states)) = keep.as_mut() {
            nodes.before_step(k, &ekf, strategy.process_noise());
            if let Some(states) = states {
                states.sync(nodes, &ekf);
            }
        }
        ekf.propagate(&ImuSample::from_array(sample), dt, strategy.process_noise())
            .map_err(|e| match e {
                Error::Numerical(m) => Error::Numerical(format!("{m} (t = {t} s)")),
                other => other,
            })?;
        at.steps_since_update += 1;
        if k + 1 == data.imu.len() {
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
            if let Some(states) = states {
                states.sync(nodes, &ekf);
            }
        }
        let next_dt = data.imu_time.get(k + 1).map_or(dt, |&next| next - t);
        keep_covariances(data, &ekf, &mut out, &mut at, k + 1, t, next_dt);
        if some {
            let recorded = match thinning.as_mut() {
                None => true,
                Some(thin) => {
                    let nearest = thin.keeps(t, next_dt);
                    nearest || k + 1 == n
                }
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
    if let Some((nodes, states)) = keep {
        nodes.finish(data.imu.len(), &ekf);
        if let Some(states) = states {
            states.sync(nodes, &ekf);
        }
    }
    out.final_covariance = ekf.covariance();
    // Times beyond the last epoch's half step are outside the run.
    out.covariance_epoch
        .resize(data.covariance_time.len(), None);
    out.covariances.resize(data.covariance_time.len(), None);
    out.depth_epoch.resize(data.depth.len(), None);
    out.depth_nis.resize(data.depth.len(), f64::NAN);
    out.fix_epoch.resize(data.fix.len(), None);
    out.fix_nis.resize(data.fix.len(), f64::NAN);
    Ok(out)
}

/// The filter at the start of a pass, once the data, the initial state and the
/// strategy have been checked for it.
fn start(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &dyn NoiseStrategy,
) -> Result<Ekf> {
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
    check::finite("initial bias", &initial_bias)?;
    let mut ekf = Ekf::new(
        cfg,
        initial,
        Vector3::new(initial_bias[0], initial_bias[1], initial_bias[2]),
        Vector3::new(initial_bias[3], initial_bias[4], initial_bias[5]),
    )?;
    if let Some(q) = strategy.sensitivity_q() {
        ekf.track_sensitivity(q);
    }
    Ok(ekf)
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
