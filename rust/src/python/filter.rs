//! `run_filter`: one filter pass over given IMU and DVL arrays.

use super::call::{interruptible, invalid, to_py_err};
use super::config::PyFilterConfig;
use super::convert::{
    arg_epochs, arg_t0, as_rows, as_values, column, fixed_or, nav_state, readonly_column,
    readonly_rows, rows, rows_array,
};
use super::strategy::PyStrategy;
use crate::attitude::euler_from_dcm;
use crate::measurement::check_depth_sigma;
use crate::mechanization::NavState;
use crate::recorded::{
    filter_recorded_until, smooth_recorded_until, Epochs, FilterOutput, RecordedData, Stream,
    StreamRecord,
};
use crate::smoother::Smoothed;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The depth readings and position fixes of a pass, each group all or none.
struct Aiding {
    depth_given: bool,
    fix_given: bool,
    depth: Vec<f64>,
    depth_time: Vec<f64>,
    depth_sigma: f64,
    fix: Vec<[f64; 3]>,
    fix_time: Vec<f64>,
    fix_sigma: Vec<[f64; 3]>,
}

impl Aiding {
    fn new(
        depth: Option<&Bound<'_, PyAny>>,
        depth_time: Option<&Bound<'_, PyAny>>,
        depth_sigma: Option<f64>,
        fix: Option<&Bound<'_, PyAny>>,
        fix_time: Option<&Bound<'_, PyAny>>,
        fix_sigma: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (depth, depth_time, depth_sigma) = match (depth, depth_time, depth_sigma) {
            (Some(d), Some(t), Some(s)) => {
                // A σ given is checked, readings or not (None stands for no sensor).
                check_depth_sigma(s).map_err(to_py_err)?;
                (column(d, "depth")?, column(t, "depth_time")?, s)
            }
            (None, None, None) => (Vec::new(), Vec::new(), f64::NAN),
            _ => {
                return Err(invalid(
                    "depth",
                    "depth, depth_time and depth_sigma go together: give all three or none",
                ))
            }
        };
        let fix_sigma_given = fix_sigma.is_some();
        let (fix, fix_time, fix_sigma) = match (fix, fix_time, fix_sigma) {
            (Some(f), Some(t), Some(s)) => (
                rows::<3>(f, "fix")?,
                column(t, "fix_time")?,
                rows::<3>(s, "fix_sigma")?,
            ),
            (None, None, None) => (Vec::new(), Vec::new(), Vec::new()),
            _ => {
                return Err(invalid(
                    "fix",
                    "fix, fix_time and fix_sigma go together: give all three or none",
                ))
            }
        };
        Ok(Self {
            depth_given: depth_sigma.is_finite(),
            fix_given: fix_sigma_given,
            depth,
            depth_time,
            depth_sigma,
            fix,
            fix_time,
            fix_sigma,
        })
    }
}

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

