//! Python bindings (`pronet._core`): validate and convert arrays, release the GIL around
//! every heavy call, and map errors. Every core error becomes a `ValueError` that starts
//! with the offending argument's name; a Rust panic (a bug) is caught and raised as
//! `RuntimeError`, never as a `PanicException`.

use crate::attitude::{dcm_from_euler, euler_from_dcm};
use crate::ekf::{filter_recorded, Aiding, FilterConfig, FilterOutput, RecordedData};
use crate::error::Error;
use crate::mechanization::{integrate, NavState};
use crate::montecarlo::{
    run_monte_carlo, with_threads, Ensemble, McOptions, McResult, Scenario, MAX_THREADS,
};
use crate::noise::StrategySpec;
use crate::sensors::{DvlModel, ImuErrorModel, SensorConfig, VarianceSchedule};
use crate::trajectory::{self, Segment, TrajectorySpec, Truth};
use crate::{earth, Result as CoreResult};
use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex};

fn to_py_err(e: Error) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn invalid(arg: &str, reason: impl Into<String>) -> PyErr {
    to_py_err(Error::invalid(arg, reason))
}

/// Run `f` without the GIL, turning core errors into `ValueError` and a panic into
/// `RuntimeError`.
fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> CoreResult<T> + Send) -> PyResult<T> {
    let outcome = py.detach(|| catch_unwind(AssertUnwindSafe(f)));
    match outcome {
        Ok(result) => result.map_err(to_py_err),
        Err(payload) => {
            let msg = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!(
                "internal error in pronet core (please report): {msg}"
            )))
        }
    }
}

fn describe(obj: &Bound<'_, PyAny>) -> String {
    let ty = obj
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into());
    match (obj.getattr("dtype"), obj.getattr("shape")) {
        (Ok(d), Ok(s)) => format!(
            "{ty} of dtype {} and shape {}",
            d.str().map(|x| x.to_string()).unwrap_or_default(),
            s.str().map(|x| x.to_string()).unwrap_or_default()
        ),
        _ => ty,
    }
}

