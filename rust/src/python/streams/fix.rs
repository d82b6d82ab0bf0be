//! `Fix`: a position-fix stream (GNSS, USBL, LBL).

use super::args::{check, lever_arm_or_zero, rows_text, sigma3, span, Rows};
use crate::python::convert::{column, rows};
use crate::recorded::{Stream, Values};
use nalgebra::Vector3;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

/// A position-fix stream for :func:`run_filter`: GNSS, USBL or LBL fixes.
///
/// ``time`` ``(f,)`` [s], strictly increasing (each row is applied at the IMU epoch
/// nearest it); ``lla`` ``(f, 3)`` ``[lat, lon (rad), h (m, up; NaN: a horizontal
/// fix)]`` of the antenna or transponder at ``lever_arm`` ``(3,)`` [m, body FRD] from
/// the IMU, within ±:data:`MAX_LEVER_ARM`; ``|lat|`` <= 89°, ``lon`` within [−π, 2π]
/// (±180° or 0–360°: its difference from the estimate is wrapped into (−π, π]).
/// ``sigma``: 1σ [m] north, east, down, ``(3,)`` or ``(f, 3)`` one per fix (a
/// horizontal fix's down σ unused, NaN allowed). Scalar updates of the position error
/// (NIS χ², 2 or 3 dof; no gate). The arrays are copied; a bad argument is a
/// ValueError naming it.
#[pyclass(name = "Fix", module = "pronet._core", frozen)]
pub struct PyFix {
    time: Vec<f64>,
    lla: Vec<[f64; 3]>,
    sigma: Rows<[f64; 3]>,
    lever_arm: [f64; 3],
}

#[pymethods]
impl PyFix {
    #[new]
    #[pyo3(signature = (time, lla, *, sigma, lever_arm = None))]
    #[pyo3(text_signature = "(time, lla, *, sigma, lever_arm=(0.0, 0.0, 0.0))")]
    fn new(
        time: &Bound<'_, PyAny>,
        lla: &Bound<'_, PyAny>,
        sigma: &Bound<'_, PyAny>,
        lever_arm: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let out = Self {
            time: column(time, "time")?,
            lla: rows::<3>(lla, "lla")?,
            sigma: sigma3(sigma, false, "m")?,
            lever_arm: lever_arm_or_zero(lever_arm)?,
        };
        check(&out.stream("lla".into()))?;
        Ok(out)
    }

    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.time.clone().into_pyarray(py)
    }
    #[getter]
    fn lla<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        numpy::ndarray::Array2::from(self.lla.clone()).into_pyarray(py)
    }
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        match &self.sigma {
            Rows::One(s) => s.to_vec().into_pyarray(py).into_any(),
            Rows::Each(s) => numpy::ndarray::Array2::from(s.clone())
                .into_pyarray(py)
                .into_any(),
        }
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.lever_arm.to_vec()
    }
    fn __repr__(&self) -> String {
        format!(
            "Fix({}, sigma={}, lever_arm={:?})",
            span(&self.time),
            rows_text(&self.sigma, ", 3"),
            self.lever_arm
        )
    }
}

impl PyFix {
    pub(super) fn stream(&self, name: String) -> Stream<'_> {
        Stream {
            name,
            time: &self.time,
            values: Values::Fix {
                rows: &self.lla,
                sigma: self.sigma.per_row(),
            },
            lever_arm: Vector3::from(self.lever_arm),
        }
    }
}
