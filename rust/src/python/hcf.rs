//! `HcfEnsemble`: the handcrafted-feature ensemble's prediction in the core, built from
//! the exported trees (`pronet.hcf.HCFEnsemble.frozen`).

use super::call::{detached, interruptible, invalid};
use super::convert::{arg_threads, describe, real_array, text_arg, window_rows};
use crate::regressors::hcf::{HcfEnsemble, Target, TreeSet};
use crate::threads::Workers;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use std::sync::Arc;

/// The handcrafted-feature ensemble's prediction (``pronet.learn.hcf.HCFEnsemble``) from
/// its exported trees; build it with :meth:`pronet.learn.hcf.HCFEnsemble.frozen`.
///
/// ``gb``, ``rf``: ``(left, right, feature, roots)`` int32 and ``threshold``, ``value``
/// float64 arrays, in the order ``(left, right, feature, threshold, value, roots)``;
/// ``target``: ``"q"`` or ``"log-ratio"``. ``threads``: worker threads for ``predict``
/// (None: all cores).
#[pyclass(name = "HcfEnsemble", module = "pronet._core", frozen)]
pub struct PyHcfEnsemble {
    inner: Arc<HcfEnsemble>,
    workers: Workers,
}

fn array<T: numpy::Element + Copy>(
    obj: &Bound<'_, PyAny>,
    arg: &str,
    dtype: &str,
) -> PyResult<Vec<T>> {
    let arr: PyReadonlyArray1<T> = real_array(obj, dtype)?.ok_or_else(|| {
        invalid(
            arg,
            format!(
                "expected numbers of shape (n,) (taken as {dtype}), got {}",
                describe(obj)
            ),
        )
    })?;
    Ok(arr.as_array().to_vec())
}

fn trees(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<TreeSet> {
    let parts: Vec<Bound<PyAny>> = obj.extract().map_err(|_| {
        invalid(
            arg,
            "expected (left, right, feature, threshold, value, roots)",
        )
    })?;
    let [left, right, feature, threshold, value, roots] = parts.as_slice() else {
        return Err(invalid(
            arg,
            "expected (left, right, feature, threshold, value, roots)",
        ));
    };
    TreeSet::new(
        array(left, &format!("{arg}.left"), "int32")?,
        array(right, &format!("{arg}.right"), "int32")?,
        array(feature, &format!("{arg}.feature"), "int32")?,
        array(threshold, &format!("{arg}.threshold"), "float64")?,
        array(value, &format!("{arg}.value"), "float64")?,
        array(roots, &format!("{arg}.roots"), "int32")?,
    )
    .map_err(|e| invalid(arg, e.to_string()))
}

#[pymethods]
impl PyHcfEnsemble {
    #[new]
    #[pyo3(signature = (*, window, gb, gb_init, gb_rate, rf, target, threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        window: usize,
        gb: &Bound<'_, PyAny>,
        gb_init: f64,
        gb_rate: f64,
        rf: &Bound<'_, PyAny>,
        target: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arg_threads)] threads: Option<usize>,
    ) -> PyResult<Self> {
        let target = match text_arg(target, "target")?.as_str() {
            "q" => Target::Q,
            "log-ratio" => Target::LogRatio,
            other => {
                return Err(invalid(
                    "target",
                    format!("'q' or 'log-ratio', got {other:?}"),
                ))
            }
        };
        let (gb, rf) = (trees(gb, "gb")?, trees(rf, "rf")?);
        let (model, workers) = detached(py, move || {
            let model = HcfEnsemble::new(window, gb, gb_init, gb_rate, rf, target)?;
            Ok((model, Workers::new(threads)?))
        })?;
        Ok(Self {
            inner: Arc::new(model),
            workers,
        })
    }

    /// q ``(n,)`` for windows ``(n, window)``.
    fn predict<'py>(
        &self,
        py: Python<'py>,
        windows: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let samples: Vec<f64> = window_rows(windows, self.inner.window(), "float64")?;
        let model = Arc::clone(&self.inner);
        let workers = self.workers.clone();
        let q = interruptible(py, move |cancel| {
            workers.run(|| model.predict_until(&samples, cancel))
        })?;
        Ok(q.into_pyarray(py))
    }

    #[getter]
    fn window(&self) -> usize {
        self.inner.window()
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyHcfEnsemble>()
}
