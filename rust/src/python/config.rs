//! `FilterConfig`: the EKF's tuning.

use super::call::{invalid, to_py_err};
use super::convert::{
    arg_accel_bias_psd, arg_aiding, arg_covariance_step, arg_dvl_bias_time_constant,
    arg_dvl_calibration, arg_dvl_misalignment_psd, arg_dvl_scale_psd, arg_dvl_scale_sigma,
    arg_formulation, arg_gyro_bias_psd, arg_heading_second_order, arg_imu_dt, arg_innovation_gate,
    fixed, fixed_or,
};
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::{Aiding, FilterConfig, Formulation, DEFAULT_COVARIANCE_STEP};
use nalgebra::Vector3;
use pyo3::prelude::*;

/// EKF tuning: initial 1σ (15), bias random-walk PSDs ε_a [(m/s²)²/s] and ε_g
/// [(rad/s)²/s], DVL variance R [(m/s)²], DVL lever arm [m, body], aiding ("body" velocity
/// or "nav" NED velocity), nominal IMU period [s], the χ² innovation gate (a DVL update
/// whose NIS exceeds it is rejected; None: no gate); opt-in DVL calibration states
/// (``dvl_calibration=True``, body aiding): scale-factor error and misalignment, initial
/// 1σ (default 0.01, 1° per axis [rad]) and random-walk PSDs [1/s, rad²/s] (default 0);
/// an opt-in correlated DVL velocity error (``dvl_bias_sigma``, stationary 1σ per DVL axis
/// [m/s], body aiding; Gauss–Markov, correlation time ``dvl_bias_time_constant`` [s],
/// default 60), three more states; the formulation, the velocity error's coordinates:
/// "invariant" (default, ``δV = δv − [v̂×]ψ``, consistent in heading), "classic" (``δv``)
/// or "se23" (the prior and every output in the classic ones either way); the covariance
/// step [s] over which P is propagated at once (the navigation at every IMU sample),
/// 0.1 s by default (``docs/results/covariance-step.md``); 0 or under 1.5 IMU periods:
/// every sample; longer ones rounded to whole IMU periods (at most
/// :data:`MAX_COVARIANCE_STEP`), P brought up to date before every update and at a pass's
/// end; ``heading_second_order=True``: P carries the second-order heading term of the
/// position error, ``¾ u uᵀ`` (not with "se23" nor the DVL error states). See
/// ``docs/reference/filter.md``.
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

fn parse_formulation(text: &str) -> PyResult<Formulation> {
    Formulation::from_name(text).ok_or_else(|| {
        invalid(
            "formulation",
            format!("must be \"invariant\", \"classic\" or \"se23\", got {text:?}"),
        )
    })
}

impl PyFilterConfig {
    /// The DVL error states' configuration where the scale and misalignment are
    /// estimated (None where they are not, or only the correlated error is).
    fn calibration(&self) -> Option<CalibrationConfig> {
        self.inner.dvl_calibration.filter(|c| c.calibrates())
    }
}