/// A float64 array of shape (n, C) as rows.
fn rows<const C: usize>(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<[f64; C]>> {
    let arr: PyReadonlyArray2<f64> = obj.extract().map_err(|_| {
        invalid(
            arg,
            format!(
                "expected a float64 numpy array of shape (n, {C}), got {}",
                describe(obj)
            ),
        )
    })?;
    let view = arr.as_array();
    if view.ncols() != C {
        return Err(invalid(
            arg,
            format!("expected shape (n, {C}), got {:?}", view.shape()),
        ));
    }
    Ok(view
        .outer_iter()
        .map(|r| std::array::from_fn(|j| r[j]))
        .collect())
}

/// A float64 array of shape (n,).
fn column(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<f64>> {
    let arr: PyReadonlyArray1<f64> = obj.extract().map_err(|_| {
        invalid(
            arg,
            format!(
                "expected a float64 numpy array of shape (n,), got {}",
                describe(obj)
            ),
        )
    })?;
    Ok(arr.as_array().to_vec())
}

/// Whether `obj` is a real number: a Python int or float (not a bool), or a NumPy value
/// of integer or float dtype. Extraction to f64 alone would let bools through as 1.0 and
/// drop the imaginary part of complex NumPy values.
fn is_real_number(obj: &Bound<'_, PyAny>) -> bool {
    use pyo3::types::{PyBool, PyFloat, PyInt};
    if obj.is_instance_of::<PyBool>() {
        return false;
    }
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return true;
    }
    numpy_kind_in(obj, &["i", "u", "f"])
}

/// Whether `obj` is a NumPy value (scalar or array) whose dtype kind is one of `kinds`.
fn numpy_kind_in(obj: &Bound<'_, PyAny>, kinds: &[&str]) -> bool {
    obj.getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .is_ok_and(|k| kinds.contains(&k.as_str()))
}

/// Exactly N finite real numbers from any sequence or array.
fn fixed<const N: usize>(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<[f64; N]> {
    use pyo3::types::{PyByteArray, PyBytes, PyString};
    let refuse = || {
        invalid(
            arg,
            format!("expected {N} real numbers, got {}", describe(obj)),
        )
    };
    if obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
        || obj.is_instance_of::<PyString>()
    {
        return Err(refuse());
    }
    for item in obj.try_iter().map_err(|_| refuse())? {
        if !is_real_number(&item?) {
            return Err(refuse());
        }
    }
    let v: Vec<f64> = obj
        .extract()
        .map_err(|_| invalid(arg, format!("expected {N} numbers, got {}", describe(obj))))?;
    let out: [f64; N] = v
        .as_slice()
        .try_into()
        .map_err(|_| invalid(arg, format!("expected {N} numbers, got {}", v.len())))?;
    if let Some(i) = out.iter().position(|x| !x.is_finite()) {
        return Err(invalid(
            arg,
            format!("must be finite, element {i} is {}", out[i]),
        ));
    }
    Ok(out)
}

/// A real scalar argument (an int or float, NumPy's included; never a bool, a string or
/// a complex), or `ValueError` naming it. pyo3's own f64 extraction would raise
/// `TypeError` for a string and take `True` as 1.0.
fn real_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<f64> {
    let refuse = || {
        invalid(
            arg,
            format!("expected a real number, got {}", describe(obj)),
        )
    };
    if !is_real_number(obj) {
        return Err(refuse());
    }
    obj.extract::<f64>().map_err(|_| refuse())
}

/// A whole-number argument in `T`'s range (an int, NumPy's included, never a bool or a
/// float), or `ValueError` naming it (pyo3 would raise `TypeError`/`OverflowError`).
fn whole_arg<T: TryFrom<i128> + std::fmt::Display>(
    obj: &Bound<'_, PyAny>,
    arg: &str,
) -> PyResult<T> {
    use pyo3::types::{PyBool, PyInt};
    let is_int = !obj.is_instance_of::<PyBool>()
        && (obj.is_instance_of::<PyInt>() || numpy_kind_in(obj, &["i", "u"]));
    if !is_int {
        return Err(invalid(
            arg,
            format!("expected a whole number, got {}", describe(obj)),
        ));
    }
    obj.extract::<i128>()
        .ok()
        .and_then(|v| T::try_from(v).ok())
        .ok_or_else(|| invalid(arg, format!("{} is out of range", describe(obj))))
}

/// `True`/`False` (NumPy's included), or `ValueError` naming the argument: a string such
/// as "no" or a number is not silently taken as a truth value.
fn flag_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<bool> {
    use pyo3::types::PyBool;
    let is_bool = obj.is_instance_of::<PyBool>() || numpy_kind_in(obj, &["b"]);
    if !is_bool {
        return Err(invalid(
            arg,
            format!("expected True or False, got {}", describe(obj)),
        ));
    }
    obj.extract::<bool>().map_err(|_| {
        invalid(
            arg,
            format!("expected True or False, got {}", describe(obj)),
        )
    })
}

fn text_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<String> {
    obj.extract::<String>()
        .map_err(|_| invalid(arg, format!("expected a string, got {}", describe(obj))))
}

/// `from_py_with` converters, one per argument name, so that the error names it.
macro_rules! arg_converters {
    ($($fn_name:ident: $t:ty = $conv:ident($name:literal);)*) => {
        $(fn $fn_name(obj: &Bound<'_, PyAny>) -> PyResult<$t> {
            $conv(obj, $name)
        })*
    };
}

arg_converters! {
    arg_lat: f64 = real_arg("lat");
    arg_h: f64 = real_arg("h");
    arg_dt: f64 = real_arg("dt");
    arg_speed0: f64 = real_arg("speed0");
    arg_t0: f64 = real_arg("t0");
    arg_accel_bias_psd: f64 = real_arg("accel_bias_psd");
    arg_gyro_bias_psd: f64 = real_arg("gyro_bias_psd");
    arg_imu_dt: f64 = real_arg("imu_dt");
    arg_dvl_period: f64 = real_arg("dvl_period");
    arg_tuning_period: f64 = real_arg("tuning_period");
    arg_aiding: String = text_arg("aiding");
    arg_window: i64 = whole_arg("window");
    arg_n_runs: i64 = whole_arg("n_runs");
    arg_record_every: i64 = whole_arg("record_every");
    arg_seed: u64 = whole_arg("seed");
    arg_first_run: u64 = whole_arg("first_run");
    arg_sample_initial_error: bool = flag_arg("sample_initial_error");
}

fn arg_innovation_gate(obj: &Bound<'_, PyAny>) -> PyResult<Option<f64>> {
    if obj.is_none() {
        return Ok(None);
    }
    real_arg(obj, "innovation_gate").map(Some)
}

fn arg_threads(obj: &Bound<'_, PyAny>) -> PyResult<Option<i64>> {
    if obj.is_none() {
        return Ok(None);
    }
    whole_arg(obj, "threads").map(Some)
}

fn finite_scalar(value: f64, arg: &str) -> PyResult<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(invalid(arg, format!("must be finite, got {value}")))
    }
}

fn nav_state(lla0: [f64; 3], vel0: [f64; 3], rpy0: [f64; 3]) -> PyResult<NavState> {
    if lla0[0].abs() > 89f64.to_radians() {
        return Err(invalid(
            "lla0",
            "latitude must be within ±89° (given in radians)",
        ));
    }
    Ok(NavState {
        lla: Vector3::from(lla0),
        vel: Vector3::from(vel0),
        dcm: dcm_from_euler(rpy0[0], rpy0[1], rpy0[2]),
    })
}

fn matrix<const C: usize>(
    py: Python<'_>,
    rows: impl ExactSizeIterator<Item = [f64; C]>,
) -> Bound<'_, numpy::PyArray2<f64>> {
    let n = rows.len();
    let flat: Vec<f64> = rows.flat_map(|r| r.into_iter()).collect();
    Array2::from_shape_vec((n, C), flat)
        .expect("length n*C by construction")
        .into_pyarray(py)
}

