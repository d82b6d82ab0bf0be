//! `SensorConfig`: the simulated IMU, DVL, depth sensor, heading sensor and position
//! fixes.

use super::call::{invalid, to_py_err};
use super::convert::{
    arg_depth_period, arg_dvl_period, arg_dvl_scale, arg_heading_period, column, fixed, fixed_or,
    matrix, real_arg, rows,
};
use crate::ekf::DvlMounting;
use crate::sensors::{
    DepthModel, DvlDropout, DvlModel, FixModel, HeadingModel, ImuErrorModel, SensorConfig,
    VarianceSchedule,
};
use nalgebra::Vector3;
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

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
/// ``MonteCarloResult.missed_updates``). ``dvl_period=0``: no DVL (a GNSS/INS or
/// depth-only run; the other DVL arguments are then unused). The aiding sensors, each
/// read at its lever arm and applied by the filter with the σ and the lever arm it is
/// simulated with: ``depth_sigma`` [m] (None: no depth sensor) every ``depth_period``
/// [s] (default 1; refused without ``depth_sigma``), the depth of a pressure sensor at
/// ``depth_lever_arm`` [m, body FRD from the IMU; default 0: the IMU's point];
/// ``heading_sigma`` [rad] (None: no heading sensor; at most π) every ``heading_period``
/// [s] (default 1; refused without ``heading_sigma``), the body's yaw from true north
/// (a compass corrected for declination, an AHRS); ``fixes``, a list of position-fix
/// sources, each a dict with ``sigma`` (1σ [m] north, east and optionally down: without
/// it the fixes carry no height), a schedule: ``period`` [s] (0 or absent: none),
/// ``times`` [s] (single fixes, each at the IMU epoch nearest it) and ``max_depth`` [m]
/// (fixes only while the true depth is at most this: at the surface), and ``lever_arm``
/// [m, body FRD] of the antenna or transponder (default 0). Each aiding sensor draws
/// from its own seeded stream: the other sensors' draws are the same with and without
/// it. Defaults: the paper's (an ideal DVL, no dropout, no depth sensor, no heading
/// sensor, no fixes).
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
    #[pyo3(signature = (*, imu_variance = None, imu_variance_times = None, imu_bias = None, imu_bias_psd = None, dvl_variance = None, dvl_period = 1.0, lever_arm = None, dvl_outages = None, dvl_scale = 0.0, dvl_misalignment = None, dvl_dropout = None, depth_sigma = None, depth_period = None, depth_lever_arm = None, heading_sigma = None, heading_period = None, fixes = None))]
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
        depth_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_depth_period)] depth_period: Option<f64>,
        depth_lever_arm: Option<&Bound<'_, PyAny>>,
        heading_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_heading_period)] heading_period: Option<f64>,
        fixes: Option<&Bound<'_, PyAny>>,
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
            depth: depth_model(depth_sigma, depth_period, depth_lever_arm)?,
            heading: heading_model(heading_sigma, heading_period)?,
            fixes: match fixes {
                Some(f) => fix_models(f)?,
                None => Vec::new(),
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
    fn imu_variance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
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
    fn dvl_outages<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
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
    /// 1σ of the depth sensor [m], or None without one.
    #[getter]
    fn depth_sigma(&self) -> Option<f64> {
        self.inner.depth.map(|d| d.sigma)
    }
    /// Period of the depth sensor [s], or None without one.
    #[getter]
    fn depth_period(&self) -> Option<f64> {
        self.inner.depth.map(|d| d.period)
    }
    /// The depth sensor's lever arm [m, body FRD], or None without one.
    #[getter]
    fn depth_lever_arm(&self) -> Option<[f64; 3]> {
        self.inner.depth.map(|d| d.lever_arm.into())
    }
    /// 1σ of the heading sensor [rad], or None without one.
    #[getter]
    fn heading_sigma(&self) -> Option<f64> {
        self.inner.heading.map(|h| h.sigma)
    }
    /// Period of the heading sensor [s], or None without one.
    #[getter]
    fn heading_period(&self) -> Option<f64> {
        self.inner.heading.map(|h| h.period)
    }
    /// The position-fix sources, as the dicts the constructor takes.
    #[getter]
    fn fixes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for f in &self.inner.fixes {
            let d = PyDict::new(py);
            let n = if f.has_height() { 3 } else { 2 };
            d.set_item("sigma", f.sigma[..n].to_vec())?;
            d.set_item("period", f.period)?;
            d.set_item("times", f.times.clone())?;
            d.set_item("max_depth", f.max_depth)?;
            d.set_item("lever_arm", <[f64; 3]>::from(f.lever_arm))?;
            list.append(d)?;
        }
        Ok(list)
    }
    fn __repr__(&self) -> String {
        format!("SensorConfig({:?})", self.inner)
    }
}