/// One filter pass; see :class:`pronet.FilterResult` for the keys. ``q_time`` (k,)
/// [s] and ``q`` (k, 6): a q schedule for an external strategy. ``epochs``: ``"all"``
/// or ``"last"`` (the epoch arrays keep only the last epoch). ``output_step`` [s] (> 0,
/// with ``"all"``): keep ``t0``, the epoch nearest each multiple of it and the last
/// (key ``epoch``: each row's index among all; empty without). ``covariance_time``
/// (j,) [s], strictly increasing: keep the full covariance at the epoch nearest each.
/// ``smooth``: also run the RTS smoother (key ``smoothed``: a dict of ``lla``, ``vel``,
/// ``rpy``, ``bias``, ``sigma``, ``calibration``, ``calibration_sigma`` per epoch;
/// None without). Key ``adaptive_q``: None where no DVL row has one. ``depth`` (d,)
/// [m, down] at
/// ``depth_time`` (d,) [s] with 1σ ``depth_sigma`` [m]; ``fix`` (f, 3) ``[lat, lon
/// (rad), h (m; NaN: none)]`` at ``fix_time`` (f,) [s] with 1σ ``fix_sigma`` (f, 3)
/// [m, N E D]: position and depth updates, each group all or none. ``|lla0[0]|`` <= 89°.
#[pyfunction]
#[pyo3(signature = (imu, imu_time, dvl, dvl_time, *, t0, lla0, vel0, rpy0, config, strategy, bias0 = None, q_time = None, q = None, epochs = "all".to_string(), output_step = None, covariance_time = None, smooth = false, depth = None, depth_time = None, depth_sigma = None, fix = None, fix_time = None, fix_sigma = None),
    text_signature = "(imu, imu_time, dvl, dvl_time, *, t0, lla0, vel0, rpy0, config, strategy, bias0=None, q_time=None, q=None, epochs='all', output_step=None, covariance_time=None, smooth=False, depth=None, depth_time=None, depth_sigma=None, fix=None, fix_time=None, fix_sigma=None)")]
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
    #[pyo3(from_py_with = arg_epochs)] epochs: String,
    output_step: Option<f64>,
    covariance_time: Option<&Bound<'py, PyAny>>,
    smooth: bool,
    depth: Option<&Bound<'py, PyAny>>,
    depth_time: Option<&Bound<'py, PyAny>>,
    depth_sigma: Option<f64>,
    fix: Option<&Bound<'py, PyAny>>,
    fix_time: Option<&Bound<'py, PyAny>>,
    fix_sigma: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let epochs = match (epochs.as_str(), output_step) {
        ("all", None) => Epochs::All,
        ("all", Some(step)) => Epochs::Step(step),
        ("last", None) => Epochs::Last,
        ("last", Some(_)) => {
            return Err(invalid(
                "output_step",
                "keeps the epoch nearest each multiple of the period, not with epochs=\"last\"",
            ))
        }
        (other, _) => {
            return Err(invalid(
                "epochs",
                format!("must be \"all\" or \"last\", got {other:?}"),
            ))
        }
    };
    epochs.validate().map_err(to_py_err)?;
    if smooth && epochs == Epochs::Last {
        return Err(invalid(
            "epochs",
            "smooth=True keeps the epochs it corrects: use epochs=\"all\" (with an \
             output_step to keep some)",
        ));
    }
    let imu_array = readonly_rows::<6>(imu, "imu")?;
    let imu_rows = as_rows::<6>(&imu_array);
    let imu = &*imu_rows;
    let (q_time, q_values) = q_schedule(q_time, q)?;
    // The IMU's arrays are read in place (~200 MB for 10 h at 100 Hz), not copied.
    let imu_time_array = readonly_column(imu_time, "imu_time")?;
    let imu_time = as_values(&imu_time_array);
    let imu_time = &*imu_time;
    let dvl_array = readonly_rows::<3>(dvl, "dvl")?;
    let dvl_rows = as_rows::<3>(&dvl_array);
    let dvl = &*dvl_rows;
    let dvl_time = column(dvl_time, "dvl_time")?;
    let covariance_time = match covariance_time {
        Some(times) => column(times, "covariance_time")?,
        None => Vec::new(),
    };
    let aiding = Aiding::new(depth, depth_time, depth_sigma, fix, fix_time, fix_sigma)?;
    let init = nav_state(lla0, vel0, rpy0)?;
    let bias0 = fixed_or::<6>(bias0, "bias0", [0.0; 6])?;
    let cfg = config.inner.clone();
    let spec = strategy.inner.clone();
    // The arrays are built on the worker thread too, without the GIL: pronet real
    // runs sections on threads, which would otherwise queue for it while one of them
    // copies its ~40 MB of results.
    let arrays = interruptible(py, move |cancel| {
        let mut streams = vec![Stream::dvl(dvl, &dvl_time, &cfg)];
        if aiding.depth_given {
            streams.push(Stream::depth(
                &aiding.depth,
                &aiding.depth_time,
                aiding.depth_sigma,
            ));
        }
        if aiding.fix_given {
            streams.push(Stream::fix(
                &aiding.fix,
                &aiding.fix_time,
                &aiding.fix_sigma,
            ));
        }
        let data = RecordedData {
            imu,
            imu_time,
            t0,
            streams,
            q_time: &q_time,
            q_values: &q_values,
            covariance_time: &covariance_time,
        };
        let mut strat = spec.build(cfg.bias_psd());
        if smooth {
            smooth_recorded_until(&data, init, bias0, &cfg, strat.as_mut(), epochs, cancel)
        } else {
            filter_recorded_until(&data, init, bias0, &cfg, strat.as_mut(), epochs, cancel)
        }
        .map(|out| OutputArrays::new(out, aiding.depth_given, aiding.fix_given))
    })?;
    arrays.into_dict(py)
}

