//! `Ensemble` (lockstep runs for outside tuning) and `tuning_instants`, the rule it
//! shares with the hybrid loop on recorded data.

use super::call::{detached, interruptible, invalid};
use super::config::PyFilterConfig;
use super::convert::{
    arg_dt, arg_first_run, arg_n_runs, arg_n_samples, arg_record_every, arg_sample_initial_error,
    arg_seed, arg_smooth, arg_threads, arg_tuning_period, arg_window, fixed, rows,
};
use super::montecarlo::{result_dict, scenario};
use super::sensors::PySensorConfig;
use super::trajectory::PyTrajectory;
use crate::cancel::Cancel;
use crate::ensemble::{Ensemble, TuningSchedule};
use crate::error::Error;
use crate::montecarlo::McOptions;
use crate::threads::Workers;
use crate::Result as CoreResult;
use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::{Arc, Mutex};

/// All runs of a Monte Carlo stepped in lockstep for outside tuning.
///
/// ``advance()`` steps every run to the next tuning instant (see
/// :func:`tuning_instants`; ``window`` 1 to the trajectory's length) and returns the
/// last ``window`` raw IMU samples of every run, float32 ``(n_runs, 6, window)`` oldest
/// first, or None at the end; ``set_q(q)`` with ``q`` ``(n_runs, 6)`` sets each
/// run's IMU variances. Until the first ``set_q`` every run uses ``prior_q``.
/// ``advance`` and ``finish`` end within a fraction of a second on Ctrl-C or SIGTERM
/// (KeyboardInterrupt); the ensemble is then unusable (ValueError). ``smooth``: as
/// :func:`monte_carlo`'s; so is the memory check before it allocates (every run is
/// under way at once).
#[pyclass(name = "Ensemble", module = "pronet._core")]
pub struct PyEnsemble {
    inner: Arc<Mutex<Option<Ensemble>>>,
    workers: Workers,
    n_runs: usize,
    window: usize,
}

fn poisoned<T>(_: T) -> Error {
    Error::Numerical("ensemble state poisoned by an earlier failure".into())
}

impl PyEnsemble {
    /// `f` on the ensemble without the GIL; with `long`, ended by Ctrl-C or SIGTERM
    /// within a fraction of a second ([`interruptible`]), and an interrupted ensemble is
    /// dropped, since its runs were left at different steps. Quick calls (`set_q`, the
    /// getters) skip the signal wait and its extra thread.
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        long: bool,
        f: impl FnOnce(&mut Ensemble, &Cancel) -> CoreResult<T> + Send,
    ) -> PyResult<T> {
        let inner = Arc::clone(&self.inner);
        let workers = self.workers.clone();
        let call = move |cancel: &Cancel| {
            let mut guard = inner.lock().map_err(poisoned)?;
            let ens = guard.as_mut().ok_or_else(|| {
                Error::invalid(
                    "ensemble",
                    "already finished or interrupted; create a new Ensemble",
                )
            })?;
            let out = workers.run(|| f(ens, cancel));
            if cancel.is_cancelled() {
                guard.take();
            }
            out
        };
        if long {
            interruptible(py, call)
        } else {
            detached(py, move || call(&Cancel::default()))
        }
    }
}