fn nav_arrays<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, states: &[NavState]) -> PyResult<()> {
    d.set_item("lla", matrix(py, states.iter().map(|s| s.lla.into())))?;
    d.set_item("vel", matrix(py, states.iter().map(|s| s.vel.into())))?;
    d.set_item(
        "rpy",
        matrix(py, states.iter().map(|s| euler_from_dcm(&s.dcm).into())),
    )?;
    Ok(())
}

// ---------------------------------------------------------------- trajectories

/// A trajectory's truth and ideal IMU (see `_core.pyi`).
#[pyclass(name = "Trajectory", module = "pronet._core", frozen)]
pub struct PyTrajectory {
    truth: Arc<Truth>,
    spec: TrajectorySpec,
}

#[pymethods]
impl PyTrajectory {
    #[getter]
    fn name(&self) -> String {
        self.truth.name.clone()
    }
    #[getter]
    fn dt(&self) -> f64 {
        self.truth.dt
    }
    #[getter]
    fn duration(&self) -> f64 {
        self.truth.duration()
    }
    #[getter]
    fn n_samples(&self) -> usize {
        self.truth.len()
    }
    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.truth.time.clone().into_pyarray(py)
    }
    #[getter]
    fn lla<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(py, self.truth.states.iter().map(|s| s.lla.into()))
    }
    #[getter]
    fn vel_ned<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(py, self.truth.states.iter().map(|s| s.vel.into()))
    }
    #[getter]
    fn rpy<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(py, self.truth.rpy.iter().map(|r| (*r).into()))
    }
    #[getter]
    fn imu<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(py, self.truth.imu.iter().copied())
    }
    #[getter]
    fn segments<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(
            py,
            self.spec
                .segments
                .iter()
                .map(|s| [s.duration, s.accel, s.yaw_rate, s.pitch_rate]),
        )
    }
    #[getter]
    fn speed0(&self) -> f64 {
        self.spec.speed0
    }
    fn __repr__(&self) -> String {
        format!(
            "Trajectory(name={:?}, duration={} s, dt={} s, samples={})",
            self.truth.name,
            self.truth.duration(),
            self.truth.dt,
            self.truth.len()
        )
    }
}

fn make_trajectory(py: Python<'_>, spec: TrajectorySpec) -> PyResult<PyTrajectory> {
    let truth = {
        let spec = spec.clone();
        detached(py, move || spec.generate())?
    };
    Ok(PyTrajectory {
        truth: Arc::new(truth),
        spec,
    })
}

#[pyfunction]
#[pyo3(signature = (name, dt = 0.01))]
fn builtin_trajectory(
    py: Python<'_>,
    name: &str,
    #[pyo3(from_py_with = arg_dt)] dt: f64,
) -> PyResult<PyTrajectory> {
    let spec = trajectory::builtin(name, dt).map_err(to_py_err)?;
    make_trajectory(py, spec)
}

#[pyfunction]
fn builtin_trajectory_names() -> Vec<&'static str> {
    trajectory::BUILTIN_NAMES.to_vec()
}

#[pyfunction]
#[pyo3(signature = (segments, *, lla0, speed0, rpy0 = None, dt = 0.01, name = "custom".to_string()))]
fn trajectory_from_segments(
    py: Python<'_>,
    segments: &Bound<'_, PyAny>,
    lla0: &Bound<'_, PyAny>,
    #[pyo3(from_py_with = arg_speed0)] speed0: f64,
    rpy0: Option<&Bound<'_, PyAny>>,
    #[pyo3(from_py_with = arg_dt)] dt: f64,
    name: String,
) -> PyResult<PyTrajectory> {
    let segs = rows::<4>(segments, "segments")?
        .into_iter()
        .map(|r| Segment::new(r[0], r[1], r[2], r[3]))
        .collect();
    let rpy0 = match rpy0 {
        Some(r) => fixed::<3>(r, "rpy0")?,
        None => [0.0; 3],
    };
    let spec = TrajectorySpec {
        name,
        lla0: Vector3::from(fixed::<3>(lla0, "lla0")?),
        speed0,
        rpy0: Vector3::from(rpy0),
        segments: segs,
        dt,
    };
    make_trajectory(py, spec)
}

// ---------------------------------------------------------------- earth, mechanization

/// Heights [m] within which `normal_gravity` answers.
const MAX_GRAVITY_HEIGHT: f64 = 100_000.0;

#[pyfunction]
#[pyo3(signature = (lat, h = 0.0))]
fn normal_gravity(
    #[pyo3(from_py_with = arg_lat)] lat: f64,
    #[pyo3(from_py_with = arg_h)] h: f64,
) -> PyResult<f64> {
    let h = finite_scalar(h, "h")?;
    // The Somigliana series with its second-order height term is a near-surface model.
    if h.abs() > MAX_GRAVITY_HEIGHT {
        return Err(invalid(
            "h",
            format!(
                "normal gravity holds within ±{MAX_GRAVITY_HEIGHT} m of the ellipsoid, got {h}"
            ),
        ));
    }
    Ok(earth::gravity(finite_scalar(lat, "lat")?, h))
}