/// The pass's epochs and updates as the arrays of the dict `pronet.FilterResult`
/// takes, owned by Rust until they are handed over.
struct OutputArrays {
    time: Array1<f64>,
    /// With an output step, each row's index among all epochs (empty otherwise).
    epoch: Array1<i64>,
    epochs: EpochArrays,
    /// (0, 4) without the DVL calibration states.
    calibration: Array2<f64>,
    calibration_sigma: Array2<f64>,
    covariance: Array2<f64>,
    /// Per depth reading and position fix: the epoch (-1 outside the run) and NIS.
    depth_epoch: Array1<i64>,
    depth_nis: Array1<f64>,
    fix_epoch: Array1<i64>,
    fix_nis: Array1<f64>,
    /// Per asked-for time: -1 and NaN where a time fell outside the run.
    covariance_epoch: Array1<i64>,
    covariances: Array3<f64>,
    dvl_epoch: Array1<i64>,
    diverged_at: Option<f64>,
    /// Per DVL row: NaN (and not accepted) where a row fell outside the run.
    innovation: Array2<f64>,
    innovation_cov: Array3<f64>,
    nis: Array1<f64>,
    accepted: Array1<bool>,
    gain: Array3<f64>,
    /// None where no DVL row has one.
    adaptive_q: Option<Array3<f64>>,
    /// The smoothed solution's (`pronet.SmoothedResult`).
    smoothed: Option<EpochArrays>,
}

/// A solution's arrays at every epoch: position, velocity, attitude, biases, σ (and
/// a smoothed solution's calibration states).
struct EpochArrays {
    lla: Array2<f64>,
    vel: Array2<f64>,
    rpy: Array2<f64>,
    bias: Array2<f64>,
    sigma: Array2<f64>,
    calibration: Option<(Array2<f64>, Array2<f64>)>,
}

impl EpochArrays {
    /// The bias and σ arrays take over their vectors without a copy.
    fn new(nav: &[NavState], bias: Vec<[f64; 6]>, sigma: Vec<[f64; 15]>) -> Self {
        Self {
            lla: rows_array(nav.iter().map(|n| n.lla.into())),
            vel: rows_array(nav.iter().map(|n| n.vel.into())),
            rpy: rows_array(nav.iter().map(|n| euler_from_dcm(&n.dcm).into())),
            bias: Array2::from(bias),
            sigma: Array2::from(sigma),
            calibration: None,
        }
    }

    fn smoothed(s: Smoothed) -> Self {
        let calibration = (
            Array2::from(s.calibration),
            Array2::from(s.calibration_sigma),
        );
        Self {
            calibration: Some(calibration),
            ..Self::new(&s.nav, s.bias, s.sigma)
        }
    }

    /// Each array handed to NumPy without a copy, into `d`.
    fn fill(self, py: Python<'_>, d: &Bound<'_, PyDict>) -> PyResult<()> {
        d.set_item("lla", self.lla.into_pyarray(py))?;
        d.set_item("vel", self.vel.into_pyarray(py))?;
        d.set_item("rpy", self.rpy.into_pyarray(py))?;
        d.set_item("bias", self.bias.into_pyarray(py))?;
        if let Some((calibration, sigma)) = self.calibration {
            d.set_item("calibration", calibration.into_pyarray(py))?;
            d.set_item("calibration_sigma", sigma.into_pyarray(py))?;
        }
        d.set_item("sigma", self.sigma.into_pyarray(py))
    }
}

