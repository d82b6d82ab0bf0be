//! `run_filter`: one filter pass over given IMU and DVL arrays.

use super::config::PyFilterConfig;
use super::convert::{
    arg_t0, as_rows, column, fixed_or, matrix, nav_arrays, nav_state, readonly_rows, rows,
};
use super::strategy::PyStrategy;
use super::{interruptible, invalid};
use crate::ekf::{filter_recorded_until, FilterOutput, RecordedData};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The q schedule `(q_time, q)`: both or neither.
type QSchedule = (Vec<f64>, Vec<[f64; 6]>);

fn q_schedule(
    q_time: Option<&Bound<'_, PyAny>>,
    q: Option<&Bound<'_, PyAny>>,
) -> PyResult<QSchedule> {
    match (q_time, q) {
        (Some(t), Some(v)) => Ok((column(t, "q_time")?, rows::<6>(v, "q")?)),
        (None, None) => Ok((Vec::new(), Vec::new())),
        _ => Err(invalid(
            "q_time",
            "q_time and q go together: give both or neither",
        )),
    }
}

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
    let imu_array = readonly_rows::<6>(imu, "imu")?;
    let imu_rows = as_rows::<6>(&imu_array);
    let imu = &*imu_rows;
    let (q_time, q_values) = q_schedule(q_time, q)?;
    let imu_time = column(imu_time, "imu_time")?;
    let dvl_array = readonly_rows::<3>(dvl, "dvl")?;
    let dvl_rows = as_rows::<3>(&dvl_array);
    let dvl = &*dvl_rows;
    let dvl_time = column(dvl_time, "dvl_time")?;
    let init = nav_state(lla0, vel0, rpy0)?;
    let bias0 = fixed_or::<6>(bias0, "bias0", [0.0; 6])?;
    let cfg = config.inner.clone();
    let spec = strategy.inner.clone();
    let out: FilterOutput = interruptible(py, move |cancel| {
        let data = RecordedData {
            imu,
            imu_time: &imu_time,
            dvl,
            dvl_time: &dvl_time,
            t0,
            q_time: &q_time,
            q_values: &q_values,
        };
        let mut strat = spec.build(cfg.bias_psd());
        filter_recorded_until(&data, init, bias0, &cfg, strat.as_mut(), cancel)
    })?;
    output_dict(py, &out)
}

/// The pass's epochs and updates as the dict `pronet.FilterResult` takes.
fn output_dict<'py>(py: Python<'py>, out: &FilterOutput) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("time", out.time.clone().into_pyarray(py))?;
    nav_arrays(py, &d, &out.nav)?;
    d.set_item("bias", matrix(py, out.bias.iter().copied()))?;
    d.set_item("sigma", matrix(py, out.sigma.iter().copied()))?;
    // (0, 4) without the DVL calibration states
    d.set_item("calibration", matrix(py, out.calibration.iter().copied()))?;
    d.set_item(
        "calibration_sigma",
        matrix(py, out.calibration_sigma.iter().copied()),
    )?;
    let p = out.final_covariance;
    d.set_item(
        "covariance",
        Array2::from_shape_fn((15, 15), |(i, j)| p[(i, j)]).into_pyarray(py),
    )?;
    d.set_item(
        "dvl_epoch",
        Array1::from_iter(out.dvl_epoch.iter().map(|e| e.map_or(-1, |k| k as i64)))
            .into_pyarray(py),
    )?;
    d.set_item("diverged_at", out.nis_monitor.diverged_at)?;
    update_arrays(py, &d, out)?;
    Ok(d)
}

/// The per-DVL-row arrays: NaN (and not accepted) where a row fell outside the run.
fn update_arrays<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, out: &FilterOutput) -> PyResult<()> {
    let m = out.updates.len();
    let each = |f: &dyn Fn(&crate::ekf::UpdateInfo) -> f64| {
        Array1::from_iter(out.updates.iter().map(|u| u.as_ref().map_or(f64::NAN, f)))
    };
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
    d.set_item("nis", each(&|u| u.nis).into_pyarray(py))?;
    d.set_item(
        "accepted",
        Array1::from_iter(
            out.updates
                .iter()
                .map(|u| u.as_ref().is_some_and(|u| u.accepted)),
        )
        .into_pyarray(py),
    )?;
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
    Ok(())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_filter, m)?)
}
