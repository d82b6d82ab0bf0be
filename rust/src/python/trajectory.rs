//! `Trajectory` and the functions that make one.

use super::call::{interruptible, to_py_err};
use super::convert::{arg_dt, arg_speed0, fixed, fixed_or, matrix, rows, vector};
use crate::trajectory::{self, Segment, TrajectorySpec, Truth};
use nalgebra::Vector3;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use std::sync::Arc;

/// Truth of a trajectory at n + 1 epochs and the ideal IMU over the n intervals.
#[pyclass(name = "Trajectory", module = "pronet._core", frozen)]
pub struct PyTrajectory {
    pub(super) truth: Arc<Truth>,
    spec: TrajectorySpec,
}

#[pymethods]
impl PyTrajectory {
    #[getter]
    fn name(&self) -> String {
        self.truth.name.clone()
    }
    /// Sample period [s].
    #[getter]
    fn dt(&self) -> f64 {
        self.truth.dt
    }
    /// Length [s].
    #[getter]
    fn duration(&self) -> f64 {
        self.truth.duration()
    }
    /// Number of IMU samples n.
    #[getter]
    fn n_samples(&self) -> usize {
        self.truth.len()
    }
    /// ``(n+1,)`` epoch times [s], starting at 0.
    #[getter]
    fn time<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        vector(py, &self.truth.time)
    }
    /// ``(n+1, 3)`` latitude, longitude [rad], height [m].
    #[getter]
    fn lla<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, self.truth.states.iter().map(|s| s.lla.into()))
    }
    /// ``(n+1, 3)`` NED velocity [m/s].
    #[getter]
    fn vel_ned<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, self.truth.states.iter().map(|s| s.vel.into()))
    }
    /// ``(n+1, 3)`` roll, pitch, yaw [rad].
    #[getter]
    fn rpy<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, self.truth.rpy.iter().map(|r| (*r).into()))
    }
    /// ``(n, 6)`` ideal IMU; row k covers ``(time[k], time[k+1]]``.
    #[getter]
    fn imu<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, self.truth.imu.iter().copied())
    }
    /// ``(k, 4)`` rows ``[duration s, accel m/s², yaw_rate rad/s, pitch_rate rad/s]``.
    #[getter]
    fn segments<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(
            py,
            self.spec
                .segments
                .iter()
                .map(|s| [s.duration, s.accel, s.yaw_rate, s.pitch_rate]),
        )
    }
    /// Initial forward speed [m/s].
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
        interruptible(py, move |cancel| spec.generate_until(cancel))?
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

/// Names of the built-in trajectories (see :func:`pronet.builtin_trajectory`).
#[pyfunction]
fn builtin_trajectory_names() -> Vec<&'static str> {
    trajectory::BUILTIN_NAMES.to_vec()
}

#[pyfunction]
#[pyo3(signature = (segments, *, lla0, speed0, rpy0 = None, dt = 0.01, name = "custom".to_string()))]
#[pyo3(text_signature = "(segments, *, lla0, speed0, rpy0=None, dt=0.01, name='custom')")]
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
    let rpy0 = fixed_or::<3>(rpy0, "rpy0", [0.0; 3])?;
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

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTrajectory>()?;
    m.add_function(wrap_pyfunction!(builtin_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_trajectory_names, m)?)?;
    m.add_function(wrap_pyfunction!(trajectory_from_segments, m)?)?;
    Ok(())
}
