//! `run_filter`: one filter pass over given IMU arrays and sensor streams.

use super::call::{interruptible, invalid, to_py_err};
use super::config::PyFilterConfig;
use super::convert::{
    arg_epochs, arg_smooth, arg_t0, as_rows, as_values, column, fixed_or, nav_state,
    readonly_column, readonly_rows, rows, rows_array,
};
use super::strategy::PyStrategy;
use super::streams::{stream_items, stream_ref, StreamRef};
use crate::attitude::euler_from_dcm;
use crate::mechanization::NavState;
use crate::pass::Extent;
use crate::recorded::{
    filter_recorded_until, smooth_recorded_until, Epochs, FilterOutput, RecordedData, StreamRecord,
};
use crate::smoother::Smoothed;
use nalgebra::SMatrix;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

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

/// One filter pass: :func:`pronet.run_filter` (its arguments, ``config`` required),
/// returning the dict :class:`pronet.FilterResult` is made of. ``streams``: a sequence
/// of :class:`Dvl`, :class:`Depth`, :class:`Fix` and :class:`Heading`, applied at an
/// epoch in this order. Key ``streams``: a dict per stream, in order, of ``kind``
/// (``"velocity"``, ``"depth"``, ``"fix"`` or ``"heading"``), ``epoch`` (r,) (-1
/// outside the run), ``nis`` (r,) (NaN outside) and, for a velocity stream,
/// ``innovation``, ``innovation_cov``, ``gain``, ``accepted``, ``adaptive_q`` (None where
/// no row has one, as the top-level key). The top-level update keys are the first
/// velocity, depth and fix stream's (the same arrays; no rows without one; a heading has
/// none). ``smoothed``: a dict of ``lla``, ``vel``, ``rpy``, ``bias``, ``sigma``,
/// ``calibration``, ``calibration_sigma`` per epoch, or None. ``extent``: the forward
/// pass's ``(bound, t_bound, σ_ψD², t_heading)`` (:class:`pronet.stats.Extent`), watched
/// at every epoch, kept or not: the bound (``"non-finite"``, ``"speed"``, ``"height"``,
/// ``"position-sigma"``; "" where none) the solution first broke and when [s], the largest
/// heading variance [rad²] and when its σ first passed :data:`MAX_LINEAR_HEADING_SIGMA_DEG`
/// (the close of the covariance step it passed in; NaN where none did). Before it
/// allocates, a pass that would hold more than this process can still take is a ``ValueError``
/// naming the argument that bounds the most of it (``output_step``, ``streams``,
/// ``strategy``, ``covariance_time`` or ``smooth``) with the estimate (docs/results/performance.md,
/// "Memory").
#[pyfunction]
#[pyo3(signature = (imu, imu_time, streams, *, t0, lla0, vel0, rpy0, config, strategy, bias0 = None, q_time = None, q = None, epochs = "all".to_string(), output_step = None, covariance_time = None, smooth = false),
    text_signature = "(imu, imu_time, streams, *, t0, lla0, vel0, rpy0, config, strategy, bias0=None, q_time=None, q=None, epochs='all', output_step=None, covariance_time=None, smooth=False)")]
#[allow(clippy::too_many_arguments)]
fn run_filter<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    imu_time: &Bound<'py, PyAny>,
    streams: &Bound<'py, PyAny>,
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
    #[pyo3(from_py_with = arg_smooth)] smooth: bool,
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
    // The streams are frozen objects holding their arrays: borrowed, not copied.
    let items = stream_items(streams)?;
    let sources: Vec<StreamRef<'_>> = (items.iter().enumerate())
        .map(|(i, item)| stream_ref(i, item))
        .collect::<PyResult<_>>()?;
    let covariance_time = match covariance_time {
        Some(times) => column(times, "covariance_time")?,
        None => Vec::new(),
    };
    let init = nav_state(lla0, vel0, rpy0)?;
    let bias0 = fixed_or::<6>(bias0, "bias0", [0.0; 6])?;
    let cfg = config.inner.clone();
    let spec = strategy.inner.clone();
    // The arrays are built on the worker thread too, without the GIL: pronet real
    // runs sections on threads, which would otherwise queue for it while one of them
    // copies its ~40 MB of results.
    let arrays = interruptible(py, move |cancel| {
        let streams = sources
            .iter()
            .enumerate()
            .map(|(i, s)| s.stream(i, &cfg))
            .collect();
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
        let kinds: Vec<Kind> = data.streams.iter().map(Kind::of).collect();
        if smooth {
            smooth_recorded_until(&data, init, bias0, &cfg, strat.as_mut(), epochs, cancel)
        } else {
            filter_recorded_until(&data, init, bias0, &cfg, strat.as_mut(), epochs, cancel)
        }
        .map(|out| OutputArrays::new(out, &kinds))
    })?;
    arrays.into_dict(py)
}

/// What a stream reads, for the top-level keys (the first stream of each kind).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Velocity,
    Depth,
    Fix,
    Heading,
}

impl Kind {
    const ALL: [Kind; 4] = [Kind::Velocity, Kind::Depth, Kind::Fix, Kind::Heading];

