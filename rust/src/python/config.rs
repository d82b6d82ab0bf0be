//! `FilterConfig`: the EKF's tuning.

use super::convert::{
    arg_accel_bias_psd, arg_aiding, arg_gyro_bias_psd, arg_imu_dt, arg_innovation_gate, fixed_or,
};
use super::{invalid, to_py_err};
use crate::ekf::{Aiding, FilterConfig};
use nalgebra::Vector3;
use pyo3::prelude::*;

/// EKF tuning (see `_core.pyi`).
#[pyclass(name = "FilterConfig", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PyFilterConfig {
    pub(super) inner: FilterConfig,
}

fn parse_aiding(text: &str) -> PyResult<Aiding> {
    match text {
        "body" => Ok(Aiding::Body),
        "nav" => Ok(Aiding::Nav),
        other => Err(invalid(
            "aiding",
            format!("must be \"body\" or \"nav\", got {other:?}"),
        )),
    }
}

#[pymethods]
impl PyFilterConfig {
    #[new]
    #[pyo3(signature = (*, p0_sigma = None, accel_bias_psd = 1e-3, gyro_bias_psd = 1e-3, dvl_variance = None, lever_arm = None, aiding = "body".to_string(), imu_dt = 0.01, innovation_gate = None))]
    #[pyo3(
        text_signature = "(*, p0_sigma=None, accel_bias_psd=0.001, gyro_bias_psd=0.001, dvl_variance=None, lever_arm=None, aiding='body', imu_dt=0.01, innovation_gate=None)"
    )]
    #[allow(clippy::too_many_arguments)] // keyword-only, one per FilterConfig field
    fn new(
        p0_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_accel_bias_psd)] accel_bias_psd: f64,
        #[pyo3(from_py_with = arg_gyro_bias_psd)] gyro_bias_psd: f64,
        dvl_variance: Option<&Bound<'_, PyAny>>,
        lever_arm: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_aiding)] aiding: String,
        #[pyo3(from_py_with = arg_imu_dt)] imu_dt: f64,
        #[pyo3(from_py_with = arg_innovation_gate)] innovation_gate: Option<f64>,
    ) -> PyResult<Self> {
        let defaults = FilterConfig::default();
        let inner = FilterConfig {
            p0_sigma: fixed_or(p0_sigma, "p0_sigma", defaults.p0_sigma)?,
            accel_bias_psd,
            gyro_bias_psd,
            dvl_variance: fixed_or(dvl_variance, "dvl_variance", defaults.dvl_variance)?,
            lever_arm: Vector3::from(fixed_or(lever_arm, "lever_arm", defaults.lever_arm.into())?),
            aiding: parse_aiding(&aiding)?,
            imu_dt,
            innovation_gate,
        };
        inner.validate().map_err(to_py_err)?;
        Ok(Self { inner })
    }
    #[getter]
    fn p0_sigma(&self) -> Vec<f64> {
        self.inner.p0_sigma.to_vec()
    }
    #[getter]
    fn accel_bias_psd(&self) -> f64 {
        self.inner.accel_bias_psd
    }
    #[getter]
    fn gyro_bias_psd(&self) -> f64 {
        self.inner.gyro_bias_psd
    }
    #[getter]
    fn dvl_variance(&self) -> Vec<f64> {
        self.inner.dvl_variance.to_vec()
    }
    #[getter]
    fn lever_arm(&self) -> Vec<f64> {
        self.inner.lever_arm.as_slice().to_vec()
    }
    #[getter]
    fn aiding(&self) -> &'static str {
        match self.inner.aiding {
            Aiding::Body => "body",
            Aiding::Nav => "nav",
        }
    }
    #[getter]
    fn imu_dt(&self) -> f64 {
        self.inner.imu_dt
    }
    #[getter]
    fn innovation_gate(&self) -> Option<f64> {
        self.inner.innovation_gate
    }
    fn __repr__(&self) -> String {
        format!(
            "FilterConfig(accel_bias_psd={}, gyro_bias_psd={}, dvl_variance={:?}, lever_arm={:?}, aiding={:?}, imu_dt={}, innovation_gate={})",
            self.inner.accel_bias_psd,
            self.inner.gyro_bias_psd,
            self.inner.dvl_variance,
            self.inner.lever_arm.as_slice(),
            self.aiding(),
            self.inner.imu_dt,
            self.inner
                .innovation_gate
                .map_or("None".to_string(), |g| g.to_string()),
        )
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFilterConfig>()
}
