//! pronet navigation core: WGS-84 Earth model, strapdown mechanization, trajectory and
//! sensor simulation, the 15-state INS/DVL error-state EKF and the measurements of its
//! aiding sensors, process-noise strategies, the one epoch loop every pass runs, the
//! RTS smoother, passes over recordings and simulated runs, a parallel Monte Carlo
//! engine, and the forward passes of the learned noise regressors.
//!
//! The modules in layers, each importing only those before it: `error`, `cancel`,
//! `threads`, `memory`, `pages`; `attitude`, `earth`, `clocks`, `regressors`; `mechanization`;
//! `trajectory`; `ekf`; `measurement`, `noise`; `sensors`; `pass`; `smoother`;
//! `recorded`, `scenario`, `run`; `montecarlo`, `ensemble`; `python`
//! (`tests/test_rust_layout.py` checks it).
//!
//! Conventions (see `docs/reference/filter.md`): navigation frame NED, body frame FRD, positions
//! geodetic `[lat, lon, h]` in rad, rad, m (height positive up), attitude as the
//! body-to-NED DCM, IMU samples `[f_x, f_y, f_z, ω_x, ω_y, ω_z]` in m/s² and rad/s.
//! This crate is plain Rust; the Python bindings live behind the `python` feature.

pub mod attitude;
pub mod cancel;
pub mod clocks;
pub mod earth;
pub mod ekf;
pub mod ensemble;
pub mod error;
pub mod measurement;
pub mod mechanization;
pub mod memory;
pub mod montecarlo;
pub mod noise;
pub mod online;
pub mod pages;
pub mod pass;
pub mod recorded;
pub mod regressors;
pub mod run;
pub mod scenario;
pub mod sensors;
pub mod smoother;
pub mod threads;
pub mod trajectory;

#[cfg(feature = "python")]
mod python;

pub use error::{Error, Result};