impl OutputArrays {
    /// The epochs' time, bias, sigma and calibration arrays take over the output's
    /// vectors without a copy.
    fn new(mut out: FilterOutput, depth: bool, fix: bool) -> Self {
        let mut streams = std::mem::take(&mut out.streams).into_iter();
        let dvl = streams.next().unwrap_or_default();
        let depth = if depth { streams.next() } else { None }.unwrap_or_default();
        let fix = if fix { streams.next() } else { None }.unwrap_or_default();
        let m = dvl.updates.len();
        let smoothed = out.smoothed.take().map(EpochArrays::smoothed);
        let p = out.final_covariance;
        let nan3 = [f64::NAN; 3];
        let StreamRecord {
            epoch: dvl_epoch,
            updates,
            adaptive_q,
            ..
        } = dvl;
        Self {
            epochs: EpochArrays::new(&out.nav, out.bias, out.sigma),
            time: Array1::from(out.time),
            epoch: out.epoch.iter().map(|&e| e as i64).collect(),
            calibration: Array2::from(out.calibration),
            calibration_sigma: Array2::from(out.calibration_sigma),
            covariance: Array2::from_shape_fn((15, 15), |(i, j)| p[(i, j)]),
            covariance_epoch: epochs_array(&out.covariance_epoch),
            depth_epoch: epochs_array(&depth.epoch),
            depth_nis: Array1::from(depth.nis),
            fix_epoch: epochs_array(&fix.epoch),
            fix_nis: Array1::from(fix.nis),
            covariances: Array3::from_shape_fn((out.covariances.len(), 15, 15), |(k, i, j)| {
                out.covariances[k].map_or(f64::NAN, |p| p[(i, j)])
            }),
            dvl_epoch: epochs_array(&dvl_epoch),
            diverged_at: out.nis_monitor.diverged_at,
            innovation: rows_array(
                updates
                    .iter()
                    .map(|u| u.as_ref().map_or(nan3, |u| u.innovation.into())),
            ),
            innovation_cov: Array3::from_shape_fn((m, 3, 3), |(k, i, j)| {
                updates[k].as_ref().map_or(f64::NAN, |u| u.s[(i, j)])
            }),
            nis: updates
                .iter()
                .map(|u| u.as_ref().map_or(f64::NAN, |u| u.nis))
                .collect(),
            accepted: updates
                .iter()
                .map(|u| u.as_ref().is_some_and(|u| u.accepted))
                .collect(),
            gain: Array3::from_shape_fn((m, 15, 3), |(k, i, j)| {
                updates[k].as_ref().map_or(f64::NAN, |u| u.gain[(i, j)])
            }),
            // None where no row has one: NumPy gives the all-NaN array as a view.
            adaptive_q: adaptive_q.iter().any(Option::is_some).then(|| {
                Array3::from_shape_fn((m, 15, 15), |(k, i, j)| {
                    adaptive_q[k].as_ref().map_or(f64::NAN, |q| q[(i, j)])
                })
            }),
            smoothed,
        }
    }

    /// The dict, each array handed to NumPy without a copy.
    fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("time", self.time.into_pyarray(py))?;
        d.set_item("epoch", self.epoch.into_pyarray(py))?;
        self.epochs.fill(py, &d)?;
        d.set_item("calibration", self.calibration.into_pyarray(py))?;
        d.set_item("calibration_sigma", self.calibration_sigma.into_pyarray(py))?;
        d.set_item("covariance", self.covariance.into_pyarray(py))?;
        d.set_item("covariance_epoch", self.covariance_epoch.into_pyarray(py))?;
        d.set_item("depth_epoch", self.depth_epoch.into_pyarray(py))?;
        d.set_item("depth_nis", self.depth_nis.into_pyarray(py))?;
        d.set_item("fix_epoch", self.fix_epoch.into_pyarray(py))?;
        d.set_item("fix_nis", self.fix_nis.into_pyarray(py))?;
        d.set_item("covariances", self.covariances.into_pyarray(py))?;
        d.set_item("dvl_epoch", self.dvl_epoch.into_pyarray(py))?;
        d.set_item("diverged_at", self.diverged_at)?;
        d.set_item("innovation", self.innovation.into_pyarray(py))?;
        d.set_item("innovation_cov", self.innovation_cov.into_pyarray(py))?;
        d.set_item("nis", self.nis.into_pyarray(py))?;
        d.set_item("accepted", self.accepted.into_pyarray(py))?;
        d.set_item("gain", self.gain.into_pyarray(py))?;
        match self.adaptive_q {
            Some(q) => d.set_item("adaptive_q", q.into_pyarray(py))?,
            None => d.set_item("adaptive_q", py.None())?,
        }
        match self.smoothed {
            Some(s) => {
                let smoothed = PyDict::new(py);
                s.fill(py, &smoothed)?;
                d.set_item("smoothed", smoothed)?;
            }
            None => d.set_item("smoothed", py.None())?,
        }
        Ok(d)
    }
}

/// Epoch indices, -1 for None (a row outside the run).
fn epochs_array(epochs: &[Option<usize>]) -> Array1<i64> {
    epochs.iter().map(|e| e.map_or(-1, |k| k as i64)).collect()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_filter, m)?)
}
