//! The memory estimates the calls check before they allocate (`pronet::memory`) against
//! what they allocate: every test runs a call under a counting allocator and asserts
//! that its estimate is at least the most it held at once, and not far above it.
//!
//! An estimate counts what the call would hold at the peak, the arrays made from the
//! output too (the Python binding's); these tests see the core's allocations only, and
//! compare them with the estimate's other parts.

use nalgebra::Vector3;
use pronet::cancel::Cancel;
use pronet::ekf::calibration::CalibrationConfig;
use pronet::ekf::FilterConfig;
use pronet::ensemble::Ensemble;
use pronet::mechanization::{mechanize, memory, NavState};
use pronet::montecarlo::{run_monte_carlo, McOptions, MC_BYTES};
use pronet::noise::StrategySpec;
use pronet::recorded::{estimate_memory, filter_recorded_until, smooth_recorded_until};
use pronet::recorded::{Epochs, RecordedData, Stream};
use pronet::run::RunMemory;
use pronet::scenario::Scenario;
use pronet::sensors::SensorConfig;
use pronet::threads::with_threads;
use pronet::trajectory::{Segment, TrajectorySpec, Truth};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex};

/// The most an estimate may be above the measured peak.
const ABOVE: f64 = 1.25;

struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed on to the system allocator unchanged; only counted.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = NOW.fetch_add(layout.size(), Relaxed) + layout.size();
            PEAK.fetch_max(now, Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        NOW.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            NOW.fetch_sub(layout.size(), Relaxed);
            let now = NOW.fetch_add(new_size, Relaxed) + new_size;
            PEAK.fetch_max(now, Relaxed);
        }
        p
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// One measurement at a time: the counters are the process's.
static ONE: Mutex<()> = Mutex::new(());

/// The most `f` holds at once above what was held before it \[bytes\], and its value.
fn peak<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let before = NOW.load(Relaxed);
    PEAK.store(before, Relaxed);
    let out = f();
    ((PEAK.load(Relaxed) - before) as f64, out)
}

/// Assert that `estimate` is at least `measured` and at most [`ABOVE`] times it.
fn close(label: &str, estimate: f64, measured: f64) {
    let ratio = estimate / measured;
    eprintln!("{label}: estimate {estimate:.0} B, peak {measured:.0} B, {ratio:.2}x");
    assert!(
        (1.0..=ABOVE).contains(&ratio),
        "{label}: the estimate {estimate:.0} B is {ratio:.2} times the peak {measured:.0} B"
    );
}

/// A turning, diving survey of `minutes` at 100 Hz.
fn truth(minutes: usize) -> Truth {
    let legs = (0..minutes)
        .map(|i| Segment::new(60.0, 0.0, 0.02 * (-1f64).powi(i as i32), 0.0))
        .collect();
    TrajectorySpec {
        name: "survey".into(),
        lla0: Vector3::new(0.55, 0.6, -5.0),
        speed0: 1.5,
        rpy0: Vector3::zeros(),
        segments: legs,
        dt: 0.01,
    }
    .generate()
    .unwrap()
}

/// The truth's body-frame velocity every `every` IMU samples, and their times.
fn dvl(truth: &Truth, every: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    (every..=truth.len())
        .step_by(every)
        .map(|k| {
            let s = &truth.states[k];
            let body = s.dcm.transpose() * s.vel;
            ([body[0], body[1], body[2]], truth.time[k])
        })
        .unzip()
}

/// A filter's configuration and strategy.
type Filter<'a> = (&'a FilterConfig, &'a StrategySpec);
/// The epochs a pass keeps, and whether it is smoothed.
type Kept = (Epochs, bool);

const Q: [f64; 6] = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];

