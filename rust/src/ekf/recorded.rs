//! One filter pass over recorded (or user-simulated) IMU and DVL arrays.

use super::{Ekf, FilterConfig, Matrix15, NisMonitor, UpdateInfo};
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
    /// Divergence watch over every update's NIS.
    pub nis_monitor: NisMonitor,
}

/// Inputs of one filter pass over recorded (or user-simulated) sensor arrays.
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
            nis_monitor: NisMonitor::default(),
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
        ekf.propagate(&ImuSample::from_array(sample), dt, strategy.process_noise())
            .map_err(|e| match e {
                Error::Numerical(m) => Error::Numerical(format!("{m} (t = {t} s)")),
                other => other,
            })?;
        at.steps_since_update += 1;
        if k + 1 == data.imu.len() {
            ekf.bring_up_to_date(); // the end of the pass
        }
        apply_dvl_rows(data, &mut ekf, strategy, &mut out, &mut at, k + 1, t, dt)?;
        if every {
            out.record(&ekf, t);
        }
        t_prev = t;
    }
    if !every {
        out.record(&ekf, t_prev);
    }
    out.final_covariance = ekf.covariance();
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

/// Apply every DVL row whose nearest epoch is `epoch` (time `t` [s], step `dt` [s]).
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
) -> Result<()> {
    while at.next_dvl < data.dvl.len() && data.dvl_time[at.next_dvl] <= t + 0.5 * dt {
        let row = at.next_dvl;
        let z = Vector3::from_column_slice(&data.dvl[row]);
        let info = ekf.update(&z).map_err(|e| match e {
            Error::Numerical(m) => Error::Numerical(format!("{m} (DVL row {row}, t = {t} s)")),
            other => other,
        })?;
        out.nis_monitor.push(info.nis, t);
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::tests::moving_state;
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
