//! What the stream constructors share: the forms of σ (one for every row or one per
//! row), a lever arm, the check of a made stream with its errors named after the
//! constructor's arguments, and the pieces of a `__repr__`.

use crate::error::Error;
use crate::python::call::{invalid, to_py_err};
use crate::python::convert::{column, describe, fixed, is_real_number, real_arg, real_array, rows};
use crate::recorded::{PerRow, Stream};
use numpy::ndarray::{Ix1, Ix2};
use pyo3::prelude::*;

/// A value given once for every row, or once per row (owned: see [`PerRow`]).
pub(super) enum Rows<T> {
    One(T),
    Each(Vec<T>),
}

impl<T: Copy> Rows<T> {
    pub(super) fn per_row(&self) -> PerRow<'_, T> {
        match self {
            Rows::One(v) => PerRow::One(*v),
            Rows::Each(v) => PerRow::Each(v),
        }
    }

    pub(super) fn rows(&self) -> &[T] {
        match self {
            Rows::One(v) => std::slice::from_ref(v),
            Rows::Each(v) => v,
        }
    }
}

/// `obj` as one real number (not an array of any shape: `real_arg` would take a
/// one-element array), or None.
pub(super) fn number(obj: &Bound<'_, PyAny>, arg: &str) -> Option<f64> {
    let ndim = obj.getattr("ndim").and_then(|n| n.extract::<usize>());
    (is_real_number(obj) && ndim.unwrap_or(0) == 0)
        .then(|| real_arg(obj, arg).ok())
        .flatten()
}

/// A 1σ of 3 axes: a number (with `scalar`), `(3,)`, or `(n, 3)` one per row.
pub(super) fn sigma3(obj: &Bound<'_, PyAny>, scalar: bool, unit: &str) -> PyResult<Rows<[f64; 3]>> {
    if let Some(arr) = real_array::<f64, Ix1>(obj, "float64")? {
        let v = arr.as_array();
        if v.len() == 3 {
            return Ok(Rows::One([v[0], v[1], v[2]]));
        }
    } else if real_array::<f64, Ix2>(obj, "float64")?.is_some() {
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

/// A 1σ \[`unit`\] of one axis: a number, or `(n,)` one per row.
pub(super) fn sigma1(obj: &Bound<'_, PyAny>, unit: &str) -> PyResult<Rows<f64>> {
    if real_array::<f64, Ix1>(obj, "float64")?.is_some() {
        return Ok(Rows::Each(column(obj, "sigma")?));
    }
    if let Some(s) = number(obj, "sigma") {
        return Ok(Rows::One(s));
    }
    Err(invalid(
        "sigma",
        format!(
            "expected a number or (n,) real numbers [{unit}], got {}",
            describe(obj)
        ),
    ))
}

/// A lever arm \[m\]: 3 numbers (the stream's check bounds them).
pub(super) fn lever_arm(obj: &Bound<'_, PyAny>) -> PyResult<[f64; 3]> {
    fixed::<3>(obj, "lever_arm")
}

pub(super) fn lever_arm_or_zero(obj: Option<&Bound<'_, PyAny>>) -> PyResult<[f64; 3]> {
    obj.map_or(Ok([0.0; 3]), lever_arm)
}

/// A core error about a stream named after its values' argument `values` raised
/// naming the constructor's argument: its arrays `{values}_time`, `{values}_sigma`
/// (`depth_sigma` for a depth's one σ), `{values}_gate` and `{values}_lever_arm` are
/// `time`, `sigma`, `gate` and `lever_arm`.
pub(super) fn renamed(e: Error, values: &str) -> PyErr {
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
pub(super) fn check(stream: &Stream<'_>) -> PyResult<()> {
    stream.validate().map_err(|e| renamed(e, &stream.name))
}

/// `[first, last]` of `time` for a `__repr__`.
pub(super) fn span(time: &[f64]) -> String {
    match (time.first(), time.last()) {
        (Some(a), Some(_)) if time.len() == 1 => format!("1 row at {a} s"),
        (Some(a), Some(b)) => format!("{} rows over [{a}, {b}] s", time.len()),
        _ => "0 rows".into(),
    }
}

pub(super) fn option_text<T: std::fmt::Debug>(value: Option<T>) -> String {
    value.map_or("None".into(), |v| format!("{v:?}"))
}

/// Rows of a per-row value for a `__repr__`: the one value, or the shape.
pub(super) fn rows_text<T: std::fmt::Debug>(rows: &Rows<T>, width: &str) -> String {
    match rows {
        Rows::One(v) => format!("{v:?}"),
        Rows::Each(v) => format!("({}{width}) per row", v.len()),
    }
}
