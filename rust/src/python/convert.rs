//! Argument converters: each takes a Python object and the argument's name and returns
//! the Rust value, or a `ValueError` naming the argument. They check types and shapes
//! only (and finiteness of fixed-size vectors); the core checks the values.

use super::call::invalid;
use crate::attitude::{dcm_from_euler, euler_from_dcm};
use crate::mechanization::NavState;
use crate::pages::vec_with_capacity;
use nalgebra::Vector3;
use numpy::ndarray::{Array2, Dimension, Ix1, Ix2};
use numpy::{
    Element, IntoPyArray, PyArray1, PyArray2, PyReadonlyArray, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyDict, PyFloat, PyInt, PyString};
use std::borrow::Cow;

/// The type (and for arrays dtype and shape) of `obj`, for error messages.
pub fn describe(obj: &Bound<'_, PyAny>) -> String {
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

/// `obj` as a read-only NumPy array of `T` (named `dtype`, e.g. "float64") with `D`'s
/// number of axes, whatever form the numbers come in (the one argument rule: a sequence
/// and an array are accepted alike): an array of that dtype as it is (no copy), else
/// anything NumPy reads as integers (and, for a float `dtype`, floats) of any width,
/// nested lists and tuples included, converted by `numpy.asarray(obj).astype(dtype)`.
/// None for anything else: booleans, complex numbers, strings, objects, ragged
/// sequences, another number of axes. A conversion that runs out of memory is the
/// `MemoryError` it raised (not "expected real numbers").
pub fn real_array<'py, T: Element, D: Dimension>(
    obj: &Bound<'py, PyAny>,
    dtype: &str,
) -> PyResult<Option<PyReadonlyArray<'py, T, D>>> {
    if let Ok(arr) = obj.extract::<PyReadonlyArray<T, D>>() {
        return Ok(Some(arr));
    }
    if obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
    {
        return Ok(None);
    }
    let kinds: &[&str] = if dtype.starts_with("float") {
        &["i", "u", "f"]
    } else {
        &["i", "u"]
    };
    let py = obj.py();
    // Only a MemoryError is an error; any other failure means "not real numbers".
    let memory = |e: PyErr| e.is_instance_of::<PyMemoryError>(py).then_some(e);
    let numpy = py.import("numpy")?;
    let arr = match numpy.call_method1("asarray", (obj,)) {
        Ok(arr) => arr,
        Err(e) => return memory(e).map_or(Ok(None), Err),
    };
    if !numpy_kind_in(&arr, kinds) {
        return Ok(None);
    }
    match arr.call_method1("astype", (dtype,)) {
        Ok(converted) => Ok(converted.extract().ok()),
        Err(e) => memory(e).map_or(Ok(None), Err),
    }
}