    fn of(stream: &crate::recorded::Stream<'_>) -> Self {
        use crate::recorded::Values;
        match stream.values {
            Values::Velocity { .. } => Kind::Velocity,
            Values::Depth { .. } => Kind::Depth,
            Values::Fix { .. } => Kind::Fix,
            Values::Heading { .. } => Kind::Heading,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Kind::Velocity => "velocity",
            Kind::Depth => "depth",
            Kind::Fix => "fix",
            Kind::Heading => "heading",
        }
    }

    /// The top-level keys of the first stream of the kind, its epochs and NIS: the
    /// sensors `pronet.FilterResult` had keys for before the streams (a heading has
    /// none: its stream's result is in `streams` only).
    fn keys(self) -> Option<(&'static str, &'static str)> {
        match self {
            Kind::Velocity => Some(("dvl_epoch", "nis")),
            Kind::Depth => Some(("depth_epoch", "depth_nis")),
            Kind::Fix => Some(("fix_epoch", "fix_nis")),
            Kind::Heading => None,
        }
    }
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
    /// Per asked-for time: -1 and NaN where a time fell outside the run.
    covariance_epoch: Array1<i64>,
    covariances: Array3<f64>,
    diverged_at: Option<f64>,
    /// What the forward pass watched at every epoch, for its health.
    extent: Extent,
    /// Each stream's rows, in the order given, with its kind.
    streams: Vec<(Kind, StreamArrays)>,
    /// The smoothed solution's (`pronet.SmoothedResult`).
    smoothed: Option<EpochArrays>,
}

/// What a pass did with each row of one stream: the epoch (-1 outside the run) and
/// the NIS (NaN outside), and a velocity stream's updates.
struct StreamArrays {
    epoch: Array1<i64>,
    nis: Array1<f64>,
    velocity: Option<VelocityArrays>,
}

/// A velocity stream's updates, per row: NaN (and not accepted) where a row fell
/// outside the run.
struct VelocityArrays {
    innovation: Array2<f64>,
    innovation_cov: Array3<f64>,
    accepted: Array1<bool>,
    gain: Array3<f64>,
    /// None where no row has one.
    adaptive_q: Option<Array3<f64>>,
}

impl StreamArrays {
    fn new(record: StreamRecord, kind: Kind) -> Self {
        let StreamRecord {
            epoch,
            nis,
            updates,
            adaptive_q,
        } = record;
        if kind != Kind::Velocity {
            return Self {
                epoch: epochs_array(&epoch),
                nis: Array1::from(nis),
                velocity: None,
            };
        }
        let nan3 = [f64::NAN; 3];
        let velocity = VelocityArrays {
            innovation: rows_array(
                updates
                    .iter()
                    .map(|u| u.as_ref().map_or(nan3, |u| u.innovation.into())),
            ),
            innovation_cov: stacked(&updates, |u| &u.s),
            accepted: updates
                .iter()
                .map(|u| u.as_ref().is_some_and(|u| u.accepted))
                .collect(),
            gain: stacked(&updates, |u| &u.gain),
            // None where no row has one: NumPy gives the all-NaN array as a view.
            adaptive_q: adaptive_q
                .iter()
                .any(Option::is_some)
                .then(|| stacked(&adaptive_q, |q| &**q)),
        };
        Self {
            epoch: epochs_array(&epoch),
            // A velocity row's NIS is its update's (NaN outside the run).
            nis: updates
                .iter()
                .map(|u| u.as_ref().map_or(f64::NAN, |u| u.nis))
                .collect(),
            velocity: Some(velocity),
        }
    }

