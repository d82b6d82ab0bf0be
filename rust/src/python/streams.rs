//! `Dvl`, `Depth`, `Fix`: the aiding sensors' streams a filter pass takes, each checked
//! when it is made ([`Stream::validate`]) and resolved against the pass's
//! `FilterConfig` when the pass runs ([`StreamRef::stream`]).

use super::call::{invalid, to_py_err};
use super::convert::{
    column, describe, fixed, is_real_number, real_arg, real_array, rows, text_arg,
};
use crate::ekf::{Aiding, FilterConfig};
use crate::error::Error;
use crate::recorded::{velocity_variance, PerRow, Stream, Values};
use nalgebra::Vector3;
use numpy::ndarray::{Ix1, Ix2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyFloat;

/// A value given once for every row, or once per row (owned: see [`PerRow`]).
enum Rows<T> {
    One(T),
    Each(Vec<T>),
}

impl<T: Copy> Rows<T> {
    fn per_row(&self) -> PerRow<'_, T> {
        match self {
            Rows::One(v) => PerRow::One(*v),
            Rows::Each(v) => PerRow::Each(v),
        }
    }

    fn rows(&self) -> &[T] {
        match self {
            Rows::One(v) => std::slice::from_ref(v),
            Rows::Each(v) => v,
        }
    }
}

/// `obj` as one real number (not an array of any shape: `real_arg` would take a
/// one-element array), or None.
fn number(obj: &Bound<'_, PyAny>, arg: &str) -> Option<f64> {
    let ndim = obj.getattr("ndim").and_then(|n| n.extract::<usize>());
    (is_real_number(obj) && ndim.unwrap_or(0) == 0)
        .then(|| real_arg(obj, arg).ok())
        .flatten()
}

/// A 1σ of 3 axes: a number (with `scalar`), `(3,)`, or `(n, 3)` one per row.
fn sigma3(obj: &Bound<'_, PyAny>, scalar: bool, unit: &str) -> PyResult<Rows<[f64; 3]>> {
    if let Some(arr) = real_array::<f64, Ix1>(obj, "float64") {
        let v = arr.as_array();
        if v.len() == 3 {
            return Ok(Rows::One([v[0], v[1], v[2]]));
        }
    } else if real_array::<f64, Ix2>(obj, "float64").is_some() {
        return Ok(Rows::Each(rows::<3>(obj, "sigma")?));
    } else if let Some(s) = scalar.then(|| number(obj, "sigma")).flatten() {
        return Ok(Rows::One([s; 3]));
    }
    let forms = if scalar {
        "a number, 3 numbers or (n, 3)"
    } else {
        "3 numbers or (n, 3)"
    };
    Err(invalid(
        "sigma",
        format!(
            "expected {forms} real numbers [{unit}], got {}",
            describe(obj)
        ),
    ))
}

/// A 1σ of one axis: a number, or `(n,)` one per row.
fn sigma1(obj: &Bound<'_, PyAny>) -> PyResult<Rows<f64>> {
    if real_array::<f64, Ix1>(obj, "float64").is_some() {
        return Ok(Rows::Each(column(obj, "sigma")?));
    }
    if let Some(s) = number(obj, "sigma") {
        return Ok(Rows::One(s));
    }
    Err(invalid(
        "sigma",
        format!(
            "expected a number or (n,) real numbers [m], got {}",
            describe(obj)
        ),
    ))
}

/// A lever arm \[m\]: 3 numbers (the stream's check bounds them).
fn lever_arm(obj: &Bound<'_, PyAny>) -> PyResult<[f64; 3]> {
    fixed::<3>(obj, "lever_arm")
}

fn lever_arm_or_zero(obj: Option<&Bound<'_, PyAny>>) -> PyResult<[f64; 3]> {
    obj.map_or(Ok([0.0; 3]), lever_arm)
}

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

/// A core error about a stream named after its values' argument `values` raised
/// naming the constructor's argument: its arrays `{values}_time`, `{values}_sigma`
/// (`depth_sigma` for a depth's one σ), `{values}_gate` and `{values}_lever_arm` are
/// `time`, `sigma`, `gate` and `lever_arm`.
fn renamed(e: Error, values: &str) -> PyErr {
    match e {
        Error::InvalidArgument { arg, reason } => {
            let arg = match arg.strip_prefix(values) {
                Some("_time") => "time".to_string(),
                Some("_sigma") => "sigma".to_string(),
                Some("_gate") => "gate".to_string(),
                Some("_lever_arm") => "lever_arm".to_string(),
                _ if arg == "depth_sigma" => "sigma".to_string(),
                _ => arg,
            };
            let reason = reason
                .replace(&format!("{values}_time"), "time")
                .replace(&format!("{values}_sigma"), "sigma");
            to_py_err(Error::InvalidArgument { arg, reason })
        }
        other => to_py_err(other),
    }
}

