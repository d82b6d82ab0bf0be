//! Monte Carlo over simulated runs of a scenario, in parallel with rayon. One run is a
//! [`Run`] (see [`crate::run`]); the lockstep variant that pauses all runs at tuning
//! instants for outside tuning is [`crate::ensemble::Ensemble`].
//!
//! Run `i` of a Monte Carlo with seed `s` draws all its randomness from streams keyed
//! by `(s, i)` (see [`crate::sensors`]), so its results are the same whatever the thread
//! count, whichever other runs are in the batch, and whatever the strategy: every
//! strategy sees the same noise (common random numbers).

use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};
use crate::memory::Estimate;
use crate::noise::StrategySpec;
use crate::run::RunMemory;
pub use crate::run::{History, Run, RunRecord, RunSummary};
use crate::scenario::epoch_times;
use crate::scenario::Scenario;
use rayon::prelude::*;
use std::sync::Arc;

/// The most memory \[bytes\] the records of one Monte Carlo call may take (4 GiB; the
/// Python arrays made from them take as much again). About 190,000 runs of the `paper`
/// scenario without histories.
pub const MAX_RESULT_BYTES: u64 = 4 << 30;

/// What a Monte Carlo holds whatever its size \[bytes\]: its thread pool, the call's
/// state.
pub const MC_BYTES: f64 = 1024.0 * 1024.0;

/// One past the largest run index: run i's random streams are numbered 4·i + k.
pub const MAX_RUN_INDEX: u64 = 1 << 62;

/// `Err` naming `n_runs` when the records of `opts` on `scenario` would take more
/// than [`MAX_RESULT_BYTES`], checked before anything is allocated. Per run: the
/// NIS, five NEES blocks and the DVL calibration states' NEES of every DVL epoch
/// (counted whether or not the filter has those states: the check does not know the
/// filter), the error, 1σ and q (36 values) of every recorded epoch, `state_bytes`
/// of running state, and 4 KiB of filter (the calibration summary included).
pub fn check_result_size(
    scenario: &Scenario,
    opts: &McOptions,
    dvl_every: Option<usize>,
    state_bytes: usize,
) -> Result<()> {
    let steps = scenario.truth.len() as f64;
    let epochs = dvl_every.map_or(0.0, |every| (steps / every.max(1) as f64).floor());
    let records = match opts.record_every {
        0 => 0.0,
        every => (steps / every as f64).floor() + 1.0,
    };
    // A smoothed run records its epochs' NEES and its histories twice.
    let twice = if opts.smooth { 2.0 } else { 1.0 };
    let per_run = 8.0 * twice * (7.0 * epochs + 36.0 * records) + state_bytes as f64 + 4096.0;
    let total = per_run * opts.n_runs as f64;
    if total > MAX_RESULT_BYTES as f64 {
        let gib = |b: f64| b / (1u64 << 30) as f64;
        return Err(Error::invalid(
            "n_runs",
            format!(
                "{} runs of this scenario would hold {:.1} GiB of results; at most {:.0} \
                 GiB per call (here about {} runs): split them into shards (first_run, \
                 or a sweep's shard_runs), or record less",
                opts.n_runs,
                gib(total),
                gib(MAX_RESULT_BYTES as f64),
                (MAX_RESULT_BYTES as f64 / per_run).floor()
            ),
        ));
    }
    Ok(())
}

