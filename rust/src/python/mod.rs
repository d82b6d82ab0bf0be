//! Python bindings (`pronet._core`), one file per exposed type or function family. Each
//! entry point converts its arguments (types and shapes: [`convert`]), calls the core
//! without the GIL (`call`: [`call::detached`], [`call::interruptible`]) and maps the error: every core error becomes a
//! `ValueError` that starts with the offending argument's name; a Rust panic (a bug) is
//! caught and raised as `RuntimeError`, never as a `PanicException`. The domain rules
//! (latitude, gravity height, overflow, tuning instants, counts) live in the core.

mod call;
mod clocks;
mod config;
mod convert;
mod convnet;
mod ensemble;
mod filter;
mod hcf;
mod montecarlo;
mod navigation;
mod navigator;
mod sensors;
mod strategy;
mod streams;
mod trajectory;

use pyo3::prelude::*;

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
    m.add("MAX_LEVER_ARM", crate::ekf::MAX_LEVER_ARM)?;
    m.add("MAX_COVARIANCE_STEP", crate::ekf::MAX_COVARIANCE_STEP)?;
    m.add(
        "MAX_LINEAR_HEADING_SIGMA_DEG",
        crate::pass::MAX_LINEAR_HEADING_SIGMA_DEG,
    )?;
    m.add("MAX_SPEED", crate::pass::MAX_SPEED)?;
    m.add("MAX_ABS_HEIGHT", crate::pass::MAX_ABS_HEIGHT)?;
    m.add("MAX_POSITION_SIGMA", crate::pass::MAX_POSITION_SIGMA)?;
    m.add("MAX_IMU_GAP", crate::online::MAX_IMU_GAP)?;
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
    streams::register(m)?;
    filter::register(m)?;
    montecarlo::register(m)?;
    ensemble::register(m)?;
    convnet::register(m)?;
    clocks::register(m)?;
    hcf::register(m)?;
    navigator::register(m)?;
    Ok(())
}
