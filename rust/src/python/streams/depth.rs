//! `Depth`: a pressure sensor's depth stream.

use super::args::{check, lever_arm_or_zero, rows_text, sigma1, span, Rows};
use crate::python::convert::column;
use crate::recorded::{Stream, Values};
use nalgebra::Vector3;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyFloat;

/// A depth stream for :func:`run_filter`: a pressure sensor's readings.
///
/// ``time`` ``(d,)`` [s], strictly increasing (each row is applied at the IMU epoch
/// nearest it); ``depth`` ``(d,)`` [m, positive down] of the sensor at ``lever_arm``
/// ``(3,)`` [m, body FRD] from the IMU, within ±:data:`MAX_LEVER_ARM`
/// (``h = −ĥ + (Ĉ r)_D``: 1 m below a level IMU reads 1 m deeper). ``sigma``: 1σ [m], a
/// number or ``(d,)`` one per reading. A scalar update of the position error (NIS χ²,
/// 1 dof; no gate). The arrays are copied; a bad argument is a ValueError naming it.
#[pyclass(name = "Depth", module = "pronet._core", frozen)]
pub struct PyDepth {
    time: Vec<f64>,
    depth: Vec<f64>,
    sigma: Rows<f64>,
    lever_arm: [f64; 3],
}

#[pymethods]
impl PyDepth {
    #[new]
    #[pyo3(signature = (time, depth, *, sigma, lever_arm = None))]
    #[pyo3(text_signature = "(time, depth, *, sigma, lever_arm=(0.0, 0.0, 0.0))")]
    fn new(
        time: &Bound<'_, PyAny>,
        depth: &Bound<'_, PyAny>,
        sigma: &Bound<'_, PyAny>,
        lever_arm: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let out = Self {
            time: column(time, "time")?,
            depth: column(depth, "depth")?,
            sigma: sigma1(sigma, "m")?,
            lever_arm: lever_arm_or_zero(lever_arm)?,
        };
        check(&out.stream("depth".into()))?;
        Ok(out)
    }

    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.time.clone().into_pyarray(py)
    }
    #[getter]
    fn depth<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.depth.clone().into_pyarray(py)
    }
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        match &self.sigma {
            Rows::One(s) => PyFloat::new(py, *s).into_any(),
            Rows::Each(s) => s.clone().into_pyarray(py).into_any(),
        }
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.lever_arm.to_vec()
    }
    fn __repr__(&self) -> String {
        format!(
            "Depth({}, sigma={}, lever_arm={:?})",
            span(&self.time),
            rows_text(&self.sigma, ""),
            self.lever_arm
        )
    }
}

impl PyDepth {
    pub(super) fn stream(&self, name: String) -> Stream<'_> {
        Stream {
            name,
            time: &self.time,
            values: Values::Depth {
                rows: &self.depth,
                sigma: self.sigma.per_row(),
            },
            lever_arm: Vector3::from(self.lever_arm),
        }
    }
}
