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

use crate::cancel::Cancel;
use crate::error::Error;
use crate::Result as CoreResult;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

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

/// How often a waiting [`interruptible`] call runs Python's signal handlers.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// [`detached`] for long calls that signals must be able to end: the work runs on a
/// scoped thread while the calling thread waits without the GIL and, every
/// [`SIGNAL_POLL`], takes the GIL to run Python's signal handlers. When a handler
/// raises (Ctrl-C's `KeyboardInterrupt`, the CLI's SIGTERM handler), the core is asked
/// to stop at its next check ([`Cancel`]) and that exception is raised once it has.
/// Handlers run on the main thread only, so from another Python thread this is
/// [`detached`] with one more thread.
fn interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce(&Cancel) -> CoreResult<T> + Send,
) -> PyResult<T> {
    let cancel = Cancel::default();
    let done = AtomicBool::new(false);
    let mut raised: Option<PyErr> = None;
    let outcome = py.detach(|| {
        std::thread::scope(|scope| {
            let waiter = std::thread::current();
            let cancel = &cancel;
            // Set before the worker wakes the waiter: `is_finished` turns true only once
            // the thread has exited, a moment after the wake-up, and a waiter that read
            // it too early slept a whole poll (50 ms per call) before seeing the result.
            let done = &done;
            let worker = scope.spawn(move || {
                let out = catch_unwind(AssertUnwindSafe(|| f(cancel)));
                done.store(true, Ordering::Release);
                waiter.unpark();
                out
            });
            while !done.load(Ordering::Acquire) {
                std::thread::park_timeout(SIGNAL_POLL);
                if raised.is_none() && !done.load(Ordering::Acquire) {
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        raised = Some(e);
                        cancel.cancel();
                    }
                }
            }
            worker.join()
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    match outcome {
        Ok(Ok(result)) => result.map_err(to_py_err),
        Ok(Err(payload)) | Err(payload) => Err(internal_error(payload.as_ref())),
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // Load NumPy's C API now, at import: loaded lazily by the first array a call
    // returns, it runs Python code that a pending Ctrl-C would interrupt, and
    // rust-numpy panics when that happens.
    numpy::PyArray1::<f64>::zeros(m.py(), [0], false);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_THREADS", crate::threads::MAX_THREADS)?;
    m.add("THREADS_PER_CORE", crate::threads::THREADS_PER_CORE)?;
    m.add("THREADS_ENV", crate::threads::THREADS_ENV)?;
    m.add("MAX_LEVER_ARM", crate::sensors::MAX_LEVER_ARM)?;
    m.add("MAX_RUN_INDEX", crate::montecarlo::MAX_RUN_INDEX)?;
    m.add("MAX_GRAVITY_HEIGHT", crate::earth::MAX_GRAVITY_HEIGHT)?;
    m.add("MAX_LATITUDE_DEG", crate::earth::MAX_LATITUDE_DEG)?;
    m.add("LONGITUDE_RANGE_DEG", crate::earth::LONGITUDE_RANGE_DEG)?;
    m.add("WGS84_A", crate::earth::A)?;
    m.add("WGS84_F", crate::earth::F)?;
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
