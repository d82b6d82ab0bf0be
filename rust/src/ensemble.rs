//! The lockstep [`Ensemble`]: all runs of a Monte Carlo stepped together, pausing at
//! tuning instants so that outside code (the ProNet regressor) can read each run's last
//! raw IMU samples and set its IMU noise variances; and the tuning-instant rule it shares
//! with the hybrid loop on recorded data ([`TuningSchedule`]).

use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::FilterConfig;
use crate::error::{check, Error, Result};
use crate::montecarlo::{check_result_size, check_strategy, estimate_memory, McOptions, McResult};
use crate::noise::StrategySpec;
use crate::run::Run;
use crate::scenario::{epoch_times, Scenario};
use rayon::prelude::*;
use std::sync::Arc;

/// The hybrid loop's tuning instants over `n_samples` IMU samples of step `dt` \[s\]:
/// every `round(tuning_period / dt)` samples (Rust's `f64::round`, half away from zero;
/// at least 1), from the first such multiple at which `window` samples exist. An instant
/// is the number of samples before it; the last sample is no instant (nothing is left
/// to tune). The [`Ensemble`] stops at these instants, and the hybrid loop on recorded
/// data (`pronet.hybrid.q_schedule`) evaluates its regressor at them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TuningSchedule {
    /// Samples between instants.
    pub every: usize,
    /// The first instant (a multiple of `every`, at least `window`).
    pub first: usize,
    pub n_samples: usize,
}

impl TuningSchedule {
    /// The schedule, or an error naming `dt`, `tuning_period` (finite and > 0 s, and at
    /// least one IMU period once rounded to whole steps) or `window` (at least 1 sample).
    pub fn new(n_samples: usize, dt: f64, window: usize, tuning_period: f64) -> Result<Self> {
        check::positive("dt", dt)?;
        if !(tuning_period.is_finite() && tuning_period > 0.0) {
            return Err(Error::invalid(
                "tuning_period",
                format!("must be finite and > 0 s, got {tuning_period}"),
            ));
        }
        if (tuning_period / dt).round() < 1.0 {
            // It would round to no step: a regressor call at every sample, 100 times the
            // default 1 s period's cost at 100 Hz, where a unit slip is the likely cause.
            return Err(Error::invalid(
                "tuning_period",
                format!(
                    "must be at least one IMU period once rounded to whole steps of \
                     {dt} s, got {tuning_period} s"
                ),
            ));
        }
        if window == 0 {
            return Err(Error::invalid("window", "must be at least 1 sample, got 0"));
        }
        // Capped at n_samples: a longer period has no instant either, and the cap keeps a
        // huge period (or a tiny step) inside usize.
        let every = ((tuning_period / dt).min(n_samples as f64).round() as usize).max(1);
        let first = window.div_ceil(every).saturating_mul(every);
        Ok(Self {
            every,
            first,
            n_samples,
        })
    }

    /// The next instant after `k` samples, or `n_samples` when none is left.
    pub fn next_after(&self, k: usize) -> usize {
        let next = if k < self.first {
            self.first
        } else {
            (k / self.every)
                .saturating_add(1)
                .saturating_mul(self.every)
        };
        next.min(self.n_samples)
    }

    /// The instants, in order.
    pub fn instants(&self) -> impl ExactSizeIterator<Item = usize> {
        let count = self
            .n_samples
            .saturating_sub(self.first)
            .div_ceil(self.every);
        let (first, every) = (self.first, self.every);
        (0..count).map(move |i| first + i * every)
    }

    /// The instants as a vector, or an error naming `n_samples` when they do not fit
    /// in memory (a hostile count must not abort the process).
    pub fn to_vec(&self) -> Result<Vec<usize>> {
        let instants = self.instants();
        let mut out = Vec::new();
        out.try_reserve_exact(instants.len()).map_err(|_| {
            Error::invalid(
                "n_samples",
                format!("{} tuning instants do not fit in memory", instants.len()),
            )
        })?;
        out.extend(instants);
        Ok(out)
    }
}

/// All runs of a Monte Carlo stepped in lockstep, pausing at tuning instants so that
/// the caller can read each run's last `window` raw IMU samples and set its IMU noise
/// variances (external strategy).
pub struct Ensemble {
    scenario: Arc<Scenario>,
    runs: Vec<Run>,
    k: usize,
    window: usize,
    tuning: TuningSchedule,
    dvl_every: Option<usize>,
    record_every: usize,
}

