//! One filter pass over recorded (or user-simulated) sensor arrays, and its smoother.

use super::data::RecordedData;
use super::epochs::Epochs;
use super::memory::estimate;
use super::output::FilterOutput;
use super::recorder::Recorder;
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::earth;
use crate::ekf::{Ekf, FilterConfig};
use crate::error::{check, Error, Result};
use crate::measurement::Reading;
use crate::mechanization::{ImuSample, NavState};
use crate::noise::NoiseStrategy;
use crate::pass::{Epoch, Failure, Pass};
use crate::smoother::thinned::{self, NodeStates, Thinned};
use crate::smoother::{self, Covariances, Forward, ForwardLog};
use nalgebra::Vector3;

/// Run the filter over recorded arrays from an initial state. A stream's row is applied
/// after the IMU step that reaches the epoch nearest to its time (first epoch with
/// `t ≥ t_row − Δt/2`); rows outside the run are skipped and reported as `None`. At an
/// epoch the streams' rows are applied stream by stream, in their order.
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
    // SE₂(3)'s anchor fixed here, where the backward pass reads it too.
    let cfg = &cfg.anchored(&initial.lla);
    let run = Recording {
        data,
        initial,
        initial_bias,
        cfg,
    };
    run.forward(strategy, epochs, None, cancel)
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
    // SE₂(3)'s anchor fixed here, where the backward pass reads it too.
    let cfg = &cfg.anchored(&initial.lla);
    let run = Recording {
        data,
        initial,
        initial_bias,
        cfg,
    };
    match epochs {
        Epochs::All => run.smooth_every(strategy, cancel),
        Epochs::Last => Err(Error::invalid(
            "epochs",
            "the smoother corrects the kept epochs: keep all, or some (an output step)",
        )),
        Epochs::Step(_) => run.smooth_thinned(strategy, epochs, cancel),
    }
}

/// What the node-only backward pass reads of a forward pass `out` over `data` that
/// kept the node states `states` and the epochs `epochs` (`out.epoch`, or every one).
pub(super) fn thinned_source<'a>(
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

/// What one pass starts from: the recording, the initial state and bias estimates
/// (`[b_a, b_g]`), and the filter's configuration.
pub(super) struct Recording<'a> {
    pub(super) data: &'a RecordedData<'a>,
    pub(super) initial: NavState,
    pub(super) initial_bias: [f64; 6],
    pub(super) cfg: &'a FilterConfig,
}

impl<'a> Recording<'a> {
    /// A pass from the moving test state with zero bias estimates.
    #[cfg(test)]
    pub(super) fn of(data: &'a RecordedData<'a>, cfg: &'a FilterConfig) -> Self {
        Recording {
            data,
            initial: crate::ekf::tests::moving_state(),
            initial_bias: [0.0; 6],
            cfg,
        }
    }

    /// Every epoch kept, then the backward pass over them.
    pub(super) fn smooth_every(
        &self,
        strategy: &mut dyn NoiseStrategy,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        let mut log = ForwardLog::default();
        let mut out = self.forward(strategy, Epochs::All, Some(&mut log), cancel)?;
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
        let nodes = &log.nodes.0;
        let smoothed = smoother::smooth(&forward, self.cfg, nodes, Covariances::Every, cancel)?;
        out.smoothed = Some(smoothed);
        Ok(out)
    }

    /// With an [`Epochs::Step`]: the forward pass keeps its solution at the nodes and
    /// the kept epochs only ([`smoother::thinned`]).
    pub(super) fn smooth_thinned(
        &self,
        strategy: &mut dyn NoiseStrategy,
        epochs: Epochs,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        let mut log = ForwardLog {
            states: Some(NodeStates::default()),
            ..ForwardLog::default()
        };
        let mut out = self.forward(strategy, epochs, Some(&mut log), cancel)?;
        let states = log.states.as_ref().unwrap_or_else(|| unreachable!());
        let forward = thinned_source(self.data, states, &out, &out.epoch);
        let smoothed = thinned::smooth(&forward, self.cfg, &log.nodes.0, cancel)?;
        out.smoothed = Some(smoothed);
        Ok(out)
    }