/// `stream` checked ([`Stream::validate`]), an error naming the constructor's argument.
fn check(stream: &Stream<'_>) -> PyResult<()> {
    stream.validate().map_err(|e| renamed(e, &stream.name))
}

/// `[first, last]` of `time` for a `__repr__`.
fn span(time: &[f64]) -> String {
    match (time.first(), time.last()) {
        (Some(a), Some(_)) if time.len() == 1 => format!("1 row at {a} s"),
        (Some(a), Some(b)) => format!("{} rows over [{a}, {b}] s", time.len()),
        _ => "0 rows".into(),
    }
}

fn option_text<T: std::fmt::Debug>(value: Option<T>) -> String {
    value.map_or("None".into(), |v| format!("{v:?}"))
}

/// Rows of a per-row value for a `__repr__`: the one value, or the shape.
fn rows_text<T: std::fmt::Debug>(rows: &Rows<T>, width: &str) -> String {
    match rows {
        Rows::One(v) => format!("{v:?}"),
        Rows::Each(v) => format!("({}{width}) per row", v.len()),
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
/// [m/s] per axis, a number, ``(3,)`` or ``(m, 3)`` one per row; R is ``diag(σ²)``.
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
        let lever_arm = lever_arm.map(self::lever_arm).transpose()?;
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
    fn stream(&self, name: String, cfg: &FilterConfig) -> Stream<'_> {
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
            sigma: sigma1(sigma)?,
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
    fn stream(&self, name: String) -> Stream<'_> {
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
    fn stream(&self, name: String) -> Stream<'_> {
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

/// One of a pass's streams, borrowed from its Python object (frozen, so readable
/// without the GIL).
#[derive(Clone, Copy)]
pub(super) enum StreamRef<'a> {
    Dvl(&'a PyDvl),
    Depth(&'a PyDepth),
    Fix(&'a PyFix),
}

impl<'a> StreamRef<'a> {
    /// The core's stream, named `streams[i]` for errors, resolved against `cfg`.
    pub(super) fn stream(self, i: usize, cfg: &FilterConfig) -> Stream<'a> {
        let name = format!("streams[{i}]");
        match self {
            StreamRef::Dvl(d) => d.stream(name, cfg),
            StreamRef::Depth(d) => d.stream(name),
            StreamRef::Fix(f) => f.stream(name),
        }
    }
}

/// The items of `streams` (a sequence of `Dvl`, `Depth` and `Fix`), type-checked.
pub(super) fn stream_items<'py>(streams: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let refuse = || {
        invalid(
            "streams",
            format!(
                "expected a sequence (a list or tuple) of Dvl, Depth and Fix streams, got {}",
                describe(streams)
            ),
        )
    };
    if streams.is_instance_of::<pyo3::types::PyString>()
        || streams.is_instance_of::<PyDvl>()
        || streams.is_instance_of::<PyDepth>()
        || streams.is_instance_of::<PyFix>()
    {
        return Err(refuse());
    }
    let items: Vec<Bound<'py, PyAny>> = streams
        .try_iter()
        .map_err(|_| refuse())?
        .collect::<PyResult<_>>()?;
    for (i, item) in items.iter().enumerate() {
        if !(item.is_instance_of::<PyDvl>()
            || item.is_instance_of::<PyDepth>()
            || item.is_instance_of::<PyFix>())
        {
            return Err(invalid(
                &format!("streams[{i}]"),
                format!("expected a Dvl, Depth or Fix, got {}", describe(item)),
            ));
        }
    }
    Ok(items)
}

/// The stream an item of [`stream_items`] is.
pub(super) fn stream_ref<'a>(item: &'a Bound<'_, PyAny>) -> StreamRef<'a> {
    if let Ok(d) = item.cast::<PyDvl>() {
        StreamRef::Dvl(d.get())
    } else if let Ok(d) = item.cast::<PyDepth>() {
        StreamRef::Depth(d.get())
    } else if let Ok(f) = item.cast::<PyFix>() {
        StreamRef::Fix(f.get())
    } else {
        unreachable!("stream_items checked the type")
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDvl>()?;
    m.add_class::<PyDepth>()?;
    m.add_class::<PyFix>()
}
