//! Earth model and strapdown mechanization: `normal_gravity`, `earth_radii`, `mechanize`.

use super::call::{interruptible, to_py_err};
use super::convert::{arg_dt, arg_h, arg_lat, as_rows, nav_arrays, nav_state, readonly_rows};
use crate::{earth, mechanization};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// WGS-84 normal gravity [m/s²] at latitude [rad] and height [m], |h| <= 100 km (a
/// near-surface model; ValueError beyond).
#[pyfunction]
#[pyo3(signature = (lat, h = 0.0))]
fn normal_gravity(
    #[pyo3(from_py_with = arg_lat)] lat: f64,
    #[pyo3(from_py_with = arg_h)] h: f64,
) -> PyResult<f64> {
    earth::checked_gravity(lat, h).map_err(to_py_err)
}

/// Meridian and prime-vertical radii of curvature [m].
#[pyfunction]
fn earth_radii(#[pyo3(from_py_with = arg_lat)] lat: f64) -> PyResult<(f64, f64)> {
    earth::checked_radii(lat).map_err(to_py_err)
}

/// Strapdown integration; keys ``lla``, ``vel``, ``rpy``, each ``(n+1, 3)``. Finite
/// IMU rows, ``dt`` > 0, ``|lla0[0]|`` <= 89°; an overflow to non-finite states is a
/// ValueError naming ``imu, dt, lla0, vel0``, more states than this process can still
/// take one naming ``imu`` (docs/results/performance.md, "Memory").
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
    let imu = readonly_rows::<6>(imu, "imu")?;
    let rows = as_rows::<6>(&imu);
    let samples = &*rows;
    let init = nav_state(lla0, vel0, rpy0)?;
    let states = interruptible(py, move |cancel| {
        mechanization::mechanize_until(&init, samples, dt, cancel)
    })?;
    let d = PyDict::new(py);
    nav_arrays(py, &d, &states)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(normal_gravity, m)?)?;
    m.add_function(wrap_pyfunction!(earth_radii, m)?)?;
    m.add_function(wrap_pyfunction!(mechanize, m)?)?;
    Ok(())
}