#[pyfunction]
fn earth_radii(#[pyo3(from_py_with = arg_lat)] lat: f64) -> PyResult<(f64, f64)> {
    Ok(earth::radii(finite_scalar(lat, "lat")?))
}

#[pyfunction]
#[pyo3(signature = (imu, dt, lla0, vel0, rpy0))]
fn mechanize<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = arg_dt)] dt: f64,
    lla0: &Bound<'py, PyAny>,
    vel0: &Bound<'py, PyAny>,
    rpy0: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let samples = rows::<6>(imu, "imu")?;
    if let Some(i) = samples
        .iter()
        .position(|r| r.iter().any(|x| !x.is_finite()))
    {
        return Err(invalid("imu", format!("row {i} is not finite")));
    }
    if !(dt.is_finite() && dt > 0.0) {
        return Err(invalid("dt", format!("must be finite and > 0, got {dt}")));
    }
    let init = nav_state(
        fixed(lla0, "lla0")?,
        fixed(vel0, "vel0")?,
        fixed(rpy0, "rpy0")?,
    )?;
    let states = detached(py, move || Ok(integrate(&init, &samples, dt)))?;
    // Finite but absurd inputs (1e300 m/s², a 1e10 s step) overflow: say so, never NaN.
    if let Some(k) = states.iter().position(|s| {
        !(s.lla.iter().chain(s.vel.iter()).chain(s.dcm.iter())).all(|x| x.is_finite())
    }) {
        return Err(invalid(
            "imu, dt, lla0, vel0",
            format!("the mechanization overflows to non-finite values at sample {k}; the inputs are far outside any vehicle's range"),
        ));
    }
    let d = PyDict::new(py);
    nav_arrays(py, &d, &states)?;
    Ok(d)
}

// ---------------------------------------------------------------- configuration

/// EKF tuning (see `_core.pyi`).
#[pyclass(name = "FilterConfig", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PyFilterConfig {
    inner: FilterConfig,
}

#[pymethods]
impl PyFilterConfig {
    #[new]
    #[pyo3(signature = (*, p0_sigma = None, accel_bias_psd = 1e-3, gyro_bias_psd = 1e-3, dvl_variance = None, lever_arm = None, aiding = "body".to_string(), imu_dt = 0.01, innovation_gate = None))]
    #[allow(clippy::too_many_arguments)] // keyword-only, one per FilterConfig field
    fn new(
        p0_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_accel_bias_psd)] accel_bias_psd: f64,
        #[pyo3(from_py_with = arg_gyro_bias_psd)] gyro_bias_psd: f64,
        dvl_variance: Option<&Bound<'_, PyAny>>,
        lever_arm: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_aiding)] aiding: String,
        #[pyo3(from_py_with = arg_imu_dt)] imu_dt: f64,
        #[pyo3(from_py_with = arg_innovation_gate)] innovation_gate: Option<f64>,
    ) -> PyResult<Self> {
        let defaults = FilterConfig::default();
        let inner = FilterConfig {
            p0_sigma: match p0_sigma {
                Some(p) => fixed::<15>(p, "p0_sigma")?,
                None => defaults.p0_sigma,
            },
            accel_bias_psd,
            gyro_bias_psd,
            dvl_variance: match dvl_variance {
                Some(v) => fixed::<3>(v, "dvl_variance")?,
                None => defaults.dvl_variance,
            },
            lever_arm: match lever_arm {
                Some(v) => Vector3::from(fixed::<3>(v, "lever_arm")?),
                None => defaults.lever_arm,
            },
            aiding: match aiding.as_str() {
                "body" => Aiding::Body,
                "nav" => Aiding::Nav,
                other => {
                    return Err(invalid(
                        "aiding",
                        format!("must be \"body\" or \"nav\", got {other:?}"),
                    ))
                }
            },
            imu_dt,
            innovation_gate,
        };
        inner.validate().map_err(to_py_err)?;
        Ok(Self { inner })
    }
    #[getter]
    fn p0_sigma(&self) -> Vec<f64> {
        self.inner.p0_sigma.to_vec()
    }
    #[getter]
    fn accel_bias_psd(&self) -> f64 {
        self.inner.accel_bias_psd
    }
    #[getter]
    fn gyro_bias_psd(&self) -> f64 {
        self.inner.gyro_bias_psd
    }
    #[getter]
    fn dvl_variance(&self) -> Vec<f64> {
        self.inner.dvl_variance.to_vec()
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.inner.lever_arm.as_slice().to_vec()
    }
    #[getter]
    fn aiding(&self) -> &'static str {
        match self.inner.aiding {
            Aiding::Body => "body",
            Aiding::Nav => "nav",
        }
    }
    #[getter]
    fn imu_dt(&self) -> f64 {
        self.inner.imu_dt
    }
    #[getter]
    fn innovation_gate(&self) -> Option<f64> {
        self.inner.innovation_gate
    }
    fn __repr__(&self) -> String {
        format!(
            "FilterConfig(accel_bias_psd={}, gyro_bias_psd={}, dvl_variance={:?}, lever_arm={:?}, aiding={:?}, imu_dt={}, innovation_gate={})",
            self.inner.accel_bias_psd,
            self.inner.gyro_bias_psd,
            self.inner.dvl_variance,
            self.inner.lever_arm.as_slice(),
            self.aiding(),
            self.inner.imu_dt,
            self.inner
                .innovation_gate
                .map_or("None".to_string(), |g| g.to_string()),
        )
    }
}