/// What a Monte Carlo (or an ensemble) of `opts` on `scenario` filtered with `filter`
/// and `strategy` would hold at its peak: every run's records and the arrays made from
/// them (as much again), and the runs under way at once (`alive`: one per thread, or
/// every run of an ensemble), each handing out `window` raw samples, with their
/// smoothers' logs and backward passes ([`RunMemory`]).
pub fn estimate_memory(
    scenario: &Scenario,
    (filter, strategy): (&FilterConfig, &StrategySpec),
    opts: &McOptions,
    (dvl_every, window, alive): (Option<usize>, usize, usize),
) -> Estimate {
    let discrete = strategy.build(filter.bias_psd()).sets_discrete_q();
    let what = (dvl_every, opts.record_every, window);
    let run = RunMemory::of(scenario, filter, what, (opts.smooth, discrete));
    let (runs, alive) = (opts.n_runs as f64, alive.min(opts.n_runs) as f64);
    let mut e = Estimate {
        fixed: MC_BYTES,
        ..Estimate::default()
    };
    e.add(
        "n_runs",
        "runs' records and their arrays",
        (runs, 2.0 * run.epochs),
        "split the runs into shards (first_run, or a sweep's shard_runs)",
    );
    e.add(
        "record_every",
        "runs' histories and their arrays",
        (runs, 2.0 * run.histories),
        "record less often (a larger record_every, or 0 for none), or fewer runs per call",
    );
    e.add(
        "n_runs",
        "runs under way at once",
        (alive, run.running),
        "run fewer at once (fewer runs, or threads)",
    );
    e.add(
        "smooth",
        "smoothers under way",
        (alive, run.smoother),
        "smooth shorter trajectories, on fewer threads at once, or smooth=False",
    );
    e
}

/// Monte Carlo size and recording options.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct McOptions {
    pub n_runs: usize,
    pub seed: u64,
    /// Record the error and 1σ history every this many IMU steps (0: no history).
    pub record_every: usize,
    /// Index of the first run: the runs are `first_run .. first_run + n_runs`, each on
    /// the random streams of `(seed, index)`, so shards of a Monte Carlo computed apart
    /// are bit-identical to the same runs computed whole.
    pub first_run: u64,
    /// Also run the RTS smoother over each run ([`RunRecord::smoothed`]).
    pub smooth: bool,
}

impl McOptions {
    pub fn validate(&self) -> Result<()> {
        if self.n_runs == 0 {
            return Err(Error::invalid("n_runs", "must be at least 1, got 0"));
        }
        if self.n_runs as u64 > MAX_RUN_INDEX {
            return Err(Error::invalid(
                "n_runs",
                format!("must be at most 2^62, got {}", self.n_runs),
            ));
        }
        // Run i's random streams are numbered 4·i + k (sensors::stream_rng): indices
        // beyond 2^62 would wrap onto other runs' noise.
        let last = self.first_run.checked_add(self.n_runs as u64);
        if last.is_none_or(|last| last > MAX_RUN_INDEX) {
            return Err(Error::invalid(
                "first_run",
                format!(
                    "first_run + n_runs must be at most 2^62, got {} + {}",
                    self.first_run, self.n_runs
                ),
            ));
        }
        Ok(())
    }
}

/// All runs of a Monte Carlo, in run order.
#[derive(Clone, Debug, PartialEq)]
pub struct McResult {
    pub runs: Vec<RunRecord>,
    /// Times of the DVL epochs \[s\].
    pub dvl_time: Vec<f64>,
    /// Times of the recorded history epochs \[s\] (empty without history).
    pub record_time: Vec<f64>,
}

pub(crate) fn check_strategy(
    filter: &FilterConfig,
    strategy: &StrategySpec,
    opts: &McOptions,
) -> Result<()> {
    filter.validate()?;
    strategy.validate()?;
    opts.validate()?;
    Ok(())
}

/// Run `opts.n_runs` runs of `scenario` with one strategy, in parallel on the current
/// rayon pool. Run i uses the random streams of `(opts.seed, i)`.
pub fn run_monte_carlo(
    scenario: &Arc<Scenario>,
    filter: &FilterConfig,
    strategy: &StrategySpec,
    opts: &McOptions,
) -> Result<McResult> {
    run_monte_carlo_until(scenario, filter, strategy, opts, &Cancel::default())
}