/// A pass over `truth` (its DVL every `every` samples, or none), as `run_filter` runs
/// it: its estimate and peak.
fn pass(
    truth: &Truth,
    every: Option<usize>,
    (cfg, spec): Filter<'_>,
    (epochs, smooth): Kept,
    covariance_time: &[f64],
) -> (f64, f64) {
    let (rows, times) = every.map_or((Vec::new(), Vec::new()), |e| dvl(truth, e));
    let imu_time = &truth.time[1..];
    let streams = match every {
        Some(_) => vec![Stream::dvl(&rows, &times, cfg)],
        None => Vec::new(),
    };
    let data = RecordedData {
        imu: &truth.imu,
        imu_time,
        t0: 0.0,
        streams,
        covariance_time,
        ..RecordedData::default()
    };
    let initial: NavState = truth.states[0];
    let mut strategy = spec.build(cfg.bias_psd());
    let discrete = strategy.sets_discrete_q();
    let memory = estimate_memory(&data, epochs, cfg, smooth, discrete);
    // The core's share: the output and the smoother's working memory.
    let estimate = memory.output.bytes() + memory.working.bytes();
    let cancel = Cancel::default();
    let (measured, out) = peak(|| {
        if smooth {
            smooth_recorded_until(
                &data,
                initial,
                [0.0; 6],
                cfg,
                strategy.as_mut(),
                epochs,
                &cancel,
            )
        } else {
            filter_recorded_until(
                &data,
                initial,
                [0.0; 6],
                cfg,
                strategy.as_mut(),
                epochs,
                &cancel,
            )
        }
    });
    out.unwrap();
    (estimate, measured)
}

fn constant() -> StrategySpec {
    StrategySpec::Constant { q: Q }
}

#[test]
fn a_recorded_pass_holds_what_its_estimate_says() {
    let _one = ONE.lock().unwrap_or_else(|e| e.into_inner());
    let truth = truth(20);
    let cfg = FilterConfig::default();
    let every_sample = FilterConfig {
        covariance_step: 0.01,
        ..FilterConfig::default()
    };
    let calibrated = FilterConfig {
        dvl_calibration: Some(CalibrationConfig::default()),
        ..FilterConfig::default()
    };
    let mehra = StrategySpec::Mehra {
        window: 5,
        prior_q: Q,
    };
    let c = constant();
    let cases: [(&str, Option<usize>, Filter, Kept); 7] = [
        ("forward", Some(20), (&cfg, &c), (Epochs::All, false)),
        (
            "forward, output_step",
            Some(20),
            (&cfg, &c),
            (Epochs::Step(1.0), false),
        ),
        ("smoothed", Some(20), (&cfg, &c), (Epochs::All, true)),
        (
            "smoothed at every sample",
            Some(20),
            (&every_sample, &c),
            (Epochs::All, true),
        ),
        (
            "smoothed, output_step",
            Some(20),
            (&cfg, &c),
            (Epochs::Step(1.0), true),
        ),
        (
            "smoothed, Mehra",
            Some(20),
            (&cfg, &mehra),
            (Epochs::All, true),
        ),
        (
            "smoothed, calibrated",
            Some(20),
            (&calibrated, &c),
            (Epochs::All, true),
        ),
    ];
    for (label, every, filter, epochs) in cases {
        let (estimate, measured) = pass(&truth, every, filter, epochs, &[]);
        close(label, estimate, measured);
    }
    // Without a reading the smoother holds the whole pass at once.
    let short = self::truth(3);
    let pure = (&every_sample, &c);
    let (estimate, measured) = pass(&short, None, pure, (Epochs::All, true), &[]);
    close("smoothed, pure inertial", estimate, measured);
    let asked: Vec<f64> = (0..100_000).map(|k| k as f64 * 0.012).collect();
    let (estimate, measured) = pass(&truth, Some(20), (&cfg, &c), (Epochs::Last, false), &asked);
    close("covariance_time", estimate, measured);
}