/// Real numbers of shape (n, C) as rows (a copy: `MemoryError` where it does not fit).
pub fn rows<const C: usize>(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<[f64; C]>> {
    owned(as_rows::<C>(&readonly_rows::<C>(obj, arg)?), arg)
}

/// `values` (of the argument `arg`) owned: a borrowed slice copied into room taken
/// first (`MemoryError` where it does not fit, never an abort).
fn owned<T: Clone>(values: Cow<'_, [T]>, arg: &str) -> PyResult<Vec<T>> {
    match values {
        Cow::Owned(values) => Ok(values),
        Cow::Borrowed(values) => {
            let mut out = room::<T>(values.len(), arg)?;
            out.extend_from_slice(values);
            Ok(out)
        }
    }
}

/// The rows of an array checked by [`readonly_rows`]: borrowed when it is C-contiguous
/// (what the Python layer passes), copied otherwise. Borrowing matters for long inputs:
/// copying eight million IMU rows took 0.6–0.9 s here, with the GIL held and so with
/// Ctrl-C unseen. Like NumPy's own GIL-free loops, a call reading a borrowed array
/// assumes no other Python thread writes into it meanwhile.
pub fn as_rows<'a, const C: usize>(arr: &'a PyReadonlyArray2<'_, f64>) -> Cow<'a, [[f64; C]]> {
    // `as_slice` alone would also take a Fortran-ordered array, whose memory runs
    // column by column.
    match arr.as_slice() {
        Ok(flat) if arr.is_c_contiguous() => Cow::Borrowed(flat.as_chunks::<C>().0),
        _ => Cow::Owned(
            arr.as_array()
                .outer_iter()
                .map(|r| std::array::from_fn(|j| r[j]))
                .collect(),
        ),
    }
}

/// `obj` as a read-only float64 array of shape (n, C) ([`real_array`]), or a
/// `ValueError` naming `arg`.
pub fn readonly_rows<'py, const C: usize>(
    obj: &Bound<'py, PyAny>,
    arg: &str,
) -> PyResult<PyReadonlyArray2<'py, f64>> {
    let arr = real_array::<f64, Ix2>(obj, "float64")?.ok_or_else(|| {
        invalid(
            arg,
            format!(
                "expected real numbers of shape (n, {C}) (an array or nested lists), got {}",
                describe(obj)
            ),
        )
    })?;
    let shape = arr.as_array().shape().to_vec();
    if shape[1] != C {
        return Err(invalid(
            arg,
            format!("expected shape (n, {C}), got {shape:?}"),
        ));
    }
    Ok(arr)
}

/// Real numbers of shape (n,) (a copy: `MemoryError` where it does not fit).
pub fn column(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<f64>> {
    owned(as_values(&readonly_column(obj, arg)?), arg)
}

/// The values of an array checked by [`readonly_column`]: borrowed when contiguous,
/// copied otherwise (see [`as_rows`]).
pub fn as_values<'a>(arr: &'a PyReadonlyArray1<'_, f64>) -> Cow<'a, [f64]> {
    match arr.as_slice() {
        Ok(values) => Cow::Borrowed(values),
        Err(_) => Cow::Owned(arr.as_array().to_vec()),
    }
}

/// `obj` as a read-only float64 array of shape (n,) ([`real_array`]), or a
/// `ValueError` naming `arg`.
pub fn readonly_column<'py>(
    obj: &Bound<'py, PyAny>,
    arg: &str,
) -> PyResult<PyReadonlyArray1<'py, f64>> {
    real_array::<f64, Ix1>(obj, "float64")?.ok_or_else(|| {
        invalid(
            arg,
            format!(
                "expected real numbers of shape (n,) (an array or a list), got {}",
                describe(obj)
            ),
        )
    })
}