    /// The forward pass keeping `epochs`; with `log`, what the smoother needs.
    pub(super) fn forward(
        &self,
        strategy: &mut dyn NoiseStrategy,
        epochs: Epochs,
        mut log: Option<&mut ForwardLog>,
        cancel: &Cancel,
    ) -> Result<FilterOutput> {
        epochs.validate()?;
        let data = self.data;
        let mut pass = Pass::new(self.start(strategy)?);
        let smooth = log.is_some();
        let memory = estimate(data, epochs, self.cfg, smooth, strategy.sets_discrete_q());
        memory.peak().check("this pass")?;
        let mut recorder = Recorder::start(data, epochs, smooth, &pass.ekf);
        let n = data.imu.len();
        let first = data.first_time();
        let mut next_row = vec![0; data.streams.len()];
        let mut next_q = 0;
        let mut readings: Vec<Reading> = Vec::new();
        let mut t_prev = data.t0;
        for (k, (sample, &t)) in data.imu.iter().zip(data.imu_time).enumerate() {
            if k % STEPS_PER_CHECK == 0 {
                cancel.check()?;
            }
            let dt = t - t_prev;
            set_scheduled_q(data, strategy, &mut next_q, t_prev + 0.5 * dt)?;
            // The rows whose nearest epoch this is, stream by stream; those before the
            // run's first half step are outside it.
            readings.clear();
            recorder.sources.clear();
            for (s, stream) in data.streams.iter().enumerate() {
                let next = &mut next_row[s];
                while *next < stream.len() && stream.time[*next] <= t + 0.5 * dt {
                    if stream.time[*next] >= first {
                        readings.push(stream.reading(*next));
                        recorder.sources.push((s, *next));
                    }
                    *next += 1;
                }
            }
            recorder.next_dt = data.imu_time.get(k + 1).map_or(dt, |&next| next - t);
            let raw = ImuSample::from_array(sample);
            let at = Epoch {
                index: k + 1,
                raw: &raw,
                dt,
                t,
                last: k + 1 == n,
            };
            let mut observer = (&mut recorder, log.as_deref_mut());
            pass.epoch(strategy, &at, &readings, &mut observer)
                .map_err(|f| self.context(f, &recorder.sources, t))?;
            t_prev = t;
        }
        if let Some(log) = log {
            log.finish(n, &pass.ekf);
        }
        Ok(recorder.finish(&pass.ekf, t_prev))
    }

    /// A failure of the pass at time `t` \[s\], named with its stream's row.
    fn context(&self, failure: Failure, sources: &[(usize, usize)], t: f64) -> Error {
        match (failure.error, failure.reading) {
            (Error::Numerical(m), None) => Error::Numerical(format!("{m} (t = {t} s)")),
            (Error::Numerical(m), Some(i)) => {
                let (stream, row) = sources[i];
                let name = self.data.streams[stream].reading(row).name();
                Error::Numerical(format!("{m} ({name} row {row}, t = {t} s)"))
            }
            (other, _) => other,
        }
    }

    /// The filter at the start of the pass, once the data, the initial state and the
    /// strategy have been checked for it.
    fn start(&self, strategy: &dyn NoiseStrategy) -> Result<Ekf> {
        let data = self.data;
        earth::check_latitude("lla0", self.initial.lla[0])?;
        data.validate()?;
        for stream in &data.streams {
            stream.check_config(self.cfg)?;
        }
        if !data.q_time.is_empty() && !strategy.takes_outside_q() {
            return Err(Error::invalid(
                "strategy",
                "a q schedule needs an external strategy (Strategy.external)",
            ));
        }
        start_filter(&self.initial, &self.initial_bias, self.cfg, strategy)
    }
}

/// The filter at the start of a pass over recorded data (or fed as it comes) from the
/// initial state `initial` (its latitude named `lla0`) and bias estimates `bias`
/// (`[b_a, b_g]`, named `bias0`), checked, with `strategy` checked for recorded data
/// (no oracle) and the sensitivity it asks for tracked.
pub fn start_filter(
    initial: &NavState,
    bias: &[f64; 6],
    cfg: &FilterConfig,
    strategy: &dyn NoiseStrategy,
) -> Result<Ekf> {
    earth::check_latitude("lla0", initial.lla[0])?;
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
        cfg,
        *initial,
        Vector3::new(bias[0], bias[1], bias[2]),
        Vector3::new(bias[3], bias[4], bias[5]),
    )?;
    if let Some(q) = strategy.sensitivity_q() {
        ekf.track_sensitivity(q);
    }
    Ok(ekf)
}

/// Set the last q schedule row stamped at or before `until` \[s\] (the epoch's start
/// plus half its step) not yet set: a row takes effect from the epoch nearest to it.
fn set_scheduled_q(
    data: &RecordedData<'_>,
    strategy: &mut dyn NoiseStrategy,
    next: &mut usize,
    until: f64,
) -> Result<()> {
    let mut q_in_force: Option<[f64; 6]> = None;
    while *next < data.q_time.len() && data.q_time[*next] <= until {
        q_in_force = Some(data.q_values[*next]);
        *next += 1;
    }
    if let Some(q) = q_in_force {
        strategy.set_imu_variance(&q)?;
    }
    Ok(())
}
