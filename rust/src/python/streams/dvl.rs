//! `Dvl`: a velocity stream, a DVL's body-frame readings or NED velocities.

use super::args::{self, check, number, option_text, renamed, rows_text, sigma3, span, Rows};
use crate::ekf::{Aiding, FilterConfig};
use crate::python::call::invalid;
use crate::python::convert::{column, describe, rows, text_arg};
use crate::recorded::{velocity_variance, PerRow, Stream, Values};
use nalgebra::Vector3;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

/// The frame of a velocity stream by its name.
fn parse_frame(obj: &Bound<'_, PyAny>) -> PyResult<Aiding> {
    match text_arg(obj, "frame")?.as_str() {
        "body" => Ok(Aiding::Body),
        "ned" => Ok(Aiding::Nav),
        other => Err(invalid(
            "frame",
            format!("must be \"body\" (a DVL: body-frame FRD velocity) or \"ned\", got {other:?}"),
        )),
    }
}

fn frame_name(frame: Aiding) -> &'static str {
    match frame {
        Aiding::Body => "body",
        Aiding::Nav => "ned",
    }
}

/// A velocity stream's 1σ given \[m/s\] and its squares, R's diagonal \[(m/s)²\].
struct VelocitySigma {
    sigma: Rows<[f64; 3]>,
    variance: Rows<[f64; 3]>,
}

/// A velocity stream for :func:`run_filter`: a DVL's readings, or velocities in NED.
///
/// ``time`` ``(m,)`` [s], strictly increasing (each row is applied at the IMU epoch
/// nearest it); ``velocity`` ``(m, 3)`` [m/s] in ``frame``: ``"body"``, a DVL's
/// velocity in the body frame FRD at its lever arm r (``h = Ĉᵀv̂ + ω̂ × r``), or
/// ``"ned"``, the NED velocity of the point at r (``h = v̂ + Ĉ(ω̂ × r)``). ``sigma``: 1σ
/// [m/s] per axis, a number, ``(3,)`` or ``(m, 3)`` one per row; R: ``diag(σ²)`` + r's gyro noise.
/// ``lever_arm`` ``(3,)`` [m, body FRD] from the IMU, within ±:data:`MAX_LEVER_ARM`.
/// ``gate``: a χ² threshold (3 dof, > 0): a row whose NIS exceeds it is rejected. Each
/// None is the pass's :class:`FilterConfig`'s (``dvl_variance``, ``aiding``,
/// ``lever_arm``, ``innovation_gate``), so ``Dvl(time, velocity)`` is the DVL it
/// describes. Beside the DVL calibration states (``dvl_calibration=True``: they read
/// every body-frame stream) a ``"ned"`` stream is refused. The arrays are copied, the
/// getters give them back as given (None: not given); a bad argument is a ValueError
/// naming it.
#[pyclass(name = "Dvl", module = "pronet._core", frozen)]
pub struct PyDvl {
    time: Vec<f64>,
    velocity: Vec<[f64; 3]>,
    /// None: the config's R.
    sigma: Option<VelocitySigma>,
    frame: Option<Aiding>,
    lever_arm: Option<[f64; 3]>,
    gate: Option<f64>,
}

#[pymethods]
impl PyDvl {
    #[new]
    #[pyo3(signature = (time, velocity, *, sigma = None, frame = None, lever_arm = None, gate = None))]
    #[pyo3(
        text_signature = "(time, velocity, *, sigma=None, frame=None, lever_arm=None, gate=None)"
    )]
    fn new(
        time: &Bound<'_, PyAny>,
        velocity: &Bound<'_, PyAny>,
        sigma: Option<&Bound<'_, PyAny>>,
        frame: Option<&Bound<'_, PyAny>>,
        lever_arm: Option<&Bound<'_, PyAny>>,
        gate: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let time = column(time, "time")?;
        let velocity = rows::<3>(velocity, "velocity")?;
        let sigma = match sigma {
            Some(s) => {
                let sigma = sigma3(s, true, "m/s")?;
                let variance = velocity_variance("velocity", sigma.rows())
                    .map_err(|e| renamed(e, "velocity"))?;
                let variance = match &sigma {
                    Rows::One(_) => Rows::One(variance[0]),
                    Rows::Each(_) => Rows::Each(variance),
                };
                Some(VelocitySigma { sigma, variance })
            }
            None => None,
        };
        let frame = frame.map(parse_frame).transpose()?;
        let lever_arm = lever_arm.map(args::lever_arm).transpose()?;
        let gate = match gate.filter(|g| !g.is_none()) {
            Some(g) => Some(number(g, "gate").ok_or_else(|| {
                invalid(
                    "gate",
                    format!(
                        "expected a real number (a χ² threshold), got {}",
                        describe(g)
                    ),
                )
            })?),
            None => None,
        };
        let dvl = Self {
            time,
            velocity,
            sigma,
            frame,
            lever_arm,
            gate,
        };
        // The config's values stand in for the ones not given, which it checks itself.
        check(&dvl.stream("velocity".into(), &FilterConfig::default()))?;
        Ok(dvl)
    }

    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.time.clone().into_pyarray(py)
    }
    #[getter]
    fn velocity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        numpy::ndarray::Array2::from(self.velocity.clone()).into_pyarray(py)
    }
    /// 1σ [m/s]: ``(3,)`` for every row (a number given: three), or ``(m, 3)``.
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.sigma.as_ref().map(|s| match &s.sigma {
            Rows::One(s) => s.to_vec().into_pyarray(py).into_any(),
            Rows::Each(s) => numpy::ndarray::Array2::from(s.clone())
                .into_pyarray(py)
                .into_any(),
        })
    }
    #[getter]
    fn frame(&self) -> Option<&'static str> {
        self.frame.map(frame_name)
    }
    #[getter]
    fn lever_arm(&self) -> Option<Vec<f64>> {
        self.lever_arm.map(|a| a.to_vec())
    }
    #[getter]
    fn gate(&self) -> Option<f64> {
        self.gate
    }
    fn __repr__(&self) -> String {
        let sigma = self
            .sigma
            .as_ref()
            .map_or("None".into(), |s| rows_text(&s.sigma, ", 3"));
        format!(
            "Dvl({}, sigma={sigma}, frame={}, lever_arm={}, gate={})",
            span(&self.time),
            option_text(self.frame()),
            option_text(self.lever_arm),
            option_text(self.gate),
        )
    }
}

impl PyDvl {
    /// The stream named `name`, what is not given taken from `cfg`: with nothing
    /// given, [`Stream::dvl`] of `cfg`.
    pub(super) fn stream(&self, name: String, cfg: &FilterConfig) -> Stream<'_> {
        Stream {
            name,
            time: &self.time,
            values: Values::Velocity {
                rows: &self.velocity,
                variance: self
                    .sigma
                    .as_ref()
                    .map_or(PerRow::One(cfg.dvl_variance), |s| s.variance.per_row()),
                frame: self.frame.unwrap_or(cfg.aiding),
                gate: self.gate.or(cfg.innovation_gate),
            },
            lever_arm: self.lever_arm.map_or(cfg.lever_arm, Vector3::from),
        }
    }
}