/// [`run_monte_carlo`] that stops with [`Error::Cancelled`] soon after `cancel` is set:
/// it is checked before each run and every [`STEPS_PER_CHECK`] steps within one.
pub fn run_monte_carlo_until(
    scenario: &Arc<Scenario>,
    filter: &FilterConfig,
    strategy: &StrategySpec,
    opts: &McOptions,
    cancel: &Cancel,
) -> Result<McResult> {
    if strategy.is_external() {
        // Nothing sets an external strategy's q in a Monte Carlo: it would run silently
        // as its prior. Its q comes from outside, through an `Ensemble`.
        return Err(Error::invalid(
            "strategy",
            "an external strategy takes its q from outside (an Ensemble's set_q, or \
             run_filter's q schedule); nothing sets it in a Monte Carlo, where it would \
             only ever use its prior q: use a constant strategy of that q",
        ));
    }
    check_strategy(filter, strategy, opts)?;
    let dvl_every = scenario.dvl_every()?;
    check_result_size(scenario, opts, dvl_every, 0)?;
    let alive = rayon::current_num_threads();
    let sizes = (dvl_every, 0, alive);
    estimate_memory(scenario, (filter, strategy), opts, sizes).check("this Monte Carlo")?;
    let n_steps = scenario.truth.len();
    let runs = (0..opts.n_runs)
        .into_par_iter()
        .map(|i| {
            cancel.check()?;
            let mut run = Run::new(
                scenario,
                filter,
                strategy,
                opts.seed,
                opts.first_run + i as u64,
                opts.record_every,
                None,
            )?;
            if opts.smooth {
                run.keep_for_smoother(scenario);
            }
            for k in 0..n_steps {
                if k % STEPS_PER_CHECK == 0 {
                    cancel.check()?;
                }
                run.step(scenario);
            }
            Ok(run.finish(scenario))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(McResult {
        runs,
        dvl_time: scenario.dvl_epoch_times(dvl_every),
        record_time: if opts.record_every > 0 {
            epoch_times(&scenario.truth, opts.record_every, true)
        } else {
            Vec::new()
        },
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::sensors::SensorConfig;
    use crate::threads::with_threads;
    use crate::trajectory::builtin;

    pub(crate) const TRUE_Q: [f64; 6] = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];

    pub(crate) fn short_scenario(seconds: f64) -> Arc<Scenario> {
        let mut spec = builtin("paper", 0.01).unwrap();
        let mut left = seconds;
        spec.segments.retain_mut(|s| {
            if left <= 0.0 {
                return false;
            }
            s.duration = s.duration.min(left);
            left -= s.duration;
            true
        });
        Arc::new(Scenario {
            truth: Arc::new(spec.generate().unwrap()),
            sensors: SensorConfig::paper(),
            sample_initial_error: true,
        })
    }

    /// Smoothing leaves the filter's records as they were and adds, per run, smoothed
    /// metrics shaped as the filter's and below them; the DVL calibration is refused.
    #[test]
    fn smoothing_adds_a_record_per_run_and_changes_no_forward_number() {
        let sc = short_scenario(60.0);
        let cfg = tuned_filter();
        let spec = StrategySpec::Constant { q: TRUE_Q };
        let opts = McOptions {
            n_runs: 6,
            seed: 2,
            record_every: 50,
            ..McOptions::default()
        };
        let plain = run_monte_carlo(&sc, &cfg, &spec, &opts).unwrap();
        let smooth = McOptions {
            smooth: true,
            ..opts
        };
        let both = run_monte_carlo(&sc, &cfg, &spec, &smooth).unwrap();
        let (mut forward, mut smoothed) = (0.0, 0.0);
        for (p, b) in plain.runs.iter().zip(&both.runs) {
            assert!(p.smoothed.is_none());
            assert_eq!(
                (&p.summary, &p.nis, &p.history),
                (&b.summary, &b.nis, &b.history)
            );
            let s = b.smoothed.as_ref().unwrap();
            assert_eq!(s.nees.len(), b.nees.len());
            let h = s.history.as_ref().unwrap();
            assert_eq!(h.error.len(), b.history.as_ref().unwrap().error.len());
            assert!(h.sigma.iter().flatten().all(|x| x.is_finite()));
            forward += b.summary.srmse;
            smoothed += s.srmse;
        }
        assert!(smoothed < 0.9 * forward, "{smoothed} vs {forward}");
        let calibrated = FilterConfig {
            dvl_calibration: Some(crate::ekf::calibration::CalibrationConfig::default()),
            ..cfg
        };
        // The 19-state filter is smoothed too, its forward numbers unchanged.
        let plain = run_monte_carlo(&sc, &calibrated, &spec, &opts).map_err(|e| e.to_string());
        let both = run_monte_carlo(&sc, &calibrated, &spec, &smooth).map_err(|e| e.to_string());
        let (plain, both) = (plain.unwrap(), both.unwrap());
        let (mut forward, mut smoothed) = (0.0, 0.0);
        for (p, b) in plain.runs.iter().zip(&both.runs) {
            assert!(p.summary == b.summary && p.nis == b.nis);
            forward += b.summary.srmse;
            smoothed += b.smoothed.as_ref().map_or(f64::NAN, |s| s.srmse);
        }
        assert!(smoothed < 0.9 * forward, "{smoothed} vs {forward}");
    }

    pub(crate) fn tuned_filter() -> FilterConfig {
        FilterConfig {
            accel_bias_psd: 1e-10,
            gyro_bias_psd: 1e-14,
            ..FilterConfig::default()
        }
    }

    #[test]
    fn a_monte_carlo_too_big_for_memory_is_refused_before_it_allocates() {
        let sc = short_scenario(30.0);
        let dvl_every = sc.dvl_every().unwrap();
        let opts = |n_runs, record_every| McOptions {
            n_runs,
            seed: 0,
            record_every,
            first_run: 0,
            smooth: false,
        };
        assert!(check_result_size(&sc, &opts(1000, 100), dvl_every, 0).is_ok());
        // A trillion runs: refused at once (the runs would take petabytes).
        let err = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts(1_000_000_000_000, 0),
        )
        .unwrap_err()
        .to_string();
        assert!(err.starts_with("n_runs: 1000000000000 runs of this scenario would hold "));
        assert!(err.contains("GiB per call (here about "), "{err}");
        // The limit is on bytes: recording every step makes fewer runs fit.
        let fits = |n, every| check_result_size(&sc, &opts(n, every), dvl_every, 0).is_ok();
        assert!(fits(100_000, 0) && !fits(100_000, 1));
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        let sc = short_scenario(30.0);
        let opts = McOptions {
            n_runs: 6,
            seed: 42,
            record_every: 50,
            first_run: 0,
            smooth: false,
        };
        let strat = StrategySpec::Mehra {
            window: 3,
            prior_q: TRUE_Q,
        };
        let one = with_threads(Some(1), || {
            run_monte_carlo(&sc, &tuned_filter(), &strat, &opts)
        })
        .unwrap()
        .unwrap();
        let two = with_threads(Some(2), || {
            run_monte_carlo(&sc, &tuned_filter(), &strat, &opts)
        })
        .unwrap()
        .unwrap();
        // Debug output prints every f64 exactly (shortest round trip) and NaN as NaN, so
        // equal text means bit-identical numbers.
        assert_eq!(format!("{one:?}"), format!("{two:?}"));
        // A run's numbers do not depend on the batch it is in.
        let three = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &strat,
            &McOptions { n_runs: 3, ..opts },
        )
        .unwrap();
        assert_eq!(format!("{:?}", three.runs), format!("{:?}", &one.runs[..3]));
        // Run indices stop short of wrapping onto other runs' random streams.
        for (first_run, n_runs) in [(MAX_RUN_INDEX, 1), (u64::MAX, 2), (MAX_RUN_INDEX - 1, 2)] {
            let bad = McOptions {
                n_runs,
                first_run,
                ..opts
            };
            assert!(bad.validate().is_err(), "{first_run} + {n_runs} accepted");
        }
        assert!(McOptions {
            n_runs: 1,
            first_run: MAX_RUN_INDEX - 1,
            ..opts
        }
        .validate()
        .is_ok());
        // Nor on the shard: runs 3..6 computed apart are runs 3..6 of the whole.
        let last_three = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &strat,
            &McOptions {
                n_runs: 3,
                first_run: 3,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(
            format!("{:?}", last_three.runs),
            format!("{:?}", &one.runs[3..])
        );
        assert_eq!(one.dvl_time.len(), 30);
        assert_eq!(one.record_time.len(), 61);
    }

    #[test]
    fn an_external_strategy_is_refused_and_no_update_means_no_mean_nis() {
        let sc = short_scenario(5.0);
        let opts = McOptions {
            n_runs: 2,
            seed: 1,
            record_every: 0,
            first_run: 0,
            smooth: false,
        };
        let external = StrategySpec::External { prior_q: TRUE_Q };
        let err = run_monte_carlo(&sc, &tuned_filter(), &external, &opts).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("strategy: an external strategy"),
            "{err}"
        );
        // A DVL period longer than the run: not one update, so the mean NIS is undefined.
        let mut quiet = (*sc).clone();
        quiet.sensors.dvl.period = 10.0;
        let constant = StrategySpec::Constant { q: TRUE_Q };
        let res = run_monte_carlo(&Arc::new(quiet), &tuned_filter(), &constant, &opts).unwrap();
        assert!(res.dvl_time.is_empty());
        assert!(res.runs.iter().all(|r| r.summary.mean_nis.is_nan()));
        assert!(res.runs.iter().all(|r| r.summary.srmse.is_finite()));
    }

    #[test]
    fn dvl_aiding_bounds_the_velocity_error() {
        let sc = short_scenario(60.0);
        let opts = McOptions {
            n_runs: 4,
            seed: 1,
            record_every: 0,
            first_run: 0,
            smooth: false,
        };
        let res = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap();
        for r in &res.runs {
            assert!(r.summary.failure.is_none());
            assert!(r.summary.srmse < 0.1, "srmse {}", r.summary.srmse);
            assert_eq!(r.nis.len(), 60);
        }
        // Without DVL (a period longer than the run) the same filter drifts far more.
        let mut free = (*sc).clone();
        free.sensors.dvl.period = 100.0;
        let free = run_monte_carlo(
            &Arc::new(free),
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap();
        let aided: f64 = res
            .runs
            .iter()
            .map(|r| r.summary.final_horizontal_error)
            .sum();
        let unaided: f64 = free
            .runs
            .iter()
            .map(|r| r.summary.final_horizontal_error)
            .sum();
        assert!(unaided > aided, "aided {aided} unaided {unaided}");
    }

    #[test]
    fn a_dvl_dropout_misses_updates_on_any_thread_count_and_unset_changes_nothing() {
        let plain = short_scenario(60.0);
        let mut lossy = (*plain).clone();
        lossy.sensors.dvl.dropout = Some(crate::sensors::DvlDropout {
            mean_interval: 15.0,
            mean_length: 5.0,
        });
        let opts = McOptions {
            n_runs: 4,
            seed: 3,
            record_every: 0,
            first_run: 0,
            smooth: false,
        };
        let strat = StrategySpec::Constant { q: TRUE_Q };
        let lossy = Arc::new(lossy);
        let run = |sc: &Arc<Scenario>, threads| {
            with_threads(Some(threads), || {
                run_monte_carlo(sc, &tuned_filter(), &strat, &opts)
            })
            .unwrap()
            .unwrap()
        };
        let (one, two) = (run(&lossy, 1), run(&lossy, 2));
        assert_eq!(format!("{one:?}"), format!("{two:?}"));
        for r in &one.runs {
            let lost = r.nis.iter().filter(|v| v.is_nan()).count();
            assert!(lost > 0 && lost == r.summary.missed_updates, "{lost}");
            assert_eq!(r.nis.len(), one.dvl_time.len());
            assert!(r.summary.mean_nis.is_finite());
        }
        // unset: no missed update, and the scenario without the field set is the paper's
        let base = run(&plain, 1);
        assert!(base.runs.iter().all(|r| r.summary.missed_updates == 0));
        assert!(base
            .runs
            .iter()
            .all(|r| r.nis.iter().all(|v| v.is_finite())));
    }

    #[test]
    fn bad_dvl_period_is_rejected() {
        let mut sc = (*short_scenario(5.0)).clone();
        sc.sensors.dvl.period = 0.015;
        let opts = McOptions {
            n_runs: 1,
            seed: 0,
            record_every: 0,
            first_run: 0,
            smooth: false,
        };
        let err = run_monte_carlo(
            &Arc::new(sc),
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("dvl_period"), "{err}");
    }
}