/// A Monte Carlo of `n_runs` on one thread over `truth` (a DVL at `dvl_period` s, an
/// outage): what [`RunMemory`] says its core holds (the records of every run, one run
/// under way), and its peak.
fn monte_carlo(
    truth: &Arc<Truth>,
    (cfg, spec): Filter<'_>,
    (n_runs, record_every, smooth): (usize, usize, bool),
) -> (f64, f64) {
    let mut sensors = SensorConfig::paper();
    sensors.dvl.period = 0.2;
    sensors.dvl.outages = vec![[300.0, 330.0]];
    let scenario = Arc::new(Scenario {
        truth: Arc::clone(truth),
        sensors,
        sample_initial_error: true,
    });
    let opts = McOptions {
        n_runs,
        seed: 7,
        record_every,
        first_run: 0,
        smooth,
    };
    let dvl_every = scenario.dvl_every().unwrap();
    let discrete = spec.build(cfg.bias_psd()).sets_discrete_q();
    let run = RunMemory::of(
        &scenario,
        cfg,
        (dvl_every, record_every, 0),
        (smooth, discrete),
    );
    let records = n_runs as f64 * (run.epochs + run.histories);
    let estimate = records + run.running + run.smoother + MC_BYTES;
    let (measured, out) =
        peak(|| with_threads(Some(1), || run_monte_carlo(&scenario, cfg, spec, &opts)).unwrap());
    let out = out.unwrap();
    assert!(out.runs.iter().all(|r| r.summary.failure.is_none()));
    (estimate, measured)
}

#[test]
fn a_monte_carlo_holds_what_its_estimate_says() {
    let _one = ONE.lock().unwrap_or_else(|e| e.into_inner());
    let truth = Arc::new(truth(10));
    let cfg = FilterConfig {
        accel_bias_psd: 1e-10,
        gyro_bias_psd: 1e-14,
        ..FilterConfig::default()
    };
    let every_sample = FilterConfig {
        covariance_step: 0.01,
        ..cfg.clone()
    };
    let calibrated = FilterConfig {
        dvl_calibration: Some(CalibrationConfig::default()),
        ..cfg.clone()
    };
    let mehra = StrategySpec::Mehra {
        window: 5,
        prior_q: Q,
    };
    let c = constant();
    let cases: [(&str, Filter, (usize, usize, bool)); 6] = [
        ("forward, histories", (&cfg, &c), (20, 10, false)),
        ("smoothed", (&cfg, &c), (1, 0, true)),
        ("smoothed, histories", (&cfg, &c), (2, 100, true)),
        (
            "smoothed at every sample",
            (&every_sample, &c),
            (1, 0, true),
        ),
        ("smoothed, calibrated", (&calibrated, &c), (1, 0, true)),
        (
            "smoothed at every sample, Mehra",
            (&every_sample, &mehra),
            (1, 0, true),
        ),
    ];
    for (label, filter, sizes) in cases {
        let (estimate, measured) = monte_carlo(&truth, filter, sizes);
        close(label, estimate, measured);
    }
}

#[test]
fn a_trajectory_a_mechanization_and_an_ensemble_hold_what_their_estimates_say() {
    let _one = ONE.lock().unwrap_or_else(|e| e.into_inner());
    let (measured, made) = peak(|| truth(10));
    close("trajectory", Truth::memory(made.len()).bytes(), measured);
    // The estimate counts the states' arrays too (72 bytes each), not made here.
    let (measured, states) = peak(|| mechanize(&made.states[0], &made.imu, made.dt).unwrap());
    let arrays = 72.0 * states.len() as f64;
    close(
        "mechanization",
        memory(made.len()).bytes() - arrays,
        measured,
    );
    let scenario = Arc::new(Scenario {
        truth: Arc::new(made),
        sensors: SensorConfig::paper(),
        sample_initial_error: true,
    });
    let opts = McOptions {
        n_runs: 50,
        seed: 1,
        record_every: 100,
        first_run: 0,
        smooth: false,
    };
    let cfg = FilterConfig::default();
    let dvl_every = scenario.dvl_every().unwrap();
    let window = 200;
    let run = RunMemory::of(&scenario, &cfg, (dvl_every, 100, window), (false, false));
    // Records once (no arrays made here), every run under way.
    let estimate = 50.0 * (run.epochs + run.histories + run.running);
    let (measured, ensemble) = peak(|| Ensemble::new(scenario, &cfg, Q, &opts, window, 1.0));
    ensemble.unwrap();
    close("ensemble", estimate, measured);
}
