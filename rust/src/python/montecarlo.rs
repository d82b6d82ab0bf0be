//! `monte_carlo` and the result dict it shares with `Ensemble.finish`.

use super::call::{interruptible, to_py_err};
use super::config::PyFilterConfig;
use super::convert::{
    arg_first_run, arg_n_runs, arg_record_every, arg_sample_initial_error, arg_seed, arg_smooth,
    arg_threads,
};
use super::sensors::PySensorConfig;
use super::strategy::PyStrategy;
use super::trajectory::PyTrajectory;
use crate::montecarlo::{
    check_result_size, run_monte_carlo_until, History, McOptions, McResult, RunSummary,
};
use crate::run::SmoothedRecord;
use crate::scenario::Scenario;
use crate::threads::{check_threads, default_threads, max_threads, with_threads};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

pub(super) fn scenario(
    trajectory: &PyTrajectory,
    sensors: &PySensorConfig,
    sample_initial_error: bool,
) -> Arc<Scenario> {
    Arc::new(Scenario {
        truth: Arc::clone(&trajectory.truth),
        sensors: sensors.inner.clone(),
        sample_initial_error,
    })
}

pub(super) fn result_dict<'py>(py: Python<'py>, res: &McResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = res.runs.len();
    let col = |f: &dyn Fn(&RunSummary) -> f64| {
        Array1::from_iter(res.runs.iter().map(|r| f(&r.summary))).into_pyarray(py)
    };
    d.set_item("srmse", col(&|s| s.srmse))?;
    d.set_item("smae", col(&|s| s.smae))?;
    d.set_item("final_horizontal_error", col(&|s| s.final_horizontal_error))?;
    d.set_item("max_horizontal_error", col(&|s| s.max_horizontal_error))?;
    d.set_item("mean_nis", col(&|s| s.mean_nis))?;
    d.set_item(
        "rejected_updates",
        Array1::from_iter(res.runs.iter().map(|r| r.summary.rejected_updates as i64))
            .into_pyarray(py),
    )?;
    d.set_item(
        "missed_updates",
        Array1::from_iter(res.runs.iter().map(|r| r.summary.missed_updates as i64))
            .into_pyarray(py),
    )?;
    d.set_item(
        "depth_updates",
        Array1::from_iter(res.runs.iter().map(|r| r.summary.depth_updates as i64)).into_pyarray(py),
    )?;
    d.set_item(
        "fix_updates",
        Array1::from_iter(res.runs.iter().map(|r| r.summary.fix_updates as i64)).into_pyarray(py),
    )?;
    // NaN without any depth or fix update
    d.set_item(
        "mean_aiding_nis",
        col(&|s| s.aiding_nis / s.aiding_dof as f64),
    )?;
    d.set_item("diverged_at", col(&|s| s.diverged_at.unwrap_or(f64::NAN)))?;
    let failures: Vec<Option<String>> =
        res.runs.iter().map(|r| r.summary.failure.clone()).collect();
    d.set_item("failure", failures)?;
    let m = res.dvl_time.len();
    d.set_item("dvl_time", res.dvl_time.clone().into_pyarray(py))?;
    // Failed runs stop early: pad their epoch series with NaN.
    d.set_item(
        "nis",
        Array2::from_shape_fn((n, m), |(i, k)| {
            res.runs[i].nis.get(k).copied().unwrap_or(f64::NAN)
        })
        .into_pyarray(py),
    )?;
    d.set_item(
        "nees",
        Array3::from_shape_fn((n, m, 5), |(i, k, b)| {
            res.runs[i].nees.get(k).map_or(f64::NAN, |e| e[b])
        })
        .into_pyarray(py),
    )?;
    if !res.record_time.is_empty() {
        history_arrays(py, &d, res)?;
    }
    if res.runs.iter().any(|r| !r.calibration_nees.is_empty()) {
        calibration_arrays(py, &d, res)?;
    }
    if res.runs.iter().any(|r| r.smoothed.is_some()) {
        d.set_item("smoothed", smoothed_dict(py, res)?)?;
    }
    Ok(d)
}