impl Ensemble {
    /// `window`: samples handed out (1 to the trajectory's length); `tuning_period` \[s\]:
    /// time between tuning instants (see [`TuningSchedule`]). Until the first instant
    /// every run uses `prior_q`.
    pub fn new(
        scenario: Arc<Scenario>,
        filter: &FilterConfig,
        prior_q: [f64; 6],
        opts: &McOptions,
        window: usize,
        tuning_period: f64,
    ) -> Result<Self> {
        let strategy = StrategySpec::External { prior_q };
        check_strategy(filter, &strategy, opts)?;
        if window == 0 || window > scenario.truth.len() {
            return Err(Error::invalid(
                "window",
                format!(
                    "must be 1 to {} samples (the trajectory's length), got {window}",
                    scenario.truth.len()
                ),
            ));
        }
        let truth = &scenario.truth;
        let tuning = TuningSchedule::new(truth.len(), truth.dt, window, tuning_period)?;
        let dvl_every = scenario.dvl_every()?;
        // Each run keeps its last `window` raw samples, and hands them out as float32.
        check_result_size(&scenario, opts, dvl_every, window * 6 * (8 + 4))?;
        let sizes = (dvl_every, window, opts.n_runs);
        estimate_memory(&scenario, (filter, &strategy), opts, sizes).check("this ensemble")?;
        let mut runs = Vec::with_capacity(opts.n_runs);
        for i in 0..opts.n_runs {
            let mut run = Run::new(
                &scenario,
                filter,
                &strategy,
                opts.seed,
                opts.first_run + i as u64,
                opts.record_every,
                Some(window),
            )?;
            if opts.smooth {
                run.keep_for_smoother(&scenario);
            }
            runs.push(run);
        }
        Ok(Self {
            scenario,
            runs,
            k: 0,
            window,
            tuning,
            dvl_every,
            record_every: opts.record_every,
        })
    }

    pub fn n_runs(&self) -> usize {
        self.runs.len()
    }

    pub fn window(&self) -> usize {
        self.window
    }

    /// IMU steps taken so far (the same for every run).
    pub fn steps(&self) -> usize {
        self.k
    }

    /// Time of the current epoch \[s\].
    pub fn time(&self) -> f64 {
        self.scenario.truth.time[self.k]
    }

    pub fn is_done(&self) -> bool {
        self.k >= self.scenario.truth.len()
    }

    /// Step every run (in parallel) to the next tuning instant. Returns the windows as
    /// a flat `(n_runs, 6, window)` float32 buffer, oldest sample first, or `None` once
    /// the end of the trajectory is reached.
    pub fn advance(&mut self) -> Option<Vec<f32>> {
        // A flag nobody sets: the call cannot be cancelled, so it cannot fail.
        self.advance_until(&Cancel::default()).unwrap_or(None)
    }

    /// [`Self::advance`] that stops with [`Error::Cancelled`] soon after `cancel` is
    /// set (every run checks it each [`STEPS_PER_CHECK`] steps). The runs are then left
    /// at different steps: the ensemble must not be used again.
    pub fn advance_until(&mut self, cancel: &Cancel) -> Result<Option<Vec<f32>>> {
        if self.is_done() {
            return Ok(None);
        }
        let stop = self.tuning.next_after(self.k);
        let steps = stop - self.k;
        let scenario = &*self.scenario;
        self.runs.par_iter_mut().for_each(|r| {
            for i in 0..steps {
                if i % STEPS_PER_CHECK == 0 && cancel.is_cancelled() {
                    return;
                }
                r.step(scenario);
            }
        });
        cancel.check()?;
        self.k = stop;
        if self.is_done() {
            return Ok(None);
        }
        let per_run = 6 * self.window;
        let mut out = vec![0f32; self.runs.len() * per_run];
        out.par_chunks_mut(per_run)
            .zip(self.runs.par_iter())
            .for_each(|(chunk, run)| {
                run.write_window(chunk);
            });
        Ok(Some(out))
    }

