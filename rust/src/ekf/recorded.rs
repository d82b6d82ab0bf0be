//! One filter pass over recorded (or user-simulated) IMU and DVL arrays.

use super::smoother::{self, Covariances, Forward, Nodes, Smoothed};
use super::{Ekf, FilterConfig, Matrix15, NisMonitor, UpdateInfo, Vector15};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::earth;
use crate::error::{check, Error, Result};
use crate::mechanization::{ImuSample, NavState};
use crate::noise::NoiseStrategy;
use nalgebra::Vector3;

/// Output of [`filter_recorded`]: the estimate after every IMU epoch (or the last one
/// only, [`Epochs::Last`]) and the updates.
#[derive(Clone, Debug, Default)]
pub struct FilterOutput {
    /// Epoch times [s]: `t0` then every IMU sample time (the last one only with
    /// [`Epochs::Last`]); the per-epoch vectors below follow them.
    pub time: Vec<f64>,
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
    /// it sets one directly (Mehra).
    pub adaptive_q: Vec<Option<Matrix15>>,
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
    /// The RTS-smoothed solution at every epoch, from [`smooth_recorded_until`].
    pub smoothed: Option<Smoothed>,
    /// For each depth reading and each position fix: the epoch it was applied at
    /// (None if outside the run) and its NIS (NaN there).
    pub depth_epoch: Vec<Option<usize>>,
    pub depth_nis: Vec<f64>,
    pub fix_epoch: Vec<Option<usize>>,
    pub fix_nis: Vec<f64>,
}

/// Inputs of one filter pass over recorded (or user-simulated) sensor arrays.
#[derive(Clone, Copy, Debug, Default)]
pub struct RecordedData<'a> {
    /// IMU samples; row k covers `(imu_time[k-1], imu_time[k]]`, `imu_time[-1] = t0`.
    pub imu: &'a [[f64; 6]],
    /// End time of every IMU sample [s], strictly increasing, after `t0`.
    pub imu_time: &'a [f64],
    /// DVL rows (body or NED velocity per the aiding) [m/s].
    pub dvl: &'a [[f64; 3]],
    /// DVL times [s], strictly increasing.
    pub dvl_time: &'a [f64],
    /// Time of the initial state [s].
    pub t0: f64,
    /// Start times [s] of a per-sample IMU variance schedule for an external strategy
    /// (the ProNet loop on recorded data); empty for none. Strictly increasing.
    pub q_time: &'a [f64],
    /// The schedule's IMU variances, one row per `q_time` [(m/s²)², (rad/s)²].
    pub q_values: &'a [[f64; 6]],
    /// Times [s] at which to keep the full covariance, strictly increasing (empty for
    /// none): each is kept at the epoch nearest to it, after that epoch's update, so a
    /// pass stores 15 × 15 numbers (1,800 bytes) per time asked for, never per epoch.
    pub covariance_time: &'a [f64],
    /// Depth readings [m, positive down] at `depth_time` [s] (strictly increasing),
    /// each of 1σ `depth_sigma` [m] (see [`super::position`]); empty for none.
    pub depth: &'a [f64],
    pub depth_time: &'a [f64],
    pub depth_sigma: f64,
    /// Position fixes `[φ (rad), λ (rad), h (m, up)]` (a NaN height: horizontal only)
    /// at `fix_time` [s] (strictly increasing), each with its 1σ `[north, east, down]`
    /// [m] in `fix_sigma`; empty for none.
    pub fix: &'a [[f64; 3]],
    pub fix_time: &'a [f64],
    pub fix_sigma: &'a [[f64; 3]],
}