/// The smoothed runs' metrics, NEES and histories, shaped as the forward ones (NaN
/// where a run has none: its filter failed).
fn smoothed_dict<'py>(py: Python<'py>, res: &McResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let (n, m, r) = (res.runs.len(), res.dvl_time.len(), res.record_time.len());
    let smoothed = |i: usize| res.runs[i].smoothed.as_ref();
    let col = |f: &dyn Fn(&SmoothedRecord) -> f64| {
        Array1::from_iter((0..n).map(|i| smoothed(i).map_or(f64::NAN, f))).into_pyarray(py)
    };
    d.set_item("srmse", col(&|s| s.srmse))?;
    d.set_item("smae", col(&|s| s.smae))?;
    d.set_item("final_horizontal_error", col(&|s| s.final_horizontal_error))?;
    d.set_item("max_horizontal_error", col(&|s| s.max_horizontal_error))?;
    d.set_item(
        "nees",
        Array3::from_shape_fn((n, m, 5), |(i, k, b)| {
            smoothed(i)
                .and_then(|s| s.nees.get(k))
                .map_or(f64::NAN, |e| e[b])
        })
        .into_pyarray(py),
    )?;
    if r > 0 {
        let history = |i: usize| smoothed(i).and_then(|s| s.history.as_ref());
        series(py, &d, "error", res, &history, &|h| &h.error)?;
        series(py, &d, "sigma", res, &history, &|h| &h.sigma)?;
    }
    Ok(d)
}

/// The DVL calibration states' final error and 1σ `(n, 4)` and NEES `(n, m)` (NaN
/// where a run has none: it failed).
fn calibration_arrays<'py>(
    py: Python<'py>,
    d: &Bound<'py, PyDict>,
    res: &McResult,
) -> PyResult<()> {
    let (n, m) = (res.runs.len(), res.dvl_time.len());
    let summary = |i: usize| res.runs[i].summary.calibration;
    d.set_item(
        "calibration_error",
        Array2::from_shape_fn((n, 4), |(i, j)| summary(i).map_or(f64::NAN, |c| c.error[j]))
            .into_pyarray(py),
    )?;
    d.set_item(
        "calibration_sigma",
        Array2::from_shape_fn((n, 4), |(i, j)| summary(i).map_or(f64::NAN, |c| c.sigma[j]))
            .into_pyarray(py),
    )?;
    d.set_item(
        "calibration_nees",
        Array2::from_shape_fn((n, m), |(i, k)| {
            res.runs[i]
                .calibration_nees
                .get(k)
                .copied()
                .unwrap_or(f64::NAN)
        })
        .into_pyarray(py),
    )?;
    Ok(())
}

/// `record_time` and the `error`, `sigma` and `q` histories (NaN where a run has none).
fn history_arrays<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, res: &McResult) -> PyResult<()> {
    d.set_item("record_time", res.record_time.clone().into_pyarray(py))?;
    let history = |i: usize| res.runs[i].history.as_ref();
    series(py, d, "error", res, &history, &|h| &h.error)?;
    series(py, d, "sigma", res, &history, &|h| &h.sigma)?;
    series(py, d, "q", res, &history, &|h| &h.imu_variance)
}

/// `d[key]`: the `(n_runs, r, N)` array of one history series, `pick(history(i))` for
/// run i (NaN where a run has none, or its series ends early).
fn series<'py, 'r, const N: usize>(
    py: Python<'py>,
    d: &Bound<'py, PyDict>,
    key: &str,
    res: &'r McResult,
    history: &dyn Fn(usize) -> Option<&'r History>,
    pick: &dyn Fn(&History) -> &Vec<[f64; N]>,
) -> PyResult<()> {
    let (n, r) = (res.runs.len(), res.record_time.len());
    let at = |i: usize, k: usize, s: usize| {
        history(i)
            .and_then(|h| pick(h).get(k))
            .map_or(f64::NAN, |e| e[s])
    };
    d.set_item(
        key,
        Array3::from_shape_fn((n, r, N), |(i, k, s)| at(i, k, s)).into_pyarray(py),
    )
}