/// A process-noise strategy (see `_core.pyi`).
#[pyclass(name = "Strategy", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PyStrategy {
    inner: StrategySpec,
}

#[pymethods]
impl PyStrategy {
    #[staticmethod]
    fn constant(q: &Bound<'_, PyAny>) -> PyResult<Self> {
        let spec = StrategySpec::Constant { q: fixed(q, "q")? };
        spec.validate().map_err(to_py_err)?;
        Ok(Self { inner: spec })
    }
    #[staticmethod]
    #[pyo3(signature = (window, prior_q))]
    fn mehra(
        #[pyo3(from_py_with = arg_window)] window: i64,
        prior_q: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        if window < 1 {
            return Err(invalid(
                "window",
                format!("must be at least 1, got {window}"),
            ));
        }
        let spec = StrategySpec::Mehra {
            window: window as usize,
            prior_q: fixed(prior_q, "prior_q")?,
        };
        spec.validate().map_err(to_py_err)?;
        Ok(Self { inner: spec })
    }
    #[staticmethod]
    fn external(prior_q: &Bound<'_, PyAny>) -> PyResult<Self> {
        let spec = StrategySpec::External {
            prior_q: fixed(prior_q, "prior_q")?,
        };
        spec.validate().map_err(to_py_err)?;
        Ok(Self { inner: spec })
    }
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner {
            StrategySpec::Constant { .. } => "constant",
            StrategySpec::Mehra { .. } => "mehra",
            StrategySpec::External { .. } => "external",
        }
    }
    #[getter]
    fn label(&self) -> String {
        self.inner.label()
    }
    /// q of a constant strategy, or the prior q of the others.
    #[getter]
    fn q(&self) -> Vec<f64> {
        match &self.inner {
            StrategySpec::Constant { q } => q.to_vec(),
            StrategySpec::Mehra { prior_q, .. } | StrategySpec::External { prior_q } => {
                prior_q.to_vec()
            }
        }
    }
    #[getter]
    fn window(&self) -> Option<usize> {
        match self.inner {
            StrategySpec::Mehra { window, .. } => Some(window),
            _ => None,
        }
    }
    fn __repr__(&self) -> String {
        format!("Strategy({:?})", self.inner)
    }
}

/// Simulated sensor models (see `_core.pyi`).
#[pyclass(name = "SensorConfig", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PySensorConfig {
    inner: SensorConfig,
}

#[pymethods]
impl PySensorConfig {
    #[new]
    #[pyo3(signature = (*, imu_variance = None, imu_variance_times = None, imu_bias = None, imu_bias_psd = None, dvl_variance = None, dvl_period = 1.0, lever_arm = None))]
    fn new(
        imu_variance: Option<&Bound<'_, PyAny>>,
        imu_variance_times: Option<&Bound<'_, PyAny>>,
        imu_bias: Option<&Bound<'_, PyAny>>,
        imu_bias_psd: Option<&Bound<'_, PyAny>>,
        dvl_variance: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_dvl_period)] dvl_period: f64,
        lever_arm: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let paper = SensorConfig::paper();
        let variance = match (imu_variance, imu_variance_times) {
            (None, None) => paper.imu.variance.clone(),
            (Some(v), None) => {
                VarianceSchedule::new(vec![0.0], vec![fixed::<6>(v, "imu_variance")?])
                    .map_err(to_py_err)?
            }
            (Some(v), Some(t)) => {
                let times = column(t, "imu_variance_times")?;
                let values = rows::<6>(v, "imu_variance")?;
                VarianceSchedule::new(times, values).map_err(to_py_err)?
            }
            (None, Some(_)) => {
                return Err(invalid("imu_variance_times", "given without imu_variance"))
            }
        };
        let inner = SensorConfig {
            imu: ImuErrorModel {
                variance,
                bias: match imu_bias {
                    Some(b) => fixed(b, "imu_bias")?,
                    None => [0.0; 6],
                },
                bias_rw_psd: match imu_bias_psd {
                    Some(b) => fixed(b, "imu_bias_psd")?,
                    None => [0.0; 6],
                },
            },
            dvl: DvlModel {
                variance: match dvl_variance {
                    Some(v) => fixed(v, "dvl_variance")?,
                    None => paper.dvl.variance,
                },
                period: dvl_period,
                lever_arm: match lever_arm {
                    Some(v) => Vector3::from(fixed::<3>(v, "lever_arm")?),
                    None => Vector3::zeros(),
                },
            },
        };
        inner.validate().map_err(to_py_err)?;
        Ok(Self { inner })
    }
    #[getter]
    fn imu_variance_times(&self) -> Vec<f64> {
        self.inner.imu.variance.times().to_vec()
    }
    #[getter]
    fn imu_variance<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        matrix(py, self.inner.imu.variance.values().iter().copied())
    }
    #[getter]
    fn imu_bias(&self) -> Vec<f64> {
        self.inner.imu.bias.to_vec()
    }
    #[getter]
    fn imu_bias_psd(&self) -> Vec<f64> {
        self.inner.imu.bias_rw_psd.to_vec()
    }
    #[getter]
    fn dvl_variance(&self) -> Vec<f64> {
        self.inner.dvl.variance.to_vec()
    }
    #[getter]
    fn dvl_period(&self) -> f64 {
        self.inner.dvl.period
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.inner.dvl.lever_arm.as_slice().to_vec()
    }
    fn __repr__(&self) -> String {
        format!("SensorConfig({:?})", self.inner)
    }
}