impl RecordedData<'_> {
    pub fn validate(&self) -> Result<()> {
        if self.imu.is_empty() {
            return Err(Error::invalid("imu", "needs at least one sample"));
        }
        if self.imu.len() != self.imu_time.len() {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "has {} rows but imu has {}",
                    self.imu_time.len(),
                    self.imu.len()
                ),
            ));
        }
        if self.dvl.len() != self.dvl_time.len() {
            return Err(Error::invalid(
                "dvl_time",
                format!(
                    "has {} rows but dvl has {}",
                    self.dvl_time.len(),
                    self.dvl.len()
                ),
            ));
        }
        for (i, row) in self.imu.iter().enumerate() {
            check::finite("imu", row)
                .map_err(|_| Error::invalid("imu", format!("row {i} is not finite: {row:?}")))?;
        }
        for (i, row) in self.dvl.iter().enumerate() {
            check::finite("dvl", row)
                .map_err(|_| Error::invalid("dvl", format!("row {i} is not finite: {row:?}")))?;
        }
        check::finite("t0", &[self.t0])?;
        check::increasing("imu_time", self.imu_time)?;
        check::increasing("dvl_time", self.dvl_time)?;
        if self.q_time.len() != self.q_values.len() {
            return Err(Error::invalid(
                "q_time",
                format!(
                    "has {} rows but q has {}",
                    self.q_time.len(),
                    self.q_values.len()
                ),
            ));
        }
        check::increasing("q_time", self.q_time)?;
        check::increasing("covariance_time", self.covariance_time)?;
        self.validate_aiding()?;
        for (i, row) in self.q_values.iter().enumerate() {
            check::non_negative("q", row).map_err(|_| {
                Error::invalid(
                    "q",
                    format!("row {i} must be finite and >= 0 (variances), got {row:?}"),
                )
            })?;
        }
        if self.imu_time[0] <= self.t0 {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "the first sample time {} must be after t0 = {} (a positive time step)",
                    self.imu_time[0], self.t0
                ),
            ));
        }
        Ok(())
    }
}

impl RecordedData<'_> {
    /// The depth readings and position fixes: lengths, times, values and σ.
    fn validate_aiding(&self) -> Result<()> {
        let same = |name: &str, n: usize, time: &str, m: usize| {
            if n == m {
                return Ok(());
            }
            Err(Error::invalid(
                time,
                format!("has {m} rows but {name} has {n}"),
            ))
        };
        same(
            "depth",
            self.depth.len(),
            "depth_time",
            self.depth_time.len(),
        )?;
        same("fix", self.fix.len(), "fix_time", self.fix_time.len())?;
        same("fix", self.fix.len(), "fix_sigma", self.fix_sigma.len())?;
        check::increasing("depth_time", self.depth_time)?;
        check::increasing("fix_time", self.fix_time)?;
        check::finite("depth", self.depth)?;
        let sigma_ok = self.depth_sigma > 0.0 && self.depth_sigma.is_finite();
        if !self.depth.is_empty() && !sigma_ok {
            return Err(Error::invalid(
                "depth_sigma",
                format!(
                    "must be a finite number of metres > 0, got {}",
                    self.depth_sigma
                ),
            ));
        }
        for (i, (fix, sigma)) in self.fix.iter().zip(self.fix_sigma).enumerate() {
            let vertical = !fix[2].is_nan();
            if !fix[0].is_finite() || !fix[1].is_finite() || fix[2].is_infinite() {
                return Err(Error::invalid(
                    "fix",
                    format!(
                        "row {i} must hold a finite latitude and longitude [rad] and a finite \
                         or NaN height [m], got {fix:?}"
                    ),
                ));
            }
            earth::check_latitude("fix", fix[0])?;
            let wanted = if vertical { 3 } else { 2 };
            if !sigma[..wanted].iter().all(|s| *s > 0.0 && s.is_finite()) {
                let axes = if vertical {
                    "north, east, down"
                } else {
                    "north, east"
                };
                return Err(Error::invalid(
                    "fix_sigma",
                    format!("row {i} must hold {wanted} finite 1σ > 0 [m] ({axes}), got {sigma:?}"),
                ));
            }
        }
        Ok(())
    }
}

