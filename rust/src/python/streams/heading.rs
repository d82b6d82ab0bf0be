//! `Heading`: a heading stream, a compass's, an AHRS's or a gyrocompass's yaw.

use super::args::{check, rows_text, sigma1, span, Rows};
use crate::python::convert::column;
use crate::recorded::{Stream, Values};
use nalgebra::Vector3;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyFloat;

/// A heading stream for :func:`run_filter`: a compass's, an AHRS's or a gyrocompass's
/// yaw.
///
/// ``time`` ``(n,)`` [s], strictly increasing (each row is applied at the IMU epoch
/// nearest it); ``heading`` ``(n,)`` [rad], the yaw of the body from true north (ZYX, as
/// the filter's ``rpy``; a magnetic heading corrected for declination first), within
/// ±2π (the innovation is wrapped into (−π, π]; degrees are refused). ``sigma``: 1σ
/// [rad], > 0 and at most π, a number or ``(n,)`` one per reading. A scalar update of
/// the attitude error (``h = atan2(Ĉ₁₀, Ĉ₀₀)``; NIS χ², 1 dof; no gate), no lever arm.
/// The arrays are copied; a bad argument is a ValueError naming it.
#[pyclass(name = "Heading", module = "pronet._core", frozen)]
pub struct PyHeading {
    time: Vec<f64>,
    heading: Vec<f64>,
    sigma: Rows<f64>,
}

#[pymethods]
impl PyHeading {
    #[new]
    #[pyo3(signature = (time, heading, *, sigma))]
    #[pyo3(text_signature = "(time, heading, *, sigma)")]
    fn new(
        time: &Bound<'_, PyAny>,
        heading: &Bound<'_, PyAny>,
        sigma: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let out = Self {
            time: column(time, "time")?,
            heading: column(heading, "heading")?,
            sigma: sigma1(sigma, "rad")?,
        };
        check(&out.stream("heading".into()))?;
        Ok(out)
    }

    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.time.clone().into_pyarray(py)
    }
    #[getter]
    fn heading<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.heading.clone().into_pyarray(py)
    }
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        match &self.sigma {
            Rows::One(s) => PyFloat::new(py, *s).into_any(),
            Rows::Each(s) => s.clone().into_pyarray(py).into_any(),
        }
    }
    fn __repr__(&self) -> String {
        format!(
            "Heading({}, sigma={})",
            span(&self.time),
            rows_text(&self.sigma, "")
        )
    }
}

impl PyHeading {
    pub(super) fn stream(&self, name: String) -> Stream<'_> {
        Stream {
            name,
            time: &self.time,
            values: Values::Heading {
                rows: &self.heading,
                sigma: self.sigma.per_row(),
            },
            lever_arm: Vector3::zeros(),
        }
    }
}
