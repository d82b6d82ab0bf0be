//! Python bindings (`pronet._core`), one file per exposed type or function family. Each
//! entry point converts its arguments (types and shapes: [`convert`]), calls the core
//! without the GIL ([`detached`]) and maps the error: every core error becomes a
//! `ValueError` that starts with the offending argument's name; a Rust panic (a bug) is
//! caught and raised as `RuntimeError`, never as a `PanicException`. The domain rules
//! (latitude, gravity height, overflow, tuning instants, counts) live in the core.

mod clocks;
mod config;
mod convert;
mod convnet;
mod ensemble;
mod filter;
mod hcf;
mod montecarlo;
mod navigation;
mod sensors;
mod strategy;
mod trajectory;

use crate::error::Error;
use crate::Result as CoreResult;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};

fn to_py_err(e: Error) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn invalid(arg: &str, reason: impl Into<String>) -> PyErr {
    to_py_err(Error::invalid(arg, reason))
}

/// The message of a caught panic.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown panic".into())
}

fn internal_error(payload: &(dyn std::any::Any + Send)) -> PyErr {
    PyRuntimeError::new_err(format!(
        "internal error in pronet core (please report): {}",
        panic_message(payload)
    ))
}

/// Run `f` without the GIL, turning core errors into `ValueError` and a panic into
/// `RuntimeError`.
fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> CoreResult<T> + Send) -> PyResult<T> {
    match py.detach(|| catch_unwind(AssertUnwindSafe(f))) {
        Ok(result) => result.map_err(to_py_err),
        Err(payload) => Err(internal_error(payload.as_ref())),
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_THREADS", crate::montecarlo::MAX_THREADS)?;
    m.add("MAX_RUN_INDEX", crate::montecarlo::MAX_RUN_INDEX)?;
    m.add("MAX_GRAVITY_HEIGHT", crate::earth::MAX_GRAVITY_HEIGHT)?;
    m.add("MAX_LATITUDE_DEG", crate::earth::MAX_LATITUDE_DEG)?;
    trajectory::register(m)?;
    navigation::register(m)?;
    config::register(m)?;
    strategy::register(m)?;
    sensors::register(m)?;
    filter::register(m)?;
    montecarlo::register(m)?;
    ensemble::register(m)?;
    convnet::register(m)?;
    clocks::register(m)?;
    hcf::register(m)?;
    Ok(())
}