    /// Set each run's IMU noise variances q (one row of 6 per run).
    pub fn set_q(&mut self, q: &[[f64; 6]]) -> Result<()> {
        if q.len() != self.runs.len() {
            return Err(Error::invalid(
                "q",
                format!(
                    "needs one row per run: {} rows for {} runs",
                    q.len(),
                    self.runs.len()
                ),
            ));
        }
        for (i, row) in q.iter().enumerate() {
            if row.iter().any(|v| !v.is_finite() || *v < 0.0) {
                return Err(Error::invalid(
                    "q",
                    format!("row {i} must be finite and >= 0, got {row:?}"),
                ));
            }
        }
        for (run, row) in self.runs.iter_mut().zip(q) {
            run.strategy_mut().set_imu_variance(row)?;
        }
        Ok(())
    }

    /// Run to the end (if not there yet) and collect the results.
    pub fn finish(self) -> Result<McResult> {
        self.finish_until(&Cancel::default())
    }

    /// [`Self::finish`] that stops with [`Error::Cancelled`] soon after `cancel` is set.
    pub fn finish_until(mut self, cancel: &Cancel) -> Result<McResult> {
        while self.advance_until(cancel)?.is_some() {}
        let truth = &self.scenario.truth;
        Ok(McResult {
            dvl_time: self.scenario.dvl_epoch_times(self.dvl_every),
            record_time: if self.record_every > 0 {
                epoch_times(truth, self.record_every, true)
            } else {
                Vec::new()
            },
            runs: self
                .runs
                .into_iter()
                .map(|r| r.finish(&self.scenario))
                .collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::montecarlo::run_monte_carlo;
    use crate::montecarlo::tests::{short_scenario, tuned_filter, TRUE_Q};
    use crate::sensors::{SensorConfig, SensorSim, VarianceSchedule};
    use crate::trajectory::{Segment, TrajectorySpec};
    use nalgebra::Vector3;

    /// Monte Carlo options from the first run.
    fn options(n_runs: usize, seed: u64, record_every: usize) -> McOptions {
        McOptions {
            n_runs,
            seed,
            record_every,
            first_run: 0,
            smooth: false,
        }
    }

    #[test]
    fn ensemble_without_outside_tuning_equals_the_monte_carlo_with_the_prior() {
        let sc = short_scenario(20.0);
        let opts = options(3, 9, 100);
        let mc = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap();
        let mut ens =
            Ensemble::new(Arc::clone(&sc), &tuned_filter(), TRUE_Q, &opts, 200, 1.0).unwrap();
        let mut stops = Vec::new();
        while let Some(w) = ens.advance() {
            assert_eq!(w.len(), 3 * 6 * 200);
            stops.push(ens.steps());
        }
        assert_eq!(stops.first(), Some(&200));
        assert_eq!(stops.last(), Some(&1900));
        assert_eq!(format!("{:?}", ens.finish().unwrap()), format!("{mc:?}"));
    }

    #[test]
    fn a_cancelled_ensemble_stops_at_its_next_check() {
        let sc = short_scenario(5.0);
        let opts = options(2, 3, 0);
        let make = || Ensemble::new(Arc::clone(&sc), &tuned_filter(), TRUE_Q, &opts, 50, 0.5);
        let cancel = Cancel::default();
        let mut ens = make().unwrap();
        assert!(ens.advance_until(&cancel).unwrap().is_some());
        let steps = ens.steps();
        cancel.cancel();
        assert_eq!(ens.advance_until(&cancel), Err(Error::Cancelled));
        assert_eq!(
            ens.steps(),
            steps,
            "the step count does not move past a cancel"
        );
        assert!(make().unwrap().finish_until(&cancel).is_err());
    }

    #[test]
    fn ensemble_windows_hold_the_raw_samples_oldest_first() {
        let sc = short_scenario(5.0);
        let opts = options(2, 3, 0);
        let mut ens =
            Ensemble::new(Arc::clone(&sc), &tuned_filter(), TRUE_Q, &opts, 50, 0.5).unwrap();
        let w = ens.advance().unwrap();
        // Regenerate run 1's first 50 raw samples from its stream (with its turn-on bias).
        let (_, bias) = crate::run::initial_state(&sc, &tuned_filter(), 3, 1);
        assert!(bias.iter().all(|b| *b != 0.0), "a drawn turn-on bias");
        let mut sim = SensorSim::new(&sc.sensors, 3, 1).with_turn_on_bias(bias);
        let raw: Vec<[f64; 6]> = (0..50)
            .map(|k| {
                sim.imu(
                    &sc.sensors.imu,
                    &sc.truth.imu[k],
                    sc.truth.time[k],
                    sc.truth.dt,
                )
            })
            .collect();
        for c in 0..6 {
            for j in 0..50 {
                assert_eq!(w[300 + c * 50 + j], raw[j][c] as f32);
            }
        }
        // Setting q changes what the filter uses from then on.
        ens.set_q(&[[1e-2; 6], [1e-2; 6]]).unwrap();
        assert!(ens.set_q(&[[1e-2; 6]]).is_err());
        assert!(ens.set_q(&[[f64::NAN; 6], [1.0; 6]]).is_err());
    }

    #[test]
    fn varying_noise_and_bias_are_simulated() {
        let spec = TrajectorySpec {
            name: "still".into(),
            lla0: crate::trajectory::paper_origin(),
            speed0: 0.0,
            rpy0: Vector3::zeros(),
            segments: vec![Segment::new(10.0, 0.0, 0.0, 0.0)],
            dt: 0.01,
        };
        let mut sensors = SensorConfig::paper();
        sensors.imu.variance =
            VarianceSchedule::new(vec![0.0, 5.0], vec![[1e-4; 6], [4e-2; 6]]).unwrap();
        let sc = Arc::new(Scenario {
            truth: Arc::new(spec.generate().unwrap()),
            sensors,
            sample_initial_error: false,
        });
        let opts = options(1, 0, 0);
        let mut ens = Ensemble::new(sc, &tuned_filter(), TRUE_Q, &opts, 400, 1.0).unwrap();
        let mut variances = Vec::new();
        while let Some(w) = ens.advance() {
            // Variance of the x-accelerometer window about its mean.
            let x = &w[..400];
            let m = x.iter().map(|v| *v as f64).sum::<f64>() / 400.0;
            variances.push((
                ens.time(),
                x.iter().map(|v| (*v as f64 - m).powi(2)).sum::<f64>() / 399.0,
            ));
        }
        let (early, late) = (variances[0].1, variances.last().unwrap().1);
        assert!(early < 3e-4 && late > 2e-2, "{variances:?}");
    }

    /// The texts `tests/test_core_rules.py` expects from Python, and the rounding.
    #[test]
    fn tuning_schedule_rounds_half_away_from_zero_and_names_bad_arguments() {
        let at = |n, dt, window, period| {
            TuningSchedule::new(n, dt, window, period)
                .map(|s| s.instants().collect::<Vec<_>>())
                .map_err(|e| e.to_string())
        };
        assert_eq!(at(10, 1.0, 1, 2.5), Ok(vec![3, 6, 9]));
        assert_eq!(at(10, 1.0, 4, 1.5), Ok(vec![4, 6, 8]));
        assert_eq!(at(5, 1.0, 1, 0.5), Ok(vec![1, 2, 3, 4]));
        assert_eq!(
            at(5, 1.0, 1, 0.49999999999999994),
            Err(
                "tuning_period: must be at least one IMU period once rounded to whole steps \
                 of 1 s, got 0.49999999999999994 s"
                    .into()
            )
        );
        assert_eq!(at(5, 1.0, 5, 1.0), Ok(vec![]));
        assert_eq!(at(5, 1.0, usize::MAX, 2.0), Ok(vec![]));
        assert_eq!(at(5, 1e-300, 1, 1e300), Ok(vec![]));
        assert_eq!(
            at(5, 1.0, 1, 0.0),
            Err("tuning_period: must be finite and > 0 s, got 0".into())
        );
        assert_eq!(
            at(5, 1.0, 1, f64::NAN),
            Err("tuning_period: must be finite and > 0 s, got NaN".into())
        );
        assert_eq!(
            at(5, 1.0, 0, 1.0),
            Err("window: must be at least 1 sample, got 0".into())
        );
        assert_eq!(
            at(5, -1.0, 1, 1.0),
            Err("dt: must be finite and > 0, got -1".into())
        );
        // The Ensemble stops exactly there.
        let s = TuningSchedule::new(1000, 0.01, 150, 0.505).unwrap();
        let mut k = 0;
        let mut stops = Vec::new();
        while k < s.n_samples {
            k = s.next_after(k);
            stops.push(k);
        }
        stops.pop();
        assert_eq!(stops, s.instants().collect::<Vec<_>>());
        assert_eq!(stops[0], 153);
    }
}