/// A Monte Carlo; see :class:`pronet.MonteCarloResult` for the keys. ``n_runs`` >= 1,
/// ``first_run + n_runs`` <= :data:`MAX_RUN_INDEX`, ``threads`` 1 to :func:`max_threads`
/// (None: :func:`check_threads`'s default). An external strategy is refused: nothing
/// sets its q here. ``smooth``: also the RTS smoother's metrics of every run (key
/// ``smoothed``: ``srmse``, ``smae``, ``final_horizontal_error``,
/// ``max_horizontal_error``, ``nees`` and, with ``record_every``, ``error`` and
/// ``sigma``). Before it allocates, one that would hold more than this process can still
/// take (the records and their arrays, the runs under way and their smoothers) is a
/// ``ValueError`` naming ``n_runs``, ``record_every`` or ``smooth`` (docs/results/performance.md,
/// "Memory").
#[pyfunction(name = "monte_carlo")]
#[pyo3(signature = (trajectory, sensors, config, strategy, *, n_runs, seed = 0, record_every = 0, sample_initial_error = true, threads = None, first_run = 0, smooth = false))]
#[allow(clippy::too_many_arguments)]
fn py_monte_carlo<'py>(
    py: Python<'py>,
    trajectory: &PyTrajectory,
    sensors: &PySensorConfig,
    config: &PyFilterConfig,
    strategy: &PyStrategy,
    #[pyo3(from_py_with = arg_n_runs)] n_runs: usize,
    #[pyo3(from_py_with = arg_seed)] seed: u64,
    #[pyo3(from_py_with = arg_record_every)] record_every: usize,
    #[pyo3(from_py_with = arg_sample_initial_error)] sample_initial_error: bool,
    #[pyo3(from_py_with = arg_threads)] threads: Option<usize>,
    #[pyo3(from_py_with = arg_first_run)] first_run: u64,
    #[pyo3(from_py_with = arg_smooth)] smooth: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = McOptions {
        n_runs,
        seed,
        record_every,
        first_run,
        smooth,
    };
    let sc = scenario(trajectory, sensors, sample_initial_error);
    let (cfg, spec) = (config.inner.clone(), strategy.inner.clone());
    let res = interruptible(py, move |cancel| {
        opts.validate()?;
        with_threads(threads, || {
            run_monte_carlo_until(&sc, &cfg, &spec, &opts, cancel)
        })?
    })?;
    result_dict(py, &res)
}

/// ``ValueError`` naming ``n_runs`` if the records of ``n_runs`` runs of
/// ``trajectory`` would exceed the core's memory limit (4 GiB), as :func:`monte_carlo`
/// checks before it allocates; nothing is run.
#[pyfunction(name = "check_result_size")]
#[pyo3(signature = (trajectory, sensors, *, n_runs, record_every = 0))]
fn py_check_result_size(
    trajectory: &PyTrajectory,
    sensors: &PySensorConfig,
    #[pyo3(from_py_with = arg_n_runs)] n_runs: usize,
    #[pyo3(from_py_with = arg_record_every)] record_every: usize,
) -> PyResult<()> {
    let sc = scenario(trajectory, sensors, true);
    let opts = McOptions {
        n_runs,
        seed: 0,
        record_every,
        first_run: 0,
        smooth: false,
    };
    let dvl_every = sc.dvl_every().map_err(to_py_err)?;
    check_result_size(&sc, &opts, dvl_every, 0).map_err(to_py_err)
}

/// ``ValueError`` naming ``fixes[j]`` (or its ``max_depth``) if fix source ``j`` of
/// ``sensors`` takes no fix on ``trajectory``: none of its scheduled epochs falls inside
/// it, or none comes at a true depth of at most its ``max_depth``. :func:`monte_carlo`
/// runs such a source (``fix_updates`` counts the fixes taken); a scenario file is
/// refused with it (:func:`pronet.config.load_scenario`).
#[pyfunction(name = "check_fixes_fire")]
fn py_check_fixes_fire(trajectory: &PyTrajectory, sensors: &PySensorConfig) -> PyResult<()> {
    let sc = scenario(trajectory, sensors, true);
    sc.dvl_every().map_err(to_py_err)?;
    sc.check_fixes_fire().map_err(to_py_err)
}

/// The thread count a call given ``threads`` runs on: ``threads`` itself if it is 1
/// to :func:`max_threads` (else ``ValueError`` naming ``threads``); for None,
/// ``RAYON_NUM_THREADS`` if set (checked the same way, the error naming the variable),
/// else one per usable core.
#[pyfunction(name = "check_threads")]
#[pyo3(signature = (threads = None))]
fn py_check_threads(#[pyo3(from_py_with = arg_threads)] threads: Option<usize>) -> PyResult<usize> {
    match threads {
        Some(n) => check_threads("threads", n),
        None => default_threads(),
    }
    .map_err(to_py_err)
}

/// The most threads a pool may have here: :data:`THREADS_PER_CORE` per usable core,
/// at most :data:`MAX_THREADS`.
#[pyfunction(name = "max_threads")]
fn py_max_threads() -> usize {
    max_threads()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(py_monte_carlo, m)?)?;
    m.add_function(wrap_pyfunction!(py_check_threads, m)?)?;
    m.add_function(wrap_pyfunction!(py_max_threads, m)?)?;
    m.add_function(wrap_pyfunction!(py_check_result_size, m)?)?;
    m.add_function(wrap_pyfunction!(py_check_fixes_fire, m)?)
}