    /// The stream's dict, each array handed to NumPy without a copy; the first
    /// stream of its kind also fills the top-level keys of `top` with the same arrays
    /// (a kind that has them: [`Kind::keys`]).
    fn into_dict<'py>(
        self,
        py: Python<'py>,
        kind: Kind,
        top: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("kind", kind.name())?;
        let (epoch_key, nis_key) = kind.keys().unwrap_or_default();
        let top = top.filter(|_| kind.keys().is_some());
        let mut items = vec![
            ("epoch", epoch_key, self.epoch.into_pyarray(py).into_any()),
            ("nis", nis_key, self.nis.into_pyarray(py).into_any()),
        ];
        if let Some(v) = self.velocity {
            let adaptive_q = match v.adaptive_q {
                Some(q) => q.into_pyarray(py).into_any(),
                None => py.None().into_bound(py),
            };
            items.extend([
                (
                    "innovation",
                    "innovation",
                    v.innovation.into_pyarray(py).into_any(),
                ),
                (
                    "innovation_cov",
                    "innovation_cov",
                    v.innovation_cov.into_pyarray(py).into_any(),
                ),
                (
                    "accepted",
                    "accepted",
                    v.accepted.into_pyarray(py).into_any(),
                ),
                ("gain", "gain", v.gain.into_pyarray(py).into_any()),
                ("adaptive_q", "adaptive_q", adaptive_q),
            ]);
        }
        for (key, top_key, value) in items {
            if let Some(top) = top {
                top.set_item(top_key, &value)?;
            }
            d.set_item(key, value)?;
        }
        Ok(d)
    }
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
    /// A forward solution's arrays: position, velocity and attitude made from its
    /// states where it kept them for the smoother, else taking over its rows; its
    /// bias and σ taking over their vectors.
    fn new(out: &mut FilterOutput) -> Self {
        use std::mem::take;
        let (bias, sigma) = (take(&mut out.bias), take(&mut out.sigma));
        if out.nav.is_empty() {
            Self {
                lla: Array2::from(take(&mut out.lla)),
                vel: Array2::from(take(&mut out.vel)),
                rpy: Array2::from(take(&mut out.rpy)),
                bias: Array2::from(bias),
                sigma: Array2::from(sigma),
                calibration: None,
            }
        } else {
            Self::of_states(&out.nav, bias, sigma)
        }
    }

    /// Position, velocity and attitude made from the states `nav`; the bias and σ
    /// arrays taking over their vectors.
    fn of_states(nav: &[NavState], bias: Vec<[f64; 6]>, sigma: Vec<[f64; 15]>) -> Self {
        Self {
            lla: rows_array(nav.iter().map(|n| n.lla.into())),
            vel: rows_array(nav.iter().map(|n| n.vel.into())),
            rpy: rows_array(nav.iter().map(|n| euler_from_dcm(&n.dcm).into())),
            bias: Array2::from(bias),
            sigma: Array2::from(sigma),
            calibration: None,
        }
    }

    /// A smoothed solution's arrays.
    fn smoothed(s: Smoothed) -> Self {
        let calibration = (
            Array2::from(s.calibration),
            Array2::from(s.calibration_sigma),
        );
        Self {
            calibration: Some(calibration),
            ..Self::of_states(&s.nav, s.bias, s.sigma)
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
    fn new(mut out: FilterOutput, kinds: &[Kind]) -> Self {
        let streams = std::mem::take(&mut out.streams);
        let smoothed = out.smoothed.take().map(EpochArrays::smoothed);
        let p = out.final_covariance;
        Self {
            epochs: EpochArrays::new(&mut out),
            time: Array1::from(out.time),
            epoch: out.epoch.iter().map(|&e| e as i64).collect(),
            calibration: Array2::from(out.calibration),
            calibration_sigma: Array2::from(out.calibration_sigma),
            covariance: Array2::from_shape_fn((15, 15), |(i, j)| p[(i, j)]),
            covariance_epoch: epochs_array(&out.covariance_epoch),
            covariances: Array3::from_shape_fn((out.covariances.len(), 15, 15), |(k, i, j)| {
                out.covariances[k].map_or(f64::NAN, |p| p[(i, j)])
            }),
            diverged_at: out.nis_monitor.diverged_at,
            extent: out.extent,
            streams: streams
                .into_iter()
                .zip(kinds)
                .map(|(record, &kind)| (kind, StreamArrays::new(record, kind)))
                .collect(),
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
        d.set_item("covariances", self.covariances.into_pyarray(py))?;
        d.set_item("diverged_at", self.diverged_at)?;
        d.set_item("extent", extent_tuple(&self.extent))?;
        let mut first = Kind::ALL.map(|_| true);
        let per_stream = PyList::empty(py);
        for (kind, arrays) in self.streams {
            let slot = &mut first[kind as usize];
            let top = std::mem::replace(slot, false).then_some(&d);
            per_stream.append(arrays.into_dict(py, kind, top)?)?;
        }
        // Without a stream of a kind, its top-level keys hold no rows.
        for (kind, missing) in Kind::ALL.into_iter().zip(first) {
            if missing && kind.keys().is_some() {
                StreamArrays::new(StreamRecord::default(), kind).into_dict(py, kind, Some(&d))?;
            }
        }
        d.set_item("streams", per_stream)?;
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

/// Each row's `R × C` matrix, row-major, NaN where a row has none: `(m, R, C)`,
/// built row by row (not element by element) and handed over without a copy.
fn stacked<T, const R: usize, const C: usize>(
    rows: &[Option<T>],
    matrix: impl Fn(&T) -> &SMatrix<f64, R, C>,
) -> Array3<f64> {
    let rows: Vec<[[f64; C]; R]> = rows
        .iter()
        .map(|row| match row {
            Some(row) => {
                let m = matrix(row);
                std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
            }
            None => [[f64::NAN; C]; R],
        })
        .collect();
    Array3::from(rows)
}

/// Epoch indices, -1 for None (a row outside the run).
fn epochs_array(epochs: &[Option<usize>]) -> Array1<i64> {
    epochs.iter().map(|e| e.map_or(-1, |k| k as i64)).collect()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_filter, m)?)
}

/// A pass's [`Extent`] as Python takes it (`pronet.stats.Extent`): the bound the
/// solution first broke ("" where none) and when \[s\], the largest heading variance
/// \[rad²\] and when its σ passed 5° (NaN where it did not).
pub(super) fn extent_tuple(e: &Extent) -> (&'static str, f64, f64, f64) {
    let (bound, at) = e.diverged.map_or(("", f64::NAN), |(t, b)| (b.name(), t));
    (bound, at, e.heading2, e.heading_over)
}