impl FilterOutput {
    /// Room for `n` epochs and `m` DVL rows.
    fn with_capacity(n: usize, m: usize) -> Self {
        Self {
            time: Vec::with_capacity(n),
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

/// Where a pass stands: the next DVL and q rows, and the IMU steps since the last
/// accepted update.
#[derive(Default)]
struct Cursor {
    next_dvl: usize,
    next_q: usize,
    next_covariance: usize,
    next_depth: usize,
    next_fix: usize,
    steps_since_update: usize,
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

/// Which epochs a pass keeps in its [`FilterOutput`] (the updates are always kept).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Epochs {
    /// The initial state and the estimate after every IMU sample.
    #[default]
    All,
    /// The estimate after the last IMU sample only: for passes whose updates alone are
    /// read, such as matching R to the innovations, which then neither compute nor
    /// store the estimate (~300 bytes here, ~70 more in the binding's arrays) at every
    /// IMU sample. `dvl_epoch` still counts every epoch.
    Last,
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

/// [`filter_recorded_until`] keeping every epoch, then the RTS smoother's backward pass
/// ([`smoother`]): the output's `smoothed` holds the smoothed solution at every epoch.
/// The DVL calibration states are not smoothed yet (refused, naming `config`).
pub fn smooth_recorded_until(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    smoother::check_config(cfg, "config")?;
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
        dt: None,
    };
    let smoothed = smoother::smooth(&forward, cfg, &nodes.0, Covariances::Every, cancel)?;
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
    mut nodes: Option<&mut Nodes>,
    cancel: &Cancel,
) -> Result<FilterOutput> {
    let mut ekf = start(data, initial, initial_bias, cfg, strategy)?;
    let every = epochs == Epochs::All;
    let kept = if every { data.imu.len() + 1 } else { 1 };
    let mut out = FilterOutput::with_capacity(kept, data.dvl.len());
    if ekf.calibration.is_some() {
        out.calibration.reserve_exact(kept);
        out.calibration_sigma.reserve_exact(kept);
    }
    if every {
        out.record(&ekf, data.t0);
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
        if let Some(nodes) = nodes.as_deref_mut() {
            nodes.before_step(k, &ekf, strategy.process_noise());
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
        let correction = match (dvl, aiding) {
            (None, None) => None,
            (a, b) => Some(a.unwrap_or_else(Vector15::zeros) + b.unwrap_or_else(Vector15::zeros)),
        };
        if let (Some(nodes), Some(correction)) = (nodes.as_deref_mut(), correction) {
            nodes.after_updates(k + 1, &ekf, correction, strategy.process_noise());
        }
        let next_dt = data.imu_time.get(k + 1).map_or(dt, |&next| next - t);
        keep_covariances(data, &ekf, &mut out, &mut at, k + 1, t, next_dt);
        if every {
            out.record(&ekf, t);
        }
        t_prev = t;
    }
    if !every {
        out.record(&ekf, t_prev);
    }
    if let Some(nodes) = nodes {
        nodes.finish(data.imu.len(), &ekf);
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

/// Apply every depth reading, then every position fix, whose nearest epoch is `epoch`
/// (time `t` [s], step `dt` [s]), as DVL rows are placed; rows before the run's first
/// half step are outside it. The sum of the error estimates fed back, or None if no row
/// was there.
#[allow(clippy::too_many_arguments)]
fn apply_position_rows(
    data: &RecordedData<'_>,
    ekf: &mut Ekf,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    dt: f64,
) -> Result<Option<Vector15>> {
    let first = data.t0 - 0.5 * (data.imu_time[0] - data.t0);
    let due = |time: f64| time <= t + 0.5 * dt;
    let mut correction: Option<Vector15> = None;
    let numerical = |what: &str, row: usize, e: Error| match e {
        Error::Numerical(m) => Error::Numerical(format!("{m} ({what} row {row}, t = {t} s)")),
        other => other,
    };
    while at.next_depth < data.depth.len() && due(data.depth_time[at.next_depth]) {
        let row = at.next_depth;
        at.next_depth += 1;
        out.depth_epoch.push(None);
        out.depth_nis.push(f64::NAN);
        if data.depth_time[row] < first {
            continue;
        }
        let done = ekf
            .update_depth(data.depth[row], data.depth_sigma)
            .map_err(|e| numerical("depth", row, e))?;
        (out.depth_epoch[row], out.depth_nis[row]) = (Some(epoch), done.nis);
        *correction.get_or_insert_with(Vector15::zeros) += done.correction;
    }
    while at.next_fix < data.fix.len() && due(data.fix_time[at.next_fix]) {
        let row = at.next_fix;
        at.next_fix += 1;
        out.fix_epoch.push(None);
        out.fix_nis.push(f64::NAN);
        if data.fix_time[row] < first {
            continue;
        }
        let done = ekf
            .update_fix(&data.fix[row], &data.fix_sigma[row])
            .map_err(|e| numerical("fix", row, e))?;
        (out.fix_epoch[row], out.fix_nis[row]) = (Some(epoch), done.nis);
        *correction.get_or_insert_with(Vector15::zeros) += done.correction;
    }
    Ok(correction)
}

/// Keep the covariance (classic coordinates) for every asked-for time whose nearest
/// epoch is `epoch` (time `t` [s]; `next_dt` [s] the step after it): the times before
/// or at `t + next_dt/2` not yet taken. Times before the run's first half step are outside
/// it (None), as DVL rows are.
fn keep_covariances(
    data: &RecordedData<'_>,
    ekf: &Ekf,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    next_dt: f64,
) {
    let times = data.covariance_time;
    let first_dt = data.imu_time[0] - data.t0;
    let mut kept: Option<Matrix15> = None;
    while at.next_covariance < times.len() && times[at.next_covariance] <= t + 0.5 * next_dt {
        if times[at.next_covariance] < data.t0 - 0.5 * first_dt {
            out.covariance_epoch.push(None);
            out.covariances.push(None);
        } else {
            let p = *kept.get_or_insert_with(|| ekf.covariance_up_to_date());
            out.covariance_epoch.push(Some(epoch));
            out.covariances.push(Some(p));
        }
        at.next_covariance += 1;
    }
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

/// Apply every DVL row whose nearest epoch is `epoch` (time `t` [s], step `dt` [s]);
/// the sum of the error estimates fed back, or None if no row was there.
#[allow(clippy::too_many_arguments)]
fn apply_dvl_rows(
    data: &RecordedData<'_>,
    ekf: &mut Ekf,
    strategy: &mut dyn NoiseStrategy,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    dt: f64,
) -> Result<Option<Vector15>> {
    let mut correction: Option<Vector15> = None;
    while at.next_dvl < data.dvl.len() && data.dvl_time[at.next_dvl] <= t + 0.5 * dt {
        let row = at.next_dvl;
        let z = Vector3::from_column_slice(&data.dvl[row]);
        let info = ekf.update(&z).map_err(|e| match e {
            Error::Numerical(m) => Error::Numerical(format!("{m} (DVL row {row}, t = {t} s)")),
            other => other,
        })?;
        out.nis_monitor.push(info.nis, t);
        let sum = correction.get_or_insert_with(Vector15::zeros);
        if let Some(dx) = &info.correction {
            *sum += dx;
        }
        if info.accepted {
            strategy.after_update(&info, at.steps_since_update);
            at.steps_since_update = 0;
        }
        // Mehra's Q̂ is built from the reported (classic) gain: classic already.
        out.adaptive_q[row] = strategy.discrete_q().copied();
        out.dvl_epoch[row] = Some(epoch);
        out.updates[row] = Some(info);
        at.next_dvl += 1;
    }
    Ok(correction)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::tests::moving_state;
    use crate::ekf::Formulation;
    use crate::noise::StrategySpec;
    #[test]
    fn recorded_data_is_validated() {
        let imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 3];
        let data = |imu_time: &'static [f64], t0: f64| -> Result<()> {
            RecordedData {
                imu: &imu[..imu_time.len().min(3)],
                imu_time,
                dvl: &[],
                dvl_time: &[],
                t0,
                q_time: &[],
                q_values: &[],
                covariance_time: &[],
                ..RecordedData::default()
            }
            .validate()
        };
        assert!(data(&[0.01, 0.02, 0.03], 0.0).is_ok());
        let err = data(&[0.01, 0.01, 0.03], 0.0).unwrap_err();
        assert!(
            matches!(&err, Error::InvalidArgument { arg, .. } if arg == "imu_time"),
            "{err}"
        );
        let err = data(&[0.01, 0.02, 0.03], 0.01).unwrap_err();
        assert!(err.to_string().contains("positive time step"), "{err}");
        let imu4 = [[0.0; 6]; 4];
        let err = RecordedData {
            imu: &imu4,
            imu_time: &[0.1, 0.2],
            dvl: &[],
            dvl_time: &[],
            t0: 0.0,
            q_time: &[],
            q_values: &[],
            covariance_time: &[],
            ..RecordedData::default()
        }
        .validate()
        .unwrap_err();
        assert!(err.to_string().starts_with("imu_time"), "{err}");
    }

    /// IMU rows alone from `t0` = 0: no DVL, no q schedule.
    fn imu_only<'a>(imu: &'a [[f64; 6]], imu_time: &'a [f64]) -> RecordedData<'a> {
        RecordedData {
            imu,
            imu_time,
            dvl: &[],
            dvl_time: &[],
            t0: 0.0,
            q_time: &[],
            q_values: &[],
            covariance_time: &[],
            ..RecordedData::default()
        }
    }

    #[test]
    fn a_set_cancel_flag_stops_a_pass() {
        let imu = vec![[0.01, 0.0, -9.79, 0.0, 1e-4, 0.0]; 10];
        let imu_time: Vec<f64> = (1..=10).map(|k| k as f64 * 0.01).collect();
        let data = imu_only(&imu, &imu_time);
        let cfg = FilterConfig::default();
        let pass = |cancel: &Cancel| {
            let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(cfg.bias_psd());
            let bias = [0.0; 6];
            filter_recorded_until(
                &data,
                moving_state(),
                bias,
                &cfg,
                strategy.as_mut(),
                Epochs::All,
                cancel,
            )
        };
        assert_eq!(pass(&Cancel::default()).unwrap().time.len(), 11);
        let cancel = Cancel::default();
        cancel.cancel();
        assert_eq!(pass(&cancel).unwrap_err(), Error::Cancelled);
    }

    /// A pass that keeps only the last epoch makes the same updates and ends in the same
    /// estimate as one that keeps every epoch, with and without the calibration states.
    #[test]
    fn keeping_the_last_epoch_changes_no_update_and_no_final_estimate() {
        let n = 250;
        let imu = vec![[0.02, -0.01, -9.79, 1e-4, 0.0, 2e-4]; n];
        let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
        let dvl = vec![[0.5, 0.01, 0.0]; 4];
        let dvl_time = [0.5, 1.0, 1.5, 2.0];
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl: &dvl,
            dvl_time: &dvl_time,
            t0: 0.0,
            q_time: &[],
            q_values: &[],
            covariance_time: &[],
            ..RecordedData::default()
        };
        for calibration in [
            None,
            Some(super::super::calibration::CalibrationConfig::default()),
        ] {
            let cfg = FilterConfig {
                dvl_calibration: calibration,
                ..FilterConfig::default()
            };
            let pass = |epochs| {
                let spec = StrategySpec::Constant { q: [1e-4; 6] };
                let mut strategy = spec.build(cfg.bias_psd());
                filter_recorded_until(
                    &data,
                    moving_state(),
                    [0.0; 6],
                    &cfg,
                    strategy.as_mut(),
                    epochs,
                    &Cancel::default(),
                )
                .unwrap()
            };
            let (all, last) = (pass(Epochs::All), pass(Epochs::Last));
            assert_eq!(all.time.len(), n + 1);
            assert_eq!(last.time, [all.time[n]]);
            assert_eq!(last.nav, [all.nav[n]]);
            assert_eq!(last.bias, [all.bias[n]]);
            assert_eq!(last.sigma, [all.sigma[n]]);
            let k = usize::from(calibration.is_some());
            assert_eq!(last.calibration.len(), k);
            assert_eq!(
                last.calibration,
                all.calibration[all.calibration.len() - k..]
            );
            assert_eq!(last.calibration_sigma.len(), k);
            assert_eq!(last.final_covariance, all.final_covariance);
            assert_eq!(last.dvl_epoch, all.dvl_epoch);
            for (a, b) in all.updates.iter().zip(&last.updates) {
                let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
                assert_eq!((a.innovation, a.s, a.nis), (b.innovation, b.s, b.nis));
            }
        }
    }

    /// The covariance is kept at the epoch nearest each asked-for time, after that
    /// epoch's update (its diagonal is the σ recorded there), the pass otherwise
    /// unchanged; times outside the run are None, and a time that is not increasing
    /// is refused by name.
    #[test]
    fn covariances_are_kept_at_the_epochs_nearest_the_times_asked_for() {
        let n = 250;
        let imu = vec![[0.02, -0.01, -9.79, 1e-4, 0.0, 2e-4]; n];
        let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
        let dvl = vec![[0.5, 0.01, 0.0]; 4];
        let dvl_time = [0.5, 1.0, 1.5, 2.0];
        let times = [-0.1, -0.004, 0.004, 0.996, 1.0, 1.2449, 2.504, 2.6];
        let cfg = FilterConfig::default();
        let pass = |covariance_time: &[f64]| {
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl: &dvl,
                dvl_time: &dvl_time,
                covariance_time,
                ..RecordedData::default()
            };
            let spec = StrategySpec::Constant { q: [1e-4; 6] };
            filter_recorded(
                &data,
                moving_state(),
                [0.0; 6],
                &cfg,
                spec.build(cfg.bias_psd()).as_mut(),
            )
        };
        let plain = pass(&[]).unwrap();
        let kept = pass(&times).unwrap();
        assert!(plain.covariances.is_empty() && plain.covariance_epoch.is_empty());
        assert_eq!(kept.sigma, plain.sigma);
        assert_eq!(kept.final_covariance, plain.final_covariance);
        let epochs = [
            None,
            Some(0),
            Some(0),
            Some(100),
            Some(100),
            Some(124),
            Some(250),
            None,
        ];
        assert_eq!(kept.covariance_epoch, epochs);
        for (p, epoch) in kept.covariances.iter().zip(epochs) {
            let Some(k) = epoch else {
                assert!(p.is_none());
                continue;
            };
            let p = p.unwrap();
            assert_eq!(p, p.transpose());
            let sigma: [f64; 15] = std::array::from_fn(|i| p[(i, i)].sqrt());
            assert_eq!(sigma, plain.sigma[k], "epoch {k}");
        }
        // Epoch 100 (t = 1.0 s) holds the covariance after its DVL update.
        let p100 = kept.covariances[3].unwrap();
        assert!(p100[(3, 3)].sqrt() < plain.sigma[99][3]);
        assert_eq!(kept.covariances[6].unwrap(), plain.final_covariance);
        let err = pass(&[1.0, 1.0]).unwrap_err();
        assert!(err.to_string().starts_with("covariance_time"), "{err}");
        let err = pass(&[f64::NAN]).unwrap_err();
        assert!(err.to_string().starts_with("covariance_time"), "{err}");
    }

    /// A q schedule switches an external strategy's q at the epoch nearest each row's
    /// time, and nothing else: before the switch the run equals the prior's constant
    /// run bit for bit, from it on the new q's constant run's covariance growth.
    #[test]
    fn q_schedule_sets_external_q_from_its_epoch_on() {
        let n = 300;
        let imu = vec![[0.01, 0.0, -9.79, 0.0, 1e-4, 0.0]; n];
        let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
        let dvl = vec![[0.0; 3]; 3];
        let dvl_time = [0.995, 2.0, 3.004];
        let cfg = FilterConfig::default();
        let init = moving_state();
        let (qa, qb) = ([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6], [4e-4; 6]);
        let run = |spec: StrategySpec, q_time: &[f64], q_values: &[[f64; 6]]| {
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl: &dvl,
                dvl_time: &dvl_time,
                t0: 0.0,
                q_time,
                q_values,
                covariance_time: &[],
                ..RecordedData::default()
            };
            filter_recorded(
                &data,
                init,
                [0.0; 6],
                &cfg,
                spec.build(cfg.bias_psd()).as_mut(),
            )
        };
        let constant_a = run(StrategySpec::Constant { q: qa }, &[], &[]).unwrap();
        let external = |q_time: &[f64], q_values: &[[f64; 6]]| {
            run(StrategySpec::External { prior_q: qa }, q_time, q_values).unwrap()
        };
        // Setting the prior's own q at t0 changes nothing.
        assert_eq!(external(&[0.0], &[qa]).sigma, constant_a.sigma);
        // Switching at 1.504 s (nearest epoch 1.50): the first 150 steps are the prior's.
        let switched = external(&[1.504], &[qb]);
        assert_eq!(switched.sigma[..=150], constant_a.sigma[..=150]);
        assert!(switched.sigma[151][3] > constant_a.sigma[151][3]);
        // A schedule with a strategy that does not take q from outside is refused.
        let err = run(StrategySpec::Constant { q: qa }, &[0.0], &[qa]).unwrap_err();
        assert!(err.to_string().starts_with("strategy"), "{err}");
        let err = run(
            StrategySpec::External { prior_q: qa },
            &[1.0, 0.5],
            &[qa, qb],
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("q_time"), "{err}");
        let err = run(StrategySpec::External { prior_q: qa }, &[1.0], &[[-1.0; 6]]).unwrap_err();
        assert!(err.to_string().starts_with("q: row 0"), "{err}");
    }

    /// IMU rows, their times, DVL rows, their times.
    type Pass = (Vec<[f64; 6]>, Vec<f64>, Vec<[f64; 3]>, Vec<f64>);

    /// A moving pass of `n` steps with a DVL row every second.
    fn moving_pass(n: usize) -> Pass {
        let imu = (0..n)
            .map(|k| {
                let wobble = (k as f64 * 0.07).sin();
                [0.02 * wobble, -0.01, -9.79, 1e-4, 2e-4 * wobble, 2e-4]
            })
            .collect();
        let imu_time = (1..=n).map(|k| k as f64 * 0.01).collect();
        let dvl_time: Vec<f64> = (1..=n / 100).map(|k| k as f64).collect();
        let dvl = dvl_time
            .iter()
            .map(|t| [0.5 + 0.01 * t, 0.01, -0.002 * t])
            .collect();
        (imu, imu_time, dvl, dvl_time)
    }

    /// The smoother's nodes: for every strategy (the noise changing at updates, and at
    /// q schedule rows between them), each interval rebuilt from its first node goes
    /// through the forward pass's covariances, bit for bit (its σ at every epoch).
    #[test]
    fn smoother_intervals_rebuild_the_forward_covariances_exactly() {
        let (imu, imu_time, dvl, dvl_time) = moving_pass(600);
        let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
        let cases = [
            (StrategySpec::Constant { q }, vec![], vec![]),
            (
                StrategySpec::Mehra {
                    window: 2,
                    prior_q: q,
                },
                vec![],
                vec![],
            ),
            (
                StrategySpec::Adaptive {
                    window: 2,
                    prior_q: q,
                },
                vec![],
                vec![],
            ),
            (
                StrategySpec::External { prior_q: q },
                vec![1.504, 3.0, 4.25],
                vec![[4e-4; 6], q, [2e-4; 6]],
            ),
        ];
        for formulation in [Formulation::Classic, Formulation::Invariant] {
            let cfg = FilterConfig {
                formulation,
                ..FilterConfig::default()
            };
            for (spec, q_time, q_values) in &cases {
                let data = RecordedData {
                    imu: &imu,
                    imu_time: &imu_time,
                    dvl: &dvl,
                    dvl_time: &dvl_time,
                    q_time,
                    q_values,
                    ..RecordedData::default()
                };
                let mut strategy = spec.build(cfg.bias_psd());
                let mut nodes = Nodes::default();
                let out = forward_pass(
                    &data,
                    moving_state(),
                    [0.0; 6],
                    &cfg,
                    strategy.as_mut(),
                    Epochs::All,
                    Some(&mut nodes),
                    &Cancel::default(),
                )
                .unwrap();
                let nodes = nodes.0;
                // A node at the start, at each of the 6 DVL epochs (the last one the
                // end), and at each q row that fell between them.
                assert_eq!(nodes.first().unwrap().epoch, 0);
                assert_eq!(nodes.last().unwrap().epoch, 600);
                let updates = nodes
                    .iter()
                    .filter(|n| n.correction != Vector15::zeros())
                    .count();
                assert_eq!(updates, 6, "{spec:?}");
                assert_eq!(
                    nodes.len(),
                    7 + usize::from(!q_time.is_empty()) * 2,
                    "{spec:?}"
                );
                let forward = Forward {
                    imu: &imu,
                    imu_time: &imu_time,
                    t0: 0.0,
                    nav: &out.nav,
                    bias: &out.bias,
                    dt: None,
                };
                for pair in nodes.windows(2) {
                    let interval = smoother::Interval::rebuild(
                        &forward,
                        &cfg,
                        &pair[0],
                        pair[1].epoch,
                        None,
                        &Cancel::default(),
                    )
                    .unwrap();
                    let (a, b) = (pair[0].epoch, pair[1].epoch);
                    assert_eq!(interval.p.len(), b - a);
                    for (k, p) in interval.p.iter().enumerate() {
                        let zero = Vector3::zeros();
                        let mut ekf = Ekf::new(&cfg, out.nav[a + k], zero, zero).unwrap();
                        ekf.p = *p;
                        let at = a + k;
                        assert_eq!(ekf.sigma(), out.sigma[at], "{spec:?} {formulation:?} {at}");
                    }
                }
            }
        }
    }

    /// The Monte Carlo's way to the smoothed covariance (the interval's forward product,
    /// inverted where read) gives the σ of the step-by-step way, to rounding, and the
    /// same mean; epochs it is not asked for stay NaN.
    #[test]
    fn covariances_where_asked_equal_the_step_by_step_ones() {
        let (imu, imu_time, dvl, dvl_time) = moving_pass(400);
        let cfg = FilterConfig::default();
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl: &dvl,
            dvl_time: &dvl_time,
            ..RecordedData::default()
        };
        let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(cfg.bias_psd());
        let mut nodes = Nodes::default();
        let cancel = Cancel::default();
        let out = forward_pass(
            &data,
            moving_state(),
            [0.0; 6],
            &cfg,
            strategy.as_mut(),
            Epochs::All,
            Some(&mut nodes),
            &cancel,
        )
        .unwrap();
        let forward = Forward {
            imu: &imu,
            imu_time: &imu_time,
            t0: 0.0,
            nav: &out.nav,
            bias: &out.bias,
            dt: None,
        };
        let every = smoother::smooth(&forward, &cfg, &nodes.0, Covariances::Every, &cancel);
        let odd = |k: usize| k % 7 == 3;
        let some = smoother::smooth(&forward, &cfg, &nodes.0, Covariances::Where(&odd), &cancel);
        let (every, some) = (every.unwrap(), some.unwrap());
        assert_eq!(every.nav, some.nav);
        let nodes: Vec<usize> = nodes.0.iter().map(|n| n.epoch).collect();
        for (k, (a, b)) in every.sigma.iter().zip(&some.sigma).enumerate() {
            if odd(k) || nodes.contains(&k) {
                for (x, y) in a.iter().zip(b) {
                    assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-12), "{k}: {x} {y}");
                }
            } else {
                assert!(b.iter().all(|y| y.is_nan()), "{k}");
            }
        }
    }

    /// Without a measurement there is nothing to smooth: the smoothed solution is the
    /// forward one. With them, the smoothed σ is below the forward σ inside the pass
    /// and equal at its end; what cannot be smoothed is refused by name.
    #[test]
    fn smoothing_without_measurements_changes_nothing() {
        let (imu, imu_time, dvl, dvl_time) = moving_pass(300);
        let cfg = FilterConfig::default();
        let spec = StrategySpec::Constant { q: [1e-4; 6] };
        let pass = |dvl: &[[f64; 3]], dvl_time: &[f64], cfg: &FilterConfig| {
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl,
                dvl_time,
                ..RecordedData::default()
            };
            smooth_recorded_until(
                &data,
                moving_state(),
                [0.0; 6],
                cfg,
                spec.build(cfg.bias_psd()).as_mut(),
                &Cancel::default(),
            )
        };
        let bare = pass(&[], &[], &cfg).unwrap();
        let s = bare.smoothed.unwrap();
        assert_eq!(s.nav, bare.nav);
        assert_eq!(s.bias, bare.bias);
        for (a, b) in s.sigma.iter().zip(&bare.sigma) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 1e-12 * y, "{x} {y}");
            }
        }
        let aided = pass(&dvl, &dvl_time, &cfg).unwrap();
        let s = aided.smoothed.unwrap();
        assert_eq!(s.sigma[300], aided.sigma[300]);
        assert!(s.sigma[150][3] < 0.99 * aided.sigma[150][3]);
        assert!(s
            .sigma
            .iter()
            .zip(&aided.sigma)
            .all(|(a, b)| a.iter().zip(b).all(|(x, y)| *x <= y * (1.0 + 1e-12))));
        let calibrated = FilterConfig {
            dvl_calibration: Some(super::super::calibration::CalibrationConfig::default()),
            ..FilterConfig::default()
        };
        let err = pass(&dvl, &dvl_time, &calibrated).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("config: the smoother does not smooth"),
            "{err}"
        );
    }

    /// The text `tests/test_core_rules.py` expects from `pronet.run_filter`.
    #[test]
    fn a_start_beyond_89_degrees_is_refused_naming_lla0() {
        let imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 2];
        let data = imu_only(&imu, &[0.01, 0.02]);
        let cfg = FilterConfig::default();
        let init = NavState {
            lla: Vector3::new(-1.56, 0.0, 0.0),
            vel: Vector3::zeros(),
            dcm: nalgebra::Matrix3::identity(),
        };
        let spec = crate::noise::StrategySpec::Constant { q: [1e-4; 6] };
        let err = filter_recorded(
            &data,
            init,
            [0.0; 6],
            &cfg,
            spec.build(cfg.bias_psd()).as_mut(),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "lla0: latitude must be within ±89° (given in radians; NED is singular at the poles)"
        );
    }
}