#[pymethods]
impl PyEnsemble {
    #[new]
    #[pyo3(signature = (trajectory, sensors, config, prior_q, *, n_runs, seed = 0, window = 200, tuning_period = 1.0, record_every = 0, sample_initial_error = true, threads = None, first_run = 0, smooth = false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        trajectory: &PyTrajectory,
        sensors: &PySensorConfig,
        config: &PyFilterConfig,
        prior_q: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arg_n_runs)] n_runs: usize,
        #[pyo3(from_py_with = arg_seed)] seed: u64,
        #[pyo3(from_py_with = arg_window)] window: usize,
        #[pyo3(from_py_with = arg_tuning_period)] tuning_period: f64,
        #[pyo3(from_py_with = arg_record_every)] record_every: usize,
        #[pyo3(from_py_with = arg_sample_initial_error)] sample_initial_error: bool,
        #[pyo3(from_py_with = arg_threads)] threads: Option<usize>,
        #[pyo3(from_py_with = arg_first_run)] first_run: u64,
        #[pyo3(from_py_with = arg_smooth)] smooth: bool,
    ) -> PyResult<Self> {
        let prior_q = fixed::<6>(prior_q, "prior_q")?;
        let opts = McOptions {
            n_runs,
            seed,
            record_every,
            first_run,
            smooth,
        };
        let sc = scenario(trajectory, sensors, sample_initial_error);
        let cfg = config.inner.clone();
        let (ens, workers) = detached(py, move || {
            opts.validate()?;
            let workers = Workers::new(threads)?;
            let ens = Ensemble::new(sc, &cfg, prior_q, &opts, window, tuning_period)?;
            Ok((ens, workers))
        })?;
        Ok(Self {
            inner: Arc::new(Mutex::new(Some(ens))),
            workers,
            n_runs,
            window,
        })
    }

    /// Step all runs to the next tuning instant; the windows ``(n_runs, 6, window)``
    /// float32, oldest sample first, or None at the end.
    fn advance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray3<f32>>>> {
        let Some(flat) = self.with(py, true, |e, cancel| e.advance_until(cancel))? else {
            return Ok(None);
        };
        let windows = Array3::from_shape_vec((self.n_runs, 6, self.window), flat)
            .map_err(|e| invalid("ensemble", format!("windows of the wrong size: {e}")))?;
        Ok(Some(windows.into_pyarray(py)))
    }

    /// Set each run's IMU variances: ``q`` ``(n_runs, 6)``.
    fn set_q(&self, py: Python<'_>, q: &Bound<'_, PyAny>) -> PyResult<()> {
        let q = rows::<6>(q, "q")?;
        self.with(py, false, move |e, _| e.set_q(&q))
    }

    /// Run to the end; the results as :func:`monte_carlo` returns them. The
    /// ensemble cannot be used afterwards.
    fn finish<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = Arc::clone(&self.inner);
        let workers = self.workers.clone();
        let res = interruptible(py, move |cancel| {
            let ens = inner
                .lock()
                .map_err(poisoned)?
                .take()
                .ok_or_else(|| Error::invalid("ensemble", "already finished or interrupted"))?;
            workers.run(|| ens.finish_until(cancel))
        })?;
        result_dict(py, &res)
    }

    #[getter]
    fn n_runs(&self) -> usize {
        self.n_runs
    }
    #[getter]
    fn window(&self) -> usize {
        self.window
    }
    /// IMU steps taken so far.
    #[getter]
    fn steps(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, false, |e, _| Ok(e.steps()))
    }
    /// Current time [s].
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, false, |e, _| Ok(e.time()))
    }
    #[getter]
    fn done(&self) -> bool {
        // A quick lock: the holder (if any) runs without needing the GIL.
        self.inner
            .lock()
            .map(|g| g.as_ref().is_none_or(|e| e.is_done()))
            .unwrap_or(true)
    }
}

/// The hybrid loop's tuning instants over ``n_samples`` IMU samples of step ``dt``
/// [s], each as the number of samples before it: every ``round(tuning_period / dt)``
/// samples (halves round away from zero), from the first such multiple at which
/// ``window`` samples exist, before the last sample. :class:`Ensemble` stops there;
/// :func:`pronet.learn.hybrid.q_schedule` evaluates its regressor there. ``dt``,
/// ``tuning_period`` finite, > 0 (a period of no step refused), ``window`` >= 1.
#[pyfunction]
fn tuning_instants<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = arg_n_samples)] n_samples: usize,
    #[pyo3(from_py_with = arg_dt)] dt: f64,
    #[pyo3(from_py_with = arg_window)] window: usize,
    #[pyo3(from_py_with = arg_tuning_period)] tuning_period: f64,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let instants = detached(py, move || {
        TuningSchedule::new(n_samples, dt, window, tuning_period)?.to_vec()
    })?;
    let instants = instants
        .into_iter()
        .map(i64::try_from)
        .collect::<Result<Array1<i64>, _>>()
        .map_err(|_| invalid("n_samples", format!("must be at most {}", i64::MAX)))?;
    Ok(instants.into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyEnsemble>()?;
    m.add_function(wrap_pyfunction!(tuning_instants, m)?)
}