#[pymethods]
impl PyFilterConfig {
    #[new]
    #[pyo3(signature = (*, p0_sigma = None, accel_bias_psd = 1e-3, gyro_bias_psd = 1e-3, dvl_variance = None, lever_arm = None, aiding = "body".to_string(), imu_dt = 0.01, innovation_gate = None, dvl_calibration = false, dvl_scale_sigma = None, dvl_misalignment_sigma = None, dvl_scale_psd = None, dvl_misalignment_psd = None, dvl_bias_sigma = None, dvl_bias_time_constant = None, formulation = Formulation::default().name().to_string(), covariance_step = DEFAULT_COVARIANCE_STEP, heading_second_order = false))]
    #[pyo3(
        text_signature = "(*, p0_sigma=None, accel_bias_psd=0.001, gyro_bias_psd=0.001, dvl_variance=None, lever_arm=None, aiding='body', imu_dt=0.01, innovation_gate=None, dvl_calibration=False, dvl_scale_sigma=None, dvl_misalignment_sigma=None, dvl_scale_psd=None, dvl_misalignment_psd=None, dvl_bias_sigma=None, dvl_bias_time_constant=None, formulation='invariant', covariance_step=0.1, heading_second_order=False)"
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
        #[pyo3(from_py_with = arg_dvl_calibration)] dvl_calibration: bool,
        #[pyo3(from_py_with = arg_dvl_scale_sigma)] dvl_scale_sigma: Option<f64>,
        dvl_misalignment_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_dvl_scale_psd)] dvl_scale_psd: Option<f64>,
        #[pyo3(from_py_with = arg_dvl_misalignment_psd)] dvl_misalignment_psd: Option<f64>,
        dvl_bias_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_dvl_bias_time_constant)] dvl_bias_time_constant: Option<f64>,
        #[pyo3(from_py_with = arg_formulation)] formulation: String,
        #[pyo3(from_py_with = arg_covariance_step)] covariance_step: f64,
        #[pyo3(from_py_with = arg_heading_second_order)] heading_second_order: bool,
    ) -> PyResult<Self> {
        let defaults = FilterConfig::default();
        let misalignment_sigma = dvl_misalignment_sigma
            .map(|v| fixed::<3>(v, "dvl_misalignment_sigma"))
            .transpose()?;
        let bias_sigma = dvl_bias_sigma
            .map(|v| fixed::<3>(v, "dvl_bias_sigma"))
            .transpose()?;
        if bias_sigma.is_none() && dvl_bias_time_constant.is_some() {
            return Err(invalid(
                "dvl_bias_time_constant",
                "describes the DVL's correlated velocity error: give it with dvl_bias_sigma",
            ));
        }
        let d = CalibrationConfig::default();
        let bias = CalibrationConfig {
            bias_sigma: bias_sigma.unwrap_or(d.bias_sigma),
            bias_time_constant: dvl_bias_time_constant.unwrap_or(d.bias_time_constant),
            ..d
        };
        let calibration = if dvl_calibration {
            Some(CalibrationConfig {
                scale_sigma: dvl_scale_sigma.unwrap_or(d.scale_sigma),
                misalignment_sigma: misalignment_sigma.unwrap_or(d.misalignment_sigma),
                scale_psd: dvl_scale_psd.unwrap_or(d.scale_psd),
                misalignment_psd: dvl_misalignment_psd.unwrap_or(d.misalignment_psd),
                ..bias
            })
        } else {
            let given = [
                ("dvl_scale_sigma", dvl_scale_sigma.is_some()),
                ("dvl_misalignment_sigma", misalignment_sigma.is_some()),
                ("dvl_scale_psd", dvl_scale_psd.is_some()),
                ("dvl_misalignment_psd", dvl_misalignment_psd.is_some()),
            ];
            if let Some((name, _)) = given.iter().find(|(_, set)| *set) {
                return Err(invalid(
                    name,
                    "describes the DVL calibration states: give it with dvl_calibration=True",
                ));
            }
            // The correlated error alone: the DVL error states with the scale and
            // misalignment held at their nominal values (σ 0, no walk).
            bias_sigma.map(|_| CalibrationConfig {
                scale_sigma: 0.0,
                misalignment_sigma: [0.0; 3],
                calibrated: false,
                ..bias
            })
        };
        let inner = FilterConfig {
            p0_sigma: fixed_or(p0_sigma, "p0_sigma", defaults.p0_sigma)?,
            accel_bias_psd,
            gyro_bias_psd,
            dvl_variance: fixed_or(dvl_variance, "dvl_variance", defaults.dvl_variance)?,
            lever_arm: Vector3::from(fixed_or(lever_arm, "lever_arm", defaults.lever_arm.into())?),
            aiding: parse_aiding(&aiding)?,
            imu_dt,
            innovation_gate,
            dvl_calibration: calibration,
            formulation: parse_formulation(&formulation)?,
            covariance_step,
            anchor: None,
            heading_second_order,
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
    /// The error coordinates: "invariant", "classic" or "se23" (``reference/filter.md``).
    #[getter]
    fn formulation(&self) -> &'static str {
        self.inner.formulation.name()
    }
    /// The covariance step [s] (0: the covariance propagated at every IMU sample).
    #[getter]
    fn covariance_step(&self) -> f64 {
        self.inner.covariance_step
    }
    /// Whether the second-order heading term of the position error is carried.
    #[getter]
    fn heading_second_order(&self) -> bool {
        self.inner.heading_second_order
    }
    #[getter]
    fn imu_dt(&self) -> f64 {
        self.inner.imu_dt
    }
    #[getter]
    fn innovation_gate(&self) -> Option<f64> {
        self.inner.innovation_gate
    }
    /// Whether the DVL scale-factor and misalignment states are estimated.
    #[getter]
    fn dvl_calibration(&self) -> bool {
        self.inner.dvl_calibration.is_some_and(|c| c.calibrates())
    }
    /// Stationary 1σ per DVL axis of its correlated velocity error [m/s], or None.
    #[getter]
    fn dvl_bias_sigma(&self) -> Option<Vec<f64>> {
        let c = self.inner.dvl_calibration.filter(|c| c.correlated())?;
        Some(c.bias_sigma.to_vec())
    }
    /// Its correlation time [s] (None without it).
    #[getter]
    fn dvl_bias_time_constant(&self) -> Option<f64> {
        let c = self.inner.dvl_calibration.filter(|c| c.correlated())?;
        Some(c.bias_time_constant)
    }
    /// Initial 1σ of the DVL scale-factor error (None without the calibration states).
    #[getter]
    fn dvl_scale_sigma(&self) -> Option<f64> {
        self.calibration().map(|c| c.scale_sigma)
    }
    /// Initial 1σ of the DVL misalignment about body x, y, z [rad] (None without them).
    #[getter]
    fn dvl_misalignment_sigma(&self) -> Option<Vec<f64>> {
        self.calibration().map(|c| c.misalignment_sigma.to_vec())
    }
    /// Random-walk PSD of the DVL scale factor [1/s] (None without the states).
    #[getter]
    fn dvl_scale_psd(&self) -> Option<f64> {
        self.calibration().map(|c| c.scale_psd)
    }
    /// Random-walk PSD of each misalignment angle [rad²/s] (None without the states).
    #[getter]
    fn dvl_misalignment_psd(&self) -> Option<f64> {
        self.calibration().map(|c| c.misalignment_psd)
    }
    fn __repr__(&self) -> String {
        let mut calibration = match self.calibration() {
            None => String::new(),
            Some(c) => format!(
                ", dvl_calibration=True, dvl_scale_sigma={}, dvl_misalignment_sigma={:?}, dvl_scale_psd={}, dvl_misalignment_psd={}",
                c.scale_sigma, c.misalignment_sigma, c.scale_psd, c.misalignment_psd
            ),
        };
        if let Some(c) = self.inner.dvl_calibration.filter(|c| c.correlated()) {
            calibration += &format!(
                ", dvl_bias_sigma={:?}, dvl_bias_time_constant={}",
                c.bias_sigma, c.bias_time_constant
            );
        }
        if self.inner.heading_second_order {
            calibration += ", heading_second_order=True";
        }
        format!(
            "FilterConfig(accel_bias_psd={}, gyro_bias_psd={}, dvl_variance={:?}, lever_arm={:?}, aiding={:?}, imu_dt={}, innovation_gate={}, formulation={:?}, covariance_step={}{calibration})",
            self.inner.accel_bias_psd,
            self.inner.gyro_bias_psd,
            self.inner.dvl_variance,
            self.inner.lever_arm.as_slice(),
            self.aiding(),
            self.inner.imu_dt,
            self.inner
                .innovation_gate
                .map_or("None".to_string(), |g| g.to_string()),
            self.formulation(),
            self.inner.covariance_step,
        )
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFilterConfig>()
}