/// Whether `obj` is a real number: a Python int or float (not a bool), or a NumPy value
/// of integer or float dtype. Extraction to f64 alone would let bools through as 1.0 and
/// drop the imaginary part of complex NumPy values.
pub fn is_real_number(obj: &Bound<'_, PyAny>) -> bool {
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
pub fn fixed<const N: usize>(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<[f64; N]> {
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

/// `fixed` for an optional argument, `default` when it is not given.
pub fn fixed_or<const N: usize>(
    obj: Option<&Bound<'_, PyAny>>,
    arg: &str,
    default: [f64; N],
) -> PyResult<[f64; N]> {
    obj.map_or(Ok(default), |o| fixed(o, arg))
}

/// A real scalar argument (an int or float, NumPy's included; never a bool, a string or
/// a complex), or `ValueError` naming it. pyo3's own f64 extraction would raise
/// `TypeError` for a string and take `True` as 1.0.
pub fn real_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<f64> {
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

/// The unsigned integer types a whole-number argument converts to.
pub trait Whole: TryFrom<u128> {
    const MAX: u128;
}
impl Whole for u64 {
    const MAX: u128 = u64::MAX as u128;
}
impl Whole for usize {
    const MAX: u128 = usize::MAX as u128;
}

/// A whole-number argument in `0..=T::MAX` (an int, NumPy's included, never a bool or a
/// float), or `ValueError` naming it (pyo3 would raise `TypeError`/`OverflowError`).
pub fn whole_arg<T: Whole>(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<T> {
    let is_int = !obj.is_instance_of::<PyBool>()
        && (obj.is_instance_of::<PyInt>() || numpy_kind_in(obj, &["i", "u"]));
    if !is_int {
        return Err(invalid(
            arg,
            format!("expected a whole number, got {}", describe(obj)),
        ));
    }
    let text = obj.str().map(|s| s.to_string()).unwrap_or_default();
    if obj.extract::<i128>().is_ok_and(|v| v < 0) {
        return Err(invalid(arg, format!("must be >= 0, got {text}")));
    }
    obj.extract::<u128>()
        .ok()
        .filter(|v| *v <= T::MAX)
        .and_then(|v| T::try_from(v).ok())
        .ok_or_else(|| invalid(arg, format!("must be at most {}, got {text}", T::MAX)))
}

/// `True`/`False` (NumPy's included), or `ValueError` naming the argument: a string such
/// as "no" or a number is not silently taken as a truth value.
pub fn flag_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<bool> {
    let refuse = || {
        invalid(
            arg,
            format!("expected True or False, got {}", describe(obj)),
        )
    };
    if !(obj.is_instance_of::<PyBool>() || numpy_kind_in(obj, &["b"])) {
        return Err(refuse());
    }
    obj.extract::<bool>().map_err(|_| refuse())
}

pub fn text_arg(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<String> {
    obj.extract::<String>()
        .map_err(|_| invalid(arg, format!("expected a string, got {}", describe(obj))))
}

/// `from_py_with` converters, one per argument name, so that the error names it.
macro_rules! arg_converters {
    ($($fn_name:ident: $t:ty = $conv:ident($name:literal);)*) => {
        $(pub fn $fn_name(obj: &Bound<'_, PyAny>) -> PyResult<$t> {
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
    arg_covariance_step: f64 = real_arg("covariance_step");
    arg_dvl_period: f64 = real_arg("dvl_period");
    arg_tuning_period: f64 = real_arg("tuning_period");
    arg_aiding: String = text_arg("aiding");
    arg_formulation: String = text_arg("formulation");
    arg_epochs: String = text_arg("epochs");
    arg_precision: String = text_arg("precision");
    arg_window: usize = whole_arg("window");
    arg_n_runs: usize = whole_arg("n_runs");
    arg_n_samples: usize = whole_arg("n_samples");
    arg_record_every: usize = whole_arg("record_every");
    arg_seed: u64 = whole_arg("seed");
    arg_first_run: u64 = whole_arg("first_run");
    arg_sample_initial_error: bool = flag_arg("sample_initial_error");
    arg_smooth: bool = flag_arg("smooth");
    arg_dvl_calibration: bool = flag_arg("dvl_calibration");
    arg_heading_second_order: bool = flag_arg("heading_second_order");
    arg_dvl_scale: f64 = real_arg("dvl_scale");
}

/// An optional real argument (None stays None).
fn optional_real(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Option<f64>> {
    if obj.is_none() {
        return Ok(None);
    }
    real_arg(obj, arg).map(Some)
}

arg_converters! {
    arg_dvl_scale_sigma: Option<f64> = optional_real("dvl_scale_sigma");
    arg_dvl_scale_psd: Option<f64> = optional_real("dvl_scale_psd");
    arg_dvl_misalignment_psd: Option<f64> = optional_real("dvl_misalignment_psd");
    arg_dvl_bias_time_constant: Option<f64> = optional_real("dvl_bias_time_constant");
    arg_depth_period: Option<f64> = optional_real("depth_period");
    arg_heading_period: Option<f64> = optional_real("heading_period");
}

pub fn arg_innovation_gate(obj: &Bound<'_, PyAny>) -> PyResult<Option<f64>> {
    optional_real(obj, "innovation_gate")
}

pub fn arg_threads(obj: &Bound<'_, PyAny>) -> PyResult<Option<usize>> {
    if obj.is_none() {
        return Ok(None);
    }
    whole_arg(obj, "threads").map(Some)
}

/// A navigation state from `lla0`, `vel0`, `rpy0` (3 finite numbers each).
pub fn nav_state(
    lla0: &Bound<'_, PyAny>,
    vel0: &Bound<'_, PyAny>,
    rpy0: &Bound<'_, PyAny>,
) -> PyResult<NavState> {
    let (lla, vel, rpy) = (
        fixed::<3>(lla0, "lla0")?,
        fixed::<3>(vel0, "vel0")?,
        fixed::<3>(rpy0, "rpy0")?,
    );
    Ok(NavState {
        lla: Vector3::from(lla),
        vel: Vector3::from(vel),
        dcm: dcm_from_euler(rpy[0], rpy[1], rpy[2]),
    })
}

/// Rows of C values as a float64 array of shape (n, C); `MemoryError` where they do
/// not fit (the room is taken before any row is written).
pub fn matrix<const C: usize>(
    py: Python<'_>,
    rows: impl ExactSizeIterator<Item = [f64; C]>,
) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let mut out = room::<[f64; C]>(rows.len(), "an array")?;
    out.extend(rows);
    Ok(Array2::from(out).into_pyarray(py))
}

/// A copy of `values` as a float64 array; `MemoryError` where it does not fit.
pub fn vector<'py>(py: Python<'py>, values: &[f64]) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let mut out = room::<f64>(values.len(), "an array")?;
    out.extend_from_slice(values);
    Ok(out.into_pyarray(py))
}

/// An empty vector with room for `n` values, or a `MemoryError` naming `what` (never
/// an abort).
fn room<T>(n: usize, what: &str) -> PyResult<Vec<T>> {
    let mut out = Vec::new();
    out.try_reserve_exact(n).map_err(|_| {
        let mib = n as f64 * std::mem::size_of::<T>() as f64 / f64::from(1u32 << 20);
        PyMemoryError::new_err(format!("{what}: {mib:.1} MiB do not fit in memory"))
    })?;
    Ok(out)
}

/// Rows of C values as an owned (n, C) array, built without Python (so without the
/// GIL where the caller has released it); handing it to Python does not copy it.
pub fn rows_array<const C: usize>(rows: impl ExactSizeIterator<Item = [f64; C]>) -> Array2<f64> {
    let mut v = vec_with_capacity(rows.len());
    v.extend(rows);
    Array2::from(v)
}

/// `lla`, `vel` and `rpy` arrays of the states into `d`.
pub fn nav_arrays<'py>(
    py: Python<'py>,
    d: &Bound<'py, PyDict>,
    states: &[NavState],
) -> PyResult<()> {
    d.set_item("lla", matrix(py, states.iter().map(|s| s.lla.into()))?)?;
    d.set_item("vel", matrix(py, states.iter().map(|s| s.vel.into()))?)?;
    d.set_item(
        "rpy",
        matrix(py, states.iter().map(|s| euler_from_dcm(&s.dcm).into()))?,
    )?;
    Ok(())
}

/// Windows `(n, window)` of dtype `T` (named `dtype`; other real numbers are converted
/// to it, [`real_array`]) as one row-major vector (a copy: `MemoryError` where it does
/// not fit).
pub fn window_rows<T: Element + Copy>(
    obj: &Bound<'_, PyAny>,
    window: usize,
    dtype: &str,
) -> PyResult<Vec<T>> {
    let w: PyReadonlyArray2<T> = real_array(obj, dtype)?.ok_or_else(|| {
        invalid(
            "windows",
            format!(
                "expected real numbers of shape (n, {window}) (taken as {dtype}), got {}",
                describe(obj)
            ),
        )
    })?;
    let view = w.as_array();
    if view.ncols() != window {
        return Err(invalid(
            "windows",
            format!("expected shape (n, {window}), got {:?}", view.shape()),
        ));
    }
    let mut out = room::<T>(view.len(), "windows")?;
    match view.as_slice() {
        Some(s) => out.extend_from_slice(s),
        None => out.extend(view.iter().copied()),
    }
    Ok(out)
}