/// The depth sensor of `depth_sigma` (None: none), its period (default 1 s) and lever
/// arm (default 0), each refused without the σ.
fn depth_model(
    sigma: Option<&Bound<'_, PyAny>>,
    period: Option<f64>,
    lever_arm: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<DepthModel>> {
    let needs = || "needs depth_sigma beside it (the depth sensor's 1σ [m])";
    match (sigma, period, lever_arm) {
        (Some(s), period, arm) => Ok(Some(DepthModel {
            sigma: real_arg(s, "depth_sigma")?,
            period: period.unwrap_or(1.0),
            lever_arm: Vector3::from(fixed_or::<3>(arm, "depth_lever_arm", [0.0; 3])?),
        })),
        (None, Some(_), _) => Err(invalid("depth_period", needs())),
        (None, None, Some(_)) => Err(invalid("depth_lever_arm", needs())),
        (None, None, None) => Ok(None),
    }
}

/// The heading sensor of `heading_sigma` (None: none) and its period (default 1 s;
/// refused without the σ).
fn heading_model(
    sigma: Option<&Bound<'_, PyAny>>,
    period: Option<f64>,
) -> PyResult<Option<HeadingModel>> {
    match (sigma, period) {
        (Some(s), period) => Ok(Some(HeadingModel {
            sigma: real_arg(s, "heading_sigma")?,
            period: period.unwrap_or(1.0),
        })),
        (None, Some(_)) => Err(invalid(
            "heading_period",
            "needs heading_sigma beside it (the heading sensor's 1σ [rad])",
        )),
        (None, None) => Ok(None),
    }
}

/// The keys of a position-fix source's dict.
const FIX_KEYS: [&str; 5] = ["sigma", "period", "times", "max_depth", "lever_arm"];

/// The position-fix sources of `fixes`: a list of dicts of [`FIX_KEYS`], each error
/// naming `fixes[i].key`.
fn fix_models(fixes: &Bound<'_, PyAny>) -> PyResult<Vec<FixModel>> {
    let refuse = || {
        invalid(
            "fixes",
            "expected a list of dicts (sigma, period, times, max_depth, lever_arm)",
        )
    };
    if fixes.is_instance_of::<PyString>() || fixes.is_instance_of::<PyDict>() {
        return Err(refuse());
    }
    let mut out = Vec::new();
    for (i, item) in fixes.try_iter().map_err(|_| refuse())?.enumerate() {
        let item = item?;
        let d = item.cast::<PyDict>().map_err(|_| {
            invalid(
                &format!("fixes[{i}]"),
                "expected a dict with sigma, period, times, max_depth, lever_arm",
            )
        })?;
        for key in d.keys() {
            let key: String = key.extract().unwrap_or_else(|_| format!("{key}"));
            if !FIX_KEYS.contains(&key.as_str()) {
                return Err(invalid(
                    &format!("fixes[{i}].{key}"),
                    format!("unknown key; expected one of {}", FIX_KEYS.join(", ")),
                ));
            }
        }
        let name = |key: &str| format!("fixes[{i}].{key}");
        let sigma = match d.get_item("sigma")? {
            Some(s) => column(&s, &name("sigma"))?,
            None => return Err(invalid(&name("sigma"), "missing; it is required")),
        };
        if !(sigma.len() == 2 || sigma.len() == 3) {
            return Err(invalid(
                &name("sigma"),
                format!(
                    "expected 2 (north, east) or 3 (north, east, down) values [m], got {}",
                    sigma.len()
                ),
            ));
        }
        let scalar = |key: &str| -> PyResult<Option<f64>> {
            match d.get_item(key)? {
                Some(v) if !v.is_none() => Ok(Some(real_arg(&v, &name(key))?)),
                _ => Ok(None),
            }
        };
        out.push(FixModel {
            sigma: [
                sigma[0],
                sigma[1],
                sigma.get(2).copied().unwrap_or(f64::NAN),
            ],
            period: scalar("period")?.unwrap_or(0.0),
            times: match d.get_item("times")? {
                Some(t) if !t.is_none() => column(&t, &name("times"))?,
                _ => Vec::new(),
            },
            max_depth: scalar("max_depth")?,
            lever_arm: match d.get_item("lever_arm")? {
                Some(a) if !a.is_none() => Vector3::from(fixed::<3>(&a, &name("lever_arm"))?),
                _ => Vector3::zeros(),
            },
        });
    }
    Ok(out)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySensorConfig>()
}