// ---------------------------------------------------------------- filter pass

#[pyfunction]
#[pyo3(signature = (imu, imu_time, dvl, dvl_time, *, t0, lla0, vel0, rpy0, config, strategy, bias0 = None, q_time = None, q = None))]
#[allow(clippy::too_many_arguments)]
fn run_filter<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    imu_time: &Bound<'py, PyAny>,
    dvl: &Bound<'py, PyAny>,
    dvl_time: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = arg_t0)] t0: f64,
    lla0: &Bound<'py, PyAny>,
    vel0: &Bound<'py, PyAny>,
    rpy0: &Bound<'py, PyAny>,
    config: &PyFilterConfig,
    strategy: &PyStrategy,
    bias0: Option<&Bound<'py, PyAny>>,
    q_time: Option<&Bound<'py, PyAny>>,
    q: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let imu = rows::<6>(imu, "imu")?;
    let (q_time, q_values) = match (q_time, q) {
        (Some(t), Some(v)) => (column(t, "q_time")?, rows::<6>(v, "q")?),
        (None, None) => (Vec::new(), Vec::new()),
        _ => {
            return Err(invalid(
                "q_time",
                "q_time and q go together: give both or neither",
            ))
        }
    };
    let imu_time = column(imu_time, "imu_time")?;
    let dvl = rows::<3>(dvl, "dvl")?;
    let dvl_time = column(dvl_time, "dvl_time")?;
    let init = nav_state(
        fixed(lla0, "lla0")?,
        fixed(vel0, "vel0")?,
        fixed(rpy0, "rpy0")?,
    )?;
    let bias0 = match bias0 {
        Some(b) => fixed::<6>(b, "bias0")?,
        None => [0.0; 6],
    };
    let cfg = config.inner.clone();
    let spec = strategy.inner.clone();
    let out: FilterOutput = detached(py, move || {
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            dvl: &dvl,
            dvl_time: &dvl_time,
            t0,
            q_time: &q_time,
            q_values: &q_values,
        };
        let mut strat = spec.build(cfg.bias_psd());
        filter_recorded(&data, init, bias0, &cfg, strat.as_mut())
    })?;
    let d = PyDict::new(py);
    d.set_item("time", out.time.clone().into_pyarray(py))?;
    nav_arrays(py, &d, &out.nav)?;
    d.set_item("bias", matrix(py, out.bias.iter().copied()))?;
    d.set_item("sigma", matrix(py, out.sigma.iter().copied()))?;
    let p = out.final_covariance;
    d.set_item(
        "covariance",
        Array2::from_shape_fn((15, 15), |(i, j)| p[(i, j)]).into_pyarray(py),
    )?;
    let m = out.updates.len();
    d.set_item(
        "dvl_epoch",
        Array1::from_iter(out.dvl_epoch.iter().map(|e| e.map_or(-1, |k| k as i64)))
            .into_pyarray(py),
    )?;
    let nan3 = [f64::NAN; 3];
    d.set_item(
        "innovation",
        matrix(
            py,
            out.updates
                .iter()
                .map(|u| u.as_ref().map_or(nan3, |u| u.innovation.into())),
        ),
    )?;
    d.set_item(
        "innovation_cov",
        Array3::from_shape_fn((m, 3, 3), |(k, i, j)| {
            out.updates[k].as_ref().map_or(f64::NAN, |u| u.s[(i, j)])
        })
        .into_pyarray(py),
    )?;
    d.set_item(
        "nis",
        Array1::from_iter(
            out.updates
                .iter()
                .map(|u| u.as_ref().map_or(f64::NAN, |u| u.nis)),
        )
        .into_pyarray(py),
    )?;
    d.set_item(
        "accepted",
        Array1::from_iter(
            out.updates
                .iter()
                .map(|u| u.as_ref().is_some_and(|u| u.accepted)),
        )
        .into_pyarray(py),
    )?;
    d.set_item("diverged_at", out.nis_monitor.diverged_at)?;
    d.set_item(
        "gain",
        Array3::from_shape_fn((m, 15, 3), |(k, i, j)| {
            out.updates[k].as_ref().map_or(f64::NAN, |u| u.gain[(i, j)])
        })
        .into_pyarray(py),
    )?;
    d.set_item(
        "adaptive_q",
        Array3::from_shape_fn((m, 15, 15), |(k, i, j)| {
            out.adaptive_q[k].map_or(f64::NAN, |q| q[(i, j)])
        })
        .into_pyarray(py),
    )?;
    Ok(d)
}

