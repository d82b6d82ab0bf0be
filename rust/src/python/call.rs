//! How a binding calls the core: without the GIL (interruptible by a signal where the
//! call is long), a core error mapped to a `ValueError` and a panic to a `RuntimeError`.

use crate::cancel::Cancel;
use crate::error::Error;
use crate::Result as CoreResult;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pub(super) fn to_py_err(e: Error) -> PyErr {
    PyValueError::new_err(e.to_string())
}

pub(super) fn invalid(arg: &str, reason: impl Into<String>) -> PyErr {
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
pub(super) fn detached<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> CoreResult<T> + Send,
) -> PyResult<T> {
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
pub(super) fn interruptible<T: Send>(
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
