//! `SensorConfig`: the simulated IMU and DVL.

use super::convert::{arg_dvl_period, arg_dvl_scale, column, fixed, fixed_or, matrix, rows};
use super::{invalid, to_py_err};
use crate::sensors::{
    DvlDropout, DvlModel, DvlMounting, ImuErrorModel, SensorConfig, VarianceSchedule,
};
use nalgebra::Vector3;
use numpy::PyArray2;
use pyo3::prelude::*;

/// Simulated sensors. ``imu_variance``: 6 per-sample variances, or with
/// ``imu_variance_times`` (k,) [s, starting at 0] a ``(k, 6)`` piecewise-constant
/// schedule. Constant bias, bias random-walk PSD, DVL variance [(m/s)²], DVL period [s]
/// (a whole number of IMU steps), DVL lever arm [m, body], DVL outages ``(k, 2)``
/// ``[start, end)`` [s] (sorted, not overlapping; no reading inside one), and the
/// DVL's scale-factor error k (it reads ``1 + k`` times the velocity, k > −1) and
/// mounting misalignment (its roll, pitch, yaw in the body frame [rad]), and
/// ``dvl_dropout`` ``(mean_interval, mean_length)`` [s]: random bottom-lock loss, a
/// locked/lost chain stepped at each due reading (mean time between losses, mean
/// length of a loss; its own seeded stream, so a Monte Carlo stays the same for any
/// thread count; a lost reading is a missed update, counted in
/// ``MonteCarloResult.missed_updates``). Defaults: the paper's (an ideal DVL, no
/// dropout).
#[pyclass(name = "SensorConfig", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PySensorConfig {
    pub(super) inner: SensorConfig,
}

/// The IMU variance: the paper's, one row of 6, or a schedule over `times`.
fn variance(
    values: Option<&Bound<'_, PyAny>>,
    times: Option<&Bound<'_, PyAny>>,
) -> PyResult<VarianceSchedule> {
    match (values, times) {
        (None, None) => Ok(SensorConfig::paper().imu.variance),
        (Some(v), None) => VarianceSchedule::new(vec![0.0], vec![fixed::<6>(v, "imu_variance")?])
            .map_err(to_py_err),
        (Some(v), Some(t)) => {
            let times = column(t, "imu_variance_times")?;
            let values = rows::<6>(v, "imu_variance")?;
            VarianceSchedule::new(times, values).map_err(to_py_err)
        }
        (None, Some(_)) => Err(invalid("imu_variance_times", "given without imu_variance")),
    }
}

#[pymethods]
impl PySensorConfig {
    #[new]
    #[allow(clippy::too_many_arguments)] // the keyword arguments of the Python constructor
    #[pyo3(signature = (*, imu_variance = None, imu_variance_times = None, imu_bias = None, imu_bias_psd = None, dvl_variance = None, dvl_period = 1.0, lever_arm = None, dvl_outages = None, dvl_scale = 0.0, dvl_misalignment = None, dvl_dropout = None))]
    fn new(
        imu_variance: Option<&Bound<'_, PyAny>>,
        imu_variance_times: Option<&Bound<'_, PyAny>>,
        imu_bias: Option<&Bound<'_, PyAny>>,
        imu_bias_psd: Option<&Bound<'_, PyAny>>,
        dvl_variance: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_dvl_period)] dvl_period: f64,
        lever_arm: Option<&Bound<'_, PyAny>>,
        dvl_outages: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_dvl_scale)] dvl_scale: f64,
        dvl_misalignment: Option<&Bound<'_, PyAny>>,
        dvl_dropout: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let dropout = match dvl_dropout {
            Some(d) => {
                let [mean_interval, mean_length] = fixed::<2>(d, "dvl_dropout")?;
                Some(DvlDropout {
                    mean_interval,
                    mean_length,
                })
            }
            None => None,
        };
        let angles = fixed_or::<3>(dvl_misalignment, "dvl_misalignment", [0.0; 3])?;
        let inner = SensorConfig {
            imu: ImuErrorModel {
                variance: variance(imu_variance, imu_variance_times)?,
                bias: fixed_or(imu_bias, "imu_bias", [0.0; 6])?,
                bias_rw_psd: fixed_or(imu_bias_psd, "imu_bias_psd", [0.0; 6])?,
            },
            dvl: DvlModel {
                variance: fixed_or(
                    dvl_variance,
                    "dvl_variance",
                    SensorConfig::paper().dvl.variance,
                )?,
                period: dvl_period,
                lever_arm: Vector3::from(fixed_or::<3>(lever_arm, "lever_arm", [0.0; 3])?),
                outages: match dvl_outages {
                    Some(o) => rows::<2>(o, "dvl_outages")?,
                    None => Vec::new(),
                },
                mounting: if dvl_scale == 0.0 && angles == [0.0; 3] {
                    DvlMounting::default() // exactly the identity, not a rounded one
                } else {
                    DvlMounting::from_angles(dvl_scale, angles)
                },
                dropout,
            },
        };
        inner.validate().map_err(to_py_err)?;
        Ok(Self { inner })
    }
    #[getter]
    fn imu_variance_times(&self) -> Vec<f64> {
        self.inner.imu.variance.times().to_vec()
    }
    #[getter]
    fn imu_variance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix(py, self.inner.imu.variance.values().iter().copied())
    }
    #[getter]
    fn imu_bias(&self) -> Vec<f64> {
        self.inner.imu.bias.to_vec()
    }
    #[getter]
    fn imu_bias_psd(&self) -> Vec<f64> {
        self.inner.imu.bias_rw_psd.to_vec()
    }
    #[getter]
    fn dvl_variance(&self) -> Vec<f64> {
        self.inner.dvl.variance.to_vec()
    }
    #[getter]
    fn dvl_period(&self) -> f64 {
        self.inner.dvl.period
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.inner.dvl.lever_arm.as_slice().to_vec()
    }
    /// The DVL's scale-factor error k: it reads ``(1 + k)`` times the true velocity.
    #[getter]
    fn dvl_scale(&self) -> f64 {
        self.inner.dvl.mounting.scale
    }
    /// The DVL's roll, pitch, yaw in the body frame [rad] (its mounting misalignment).
    #[getter]
    fn dvl_misalignment(&self) -> Vec<f64> {
        self.inner.dvl.mounting.angles().to_vec()
    }
    /// ``(k, 2)`` DVL outages ``[start, end)`` [s].
    #[getter]
    fn dvl_outages<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix(py, self.inner.dvl.outages.iter().copied())
    }
    /// ``(mean_interval, mean_length)`` [s] of the random bottom-lock loss, or None.
    #[getter]
    fn dvl_dropout(&self) -> Option<(f64, f64)> {
        self.inner
            .dvl
            .dropout
            .map(|d| (d.mean_interval, d.mean_length))
    }
    fn __repr__(&self) -> String {
        format!("SensorConfig({:?})", self.inner)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySensorConfig>()
}