// ---------------------------------------------------------------- Monte Carlo

fn scenario(
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

fn options(n_runs: i64, seed: u64, record_every: i64, first_run: u64) -> PyResult<McOptions> {
    if n_runs < 1 {
        return Err(invalid(
            "n_runs",
            format!("must be at least 1, got {n_runs}"),
        ));
    }
    if record_every < 0 {
        return Err(invalid(
            "record_every",
            format!("must be >= 0 IMU steps, got {record_every}"),
        ));
    }
    Ok(McOptions {
        n_runs: n_runs as usize,
        seed,
        record_every: record_every as usize,
        first_run,
    })
}

fn threads_arg(threads: Option<i64>) -> PyResult<Option<usize>> {
    match threads {
        None => Ok(None),
        Some(n) if (1..=MAX_THREADS as i64).contains(&n) => Ok(Some(n as usize)),
        Some(n) => Err(invalid(
            "threads",
            format!("must be 1 to {MAX_THREADS}, got {n}"),
        )),
    }
}

fn result_dict<'py>(py: Python<'py>, res: &McResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = res.runs.len();
    let col = |f: &dyn Fn(&crate::montecarlo::RunSummary) -> f64| {
        Array1::from_iter(res.runs.iter().map(|r| f(&r.summary)))
    };
    d.set_item("srmse", col(&|s| s.srmse).into_pyarray(py))?;
    d.set_item("smae", col(&|s| s.smae).into_pyarray(py))?;
    d.set_item(
        "final_horizontal_error",
        col(&|s| s.final_horizontal_error).into_pyarray(py),
    )?;
    d.set_item(
        "max_horizontal_error",
        col(&|s| s.max_horizontal_error).into_pyarray(py),
    )?;
    d.set_item("mean_nis", col(&|s| s.mean_nis).into_pyarray(py))?;
    d.set_item(
        "rejected_updates",
        Array1::from_iter(res.runs.iter().map(|r| r.summary.rejected_updates as i64))
            .into_pyarray(py),
    )?;
    d.set_item(
        "diverged_at",
        col(&|s| s.diverged_at.unwrap_or(f64::NAN)).into_pyarray(py),
    )?;
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
        let r = res.record_time.len();
        d.set_item("record_time", res.record_time.clone().into_pyarray(py))?;
        let hist = |i: usize| {
            res.runs[i]
                .history
                .as_ref()
                .expect("history recorded when record_time is set")
        };
        d.set_item(
            "error",
            Array3::from_shape_fn((n, r, 15), |(i, k, s)| hist(i).error[k][s]).into_pyarray(py),
        )?;
        d.set_item(
            "sigma",
            Array3::from_shape_fn((n, r, 15), |(i, k, s)| hist(i).sigma[k][s]).into_pyarray(py),
        )?;
        d.set_item(
            "q",
            Array3::from_shape_fn((n, r, 6), |(i, k, s)| hist(i).imu_variance[k][s])
                .into_pyarray(py),
        )?;
    }
    Ok(d)
}

#[pyfunction(name = "monte_carlo")]
#[pyo3(signature = (trajectory, sensors, config, strategy, *, n_runs, seed = 0, record_every = 0, sample_initial_error = true, threads = None, first_run = 0))]
#[allow(clippy::too_many_arguments)]
fn py_monte_carlo<'py>(
    py: Python<'py>,
    trajectory: &PyTrajectory,
    sensors: &PySensorConfig,
    config: &PyFilterConfig,
    strategy: &PyStrategy,
    #[pyo3(from_py_with = arg_n_runs)] n_runs: i64,
    #[pyo3(from_py_with = arg_seed)] seed: u64,
    #[pyo3(from_py_with = arg_record_every)] record_every: i64,
    #[pyo3(from_py_with = arg_sample_initial_error)] sample_initial_error: bool,
    #[pyo3(from_py_with = arg_threads)] threads: Option<i64>,
    #[pyo3(from_py_with = arg_first_run)] first_run: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = options(n_runs, seed, record_every, first_run)?;
    let threads = threads_arg(threads)?;
    let sc = scenario(trajectory, sensors, sample_initial_error);
    let (cfg, spec) = (config.inner.clone(), strategy.inner.clone());
    let res = detached(py, move || {
        with_threads(threads, || run_monte_carlo(&sc, &cfg, &spec, &opts))?
    })?;
    result_dict(py, &res)
}

/// Lockstep ensemble for outside tuning (see `_core.pyi`).
#[pyclass(name = "Ensemble", module = "pronet._core")]
pub struct PyEnsemble {
    inner: Arc<Mutex<Option<Ensemble>>>,
    pool: Option<Arc<rayon::ThreadPool>>,
    n_runs: usize,
    window: usize,
}

impl PyEnsemble {
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Ensemble) -> CoreResult<T> + Send,
    ) -> PyResult<T> {
        let inner = Arc::clone(&self.inner);
        let pool = self.pool.clone();
        detached(py, move || {
            let mut guard = inner.lock().map_err(|_| {
                Error::Numerical("ensemble state poisoned by an earlier failure".into())
            })?;
            let ens = guard.as_mut().ok_or_else(|| {
                Error::invalid("ensemble", "already finished; create a new Ensemble")
            })?;
            match pool {
                Some(p) => p.install(|| f(ens)),
                None => f(ens),
            }
        })
    }
}

#[pymethods]
impl PyEnsemble {
    #[new]
    #[pyo3(signature = (trajectory, sensors, config, prior_q, *, n_runs, seed = 0, window = 200, tuning_period = 1.0, record_every = 0, sample_initial_error = true, threads = None, first_run = 0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        trajectory: &PyTrajectory,
        sensors: &PySensorConfig,
        config: &PyFilterConfig,
        prior_q: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arg_n_runs)] n_runs: i64,
        #[pyo3(from_py_with = arg_seed)] seed: u64,
        #[pyo3(from_py_with = arg_window)] window: i64,
        #[pyo3(from_py_with = arg_tuning_period)] tuning_period: f64,
        #[pyo3(from_py_with = arg_record_every)] record_every: i64,
        #[pyo3(from_py_with = arg_sample_initial_error)] sample_initial_error: bool,
        #[pyo3(from_py_with = arg_threads)] threads: Option<i64>,
        #[pyo3(from_py_with = arg_first_run)] first_run: u64,
    ) -> PyResult<Self> {
        let opts = options(n_runs, seed, record_every, first_run)?;
        let prior_q = fixed::<6>(prior_q, "prior_q")?;
        if window < 1 {
            return Err(invalid(
                "window",
                format!("must be at least 1 sample, got {window}"),
            ));
        }
        let dt = trajectory.truth.dt;
        if !(tuning_period.is_finite() && tuning_period >= dt) {
            return Err(invalid(
                "tuning_period",
                format!("must be finite and at least one IMU period ({dt} s), got {tuning_period}"),
            ));
        }
        let tuning_every = (tuning_period / dt).round() as usize;
        let pool = match threads_arg(threads)? {
            None => None,
            Some(n) => Some(Arc::new(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| invalid("threads", format!("cannot start {n} threads: {e}")))?,
            )),
        };
        let sc = scenario(trajectory, sensors, sample_initial_error);
        let cfg = config.inner.clone();
        let window = window as usize;
        let ens = detached(py, move || {
            Ensemble::new(sc, &cfg, prior_q, &opts, window, tuning_every)
        })?;
        Ok(Self {
            inner: Arc::new(Mutex::new(Some(ens))),
            pool,
            n_runs: opts.n_runs,
            window,
        })
    }

    /// Step all runs to the next tuning instant; the windows `(n_runs, 6, window)`
    /// float32, or None at the end.
    fn advance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, numpy::PyArray3<f32>>>> {
        let out = self.with(py, |e| Ok(e.advance()))?;
        Ok(out.map(|flat| {
            Array3::from_shape_vec((self.n_runs, 6, self.window), flat)
                .expect("n_runs*6*window values by construction")
                .into_pyarray(py)
        }))
    }

    /// Set each run's IMU variances, `q` of shape (n_runs, 6), float64.
    fn set_q(&self, py: Python<'_>, q: &Bound<'_, PyAny>) -> PyResult<()> {
        let q = rows::<6>(q, "q")?;
        self.with(py, move |e| e.set_q(&q))
    }

    /// Run to the end and return the results (as `monte_carlo`). The ensemble cannot be
    /// used afterwards.
    fn finish<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = Arc::clone(&self.inner);
        let pool = self.pool.clone();
        let res = detached(py, move || {
            let ens = inner
                .lock()
                .map_err(|_| {
                    Error::Numerical("ensemble state poisoned by an earlier failure".into())
                })?
                .take()
                .ok_or_else(|| Error::invalid("ensemble", "already finished"))?;
            Ok(match pool {
                Some(p) => p.install(|| ens.finish()),
                None => ens.finish(),
            })
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
        self.with(py, |e| Ok(e.steps()))
    }
    /// Current time [s].
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |e| Ok(e.time()))
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

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<PyTrajectory>()?;
    m.add_class::<PyFilterConfig>()?;
    m.add_class::<PyStrategy>()?;
    m.add_class::<PySensorConfig>()?;
    m.add_class::<PyEnsemble>()?;
    m.add_function(wrap_pyfunction!(builtin_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_trajectory_names, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory_from_segments, m)?)?;
    m.add_function(wrap_pyfunction!(normal_gravity, m)?)?;
    m.add_function(wrap_pyfunction!(earth_radii, m)?)?;
    m.add_function(wrap_pyfunction!(mechanize, m)?)?;
    m.add_function(wrap_pyfunction!(run_filter, m)?)?;
    m.add_function(wrap_pyfunction!(py_monte_carlo, m)?)?;
    Ok(())
}
