//! `Navigator`: the filter pass fed as data arrives ([`crate::online::Navigator`]).

use super::call::{detached, invalid, to_py_err};
use super::config::PyFilterConfig;
use super::convert::{
    arg_t0, as_rows, as_values, column, fixed, fixed_or, nav_state, readonly_column, readonly_rows,
    real_arg, whole_arg,
};
use super::filter::extent_tuple;
use super::strategy::PyStrategy;
use super::streams::{stream_items, stream_ref};
use crate::attitude::euler_from_dcm;
use crate::online::{Fate, Lag, Navigator, Sensor, Start, Tuning};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyList};

/// The filter pass fed as the data arrives: :class:`pronet.recorded.online.Navigator`
/// (its documentation is there). ``streams``: :class:`Dvl`, :class:`Depth`, :class:`Fix` and
/// :class:`Heading` without rows, describing the sensors (noise, frame, lever arm,
/// gate), whose readings are applied at an epoch in this order. ``lag`` [s] (finite,
/// >= 0): how late a reading may be stamped before the newest IMU sample and still be
/// applied at its own epoch; ``checkpoint_every`` (>= 1): a copy of the filter every so
/// many epochs. ``tuning_period`` [s] with ``imu_dt`` [s] and ``window`` (samples): the
/// learned loop's instants, as :func:`tuning_instants` places them. A feed whose lag
/// window's history is about to outgrow the memory this process can still take is a
/// ``ValueError`` naming ``lag`` (docs/results/performance.md, "Memory").
#[pyclass(name = "Navigator", module = "pronet._core")]
pub struct PyNavigator {
    inner: Navigator,
}

/// Six finite numbers: a float64 NumPy array read in place, anything else checked.
fn imu_sample(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<[f64; 6]> {
    if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        if let Ok(s) = a.as_slice() {
            if let Ok(v) = <[f64; 6]>::try_from(s) {
                return Ok(v);
            }
        }
    }
    fixed::<6>(obj, arg)
}

/// A reading's values or σ: a real number or a 1-D array of them (finite or not: the
/// core checks them, a fix's height may be NaN).
fn numbers(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<f64>> {
    if obj.len().is_ok() {
        return column(obj, arg);
    }
    Ok(vec![real_arg(obj, arg)?])
}

/// A time [s]: a float (NumPy's float64 too, a subclass) read at once (one IMU sample
/// at a time), any other real number checked by [`real_arg`].
fn time_arg(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    match obj.cast::<PyFloat>() {
        Ok(f) => Ok(f.value()),
        Err(_) => real_arg(obj, "time"),
    }
}

fn fate_name(fate: Fate) -> &'static str {
    match fate {
        Fate::Queued => "queued",
        Fate::Current => "current",
        Fate::Late => "late",
        Fate::Refused => "refused",
        Fate::Skipped => "skipped",
    }
}

#[pymethods]
impl PyNavigator {
    #[new]
    #[pyo3(signature = (streams, *, t0, lla0, vel0, rpy0, config, strategy, bias0 = None, lag = None, checkpoint_every = None, tuning_period = None, imu_dt = None, window = None))]
    #[pyo3(
        text_signature = "(streams, *, t0, lla0, vel0, rpy0, config, strategy, bias0=None, lag=1.0, checkpoint_every=32, tuning_period=None, imu_dt=None, window=200)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        streams: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arg_t0)] t0: f64,
        lla0: &Bound<'_, PyAny>,
        vel0: &Bound<'_, PyAny>,
        rpy0: &Bound<'_, PyAny>,
        config: &PyFilterConfig,
        strategy: &PyStrategy,
        bias0: Option<&Bound<'_, PyAny>>,
        lag: Option<&Bound<'_, PyAny>>,
        checkpoint_every: Option<&Bound<'_, PyAny>>,
        tuning_period: Option<&Bound<'_, PyAny>>,
        imu_dt: Option<&Bound<'_, PyAny>>,
        window: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let cfg = config.inner.clone();
        let items = stream_items(streams)?;
        let mut sensors = Vec::with_capacity(items.len());
        for (i, item) in items.iter().enumerate() {
            let stream = stream_ref(i, item)?.stream(i, &cfg);
            if !stream.is_empty() {
                return Err(invalid(
                    &format!("streams[{i}]"),
                    format!(
                        "a navigator's stream describes its sensor and holds no rows (got {}); \
                         feed its readings with reading() or readings()",
                        stream.len()
                    ),
                ));
            }
            sensors.push(Sensor::of(&stream).map_err(to_py_err)?);
        }
        let lag = Lag {
            window: lag.map_or(Ok(Lag::default().window), |l| real_arg(l, "lag"))?,
            every: checkpoint_every.map_or(Ok(Lag::default().every), |c| {
                whole_arg(c, "checkpoint_every")
            })?,
        };
        let tuning = match (tuning_period, imu_dt) {
            (None, None) => None,
            (Some(p), Some(dt)) => {
                let window = window.map_or(Ok(200), |w| whole_arg(w, "window"))?;
                let (p, dt) = (real_arg(p, "tuning_period")?, real_arg(dt, "imu_dt")?);
                Some(Tuning::new(dt, window, p).map_err(to_py_err)?)
            }
            _ => {
                return Err(invalid(
                    "tuning_period",
                    "tuning_period and imu_dt go together: give both or neither",
                ))
            }
        };
        let start = Start {
            t0,
            nav: nav_state(lla0, vel0, rpy0)?,
            bias: fixed_or::<6>(bias0, "bias0", [0.0; 6])?,
        };
        let strategy = strategy.inner.build(cfg.bias_psd());
        let inner = detached(py, move || {
            Navigator::new(start, &cfg, strategy, sensors, lag, tuning)
        })?;
        Ok(Self { inner })
    }

    /// Feed one IMU sample ``[f (m/s²), ω (rad/s)]`` (body FRD) ending at ``time`` [s].
    fn imu(
        &mut self,
        py: Python<'_>,
        #[pyo3(from_py_with = time_arg)] time: f64,
        sample: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let raw = imu_sample(sample, "imu")?;
        let nav = &mut self.inner;
        detached(py, move || nav.feed_imu(time, &raw))
    }

    /// Feed IMU samples ``(n, 6)`` ending at ``times`` ``(n,)`` [s], in order, stopping
    /// after a tuning instant (:attr:`tuning_due`): the number fed. Every sample and time
    /// is checked first: a block with a bad one feeds none.
    fn imu_block(
        &mut self,
        py: Python<'_>,
        times: &Bound<'_, PyAny>,
        samples: &Bound<'_, PyAny>,
    ) -> PyResult<usize> {
        let t = readonly_column(times, "imu_time")?;
        let s = readonly_rows::<6>(samples, "imu")?;
        let (t, s) = (as_values(&t), as_rows::<6>(&s));
        if t.len() != s.len() {
            return Err(invalid(
                "imu_time",
                format!("has {} rows but imu has {}", t.len(), s.len()),
            ));
        }
        let nav = &mut self.inner;
        detached(py, move || nav.feed_imu_block(&t, &s))
    }

    /// Feed the reading ``value`` of ``streams[stream]`` stamped ``time`` [s], with its
    /// own 1σ ``sigma`` (None: the stream's): ``"queued"``, ``"current"``, ``"late"``,
    /// ``"refused"`` or ``"skipped"``.
    #[pyo3(signature = (stream, time, value, sigma = None))]
    fn reading(
        &mut self,
        py: Python<'_>,
        stream: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = time_arg)] time: f64,
        value: &Bound<'_, PyAny>,
        sigma: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<&'static str> {
        let stream: usize = whole_arg(stream, "stream")?;
        let value = numbers(value, "value")?;
        let sigma = sigma.map(|s| numbers(s, "sigma")).transpose()?;
        let nav = &mut self.inner;
        let fate = detached(py, move || {
            nav.feed_reading(stream, time, &value, sigma.as_deref())
        })?;
        Ok(fate_name(fate))
    }

    /// Set the IMU variances ``q`` (6) from the next IMU step on (an external strategy).
    fn set_q(&mut self, py: Python<'_>, q: &Bound<'_, PyAny>) -> PyResult<()> {
        let q = fixed::<6>(q, "q")?;
        let nav = &mut self.inner;
        detached(py, move || nav.set_q(q))
    }

    /// The newest epoch: the number of IMU samples fed.
    #[getter]
    fn epoch(&self) -> usize {
        self.inner.epoch()
    }

    /// Whether the newest epoch is a tuning instant (set q before the next sample).
    #[getter]
    fn tuning_due(&self) -> bool {
        self.inner.tuning_due()
    }

    /// The learned loop's window ``(6, window)`` float32, oldest sample first (None
    /// without a tuning or before it is full).
    #[getter]
    fn window<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f32>>> {
        let w = self.inner.window()?;
        let a = Array2::from_shape_fn((6, w.len()), |(c, k)| w[k][c] as f32);
        Some(a.into_pyarray(py))
    }

    /// The error that stopped the navigator, or None.
    #[getter]
    fn failure(&self) -> Option<String> {
        self.inner.failure().map(ToString::to_string)
    }

    /// The estimate at the newest epoch: a dict of ``epoch``, ``time`` [s], ``lla``
    /// [rad, rad, m], ``vel`` [m/s NED], ``rpy`` [rad], ``bias`` (6), ``sigma`` (15,
    /// brought up to date), ``calibration`` and ``calibration_sigma`` (4, or None). A
    /// stopped navigator raises its failure.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.inner.alive().map_err(to_py_err)?;
        let e = self.inner.estimate();
        let d = PyDict::new(py);
        d.set_item("epoch", e.epoch)?;
        d.set_item("time", e.t)?;
        let v3 = |v: [f64; 3]| v.to_vec().into_pyarray(py);
        d.set_item("lla", v3(e.nav.lla.into()))?;
        d.set_item("vel", v3(e.nav.vel.into()))?;
        d.set_item("rpy", v3(euler_from_dcm(&e.nav.dcm).into()))?;
        d.set_item("bias", e.bias.to_vec().into_pyarray(py))?;
        d.set_item("sigma", e.sigma.to_vec().into_pyarray(py))?;
        let (cal, cal_sigma) = e.calibration.unzip();
        d.set_item("calibration", cal.map(|c| c.to_vec().into_pyarray(py)))?;
        d.set_item(
            "calibration_sigma",
            cal_sigma.map(|c| c.to_vec().into_pyarray(py)),
        )?;
        Ok(d)
    }

    /// What the pass watched for its health over every epoch so far (as
    /// ``run_filter``'s ``extent``, :class:`pronet.stats.Extent`).
    fn extent(&self) -> (&'static str, f64, f64, f64) {
        extent_tuple(&self.inner.extent())
    }

    /// The IMU's gaps so far: their number, the first's end [s] and length [s], the
    /// longest's length [s] (NaN: none), and the usual step [s] (:data:`MAX_IMU_GAP`).
    fn imu_gaps(&self) -> (usize, f64, f64, f64, f64) {
        let s = self.inner.stamps();
        let (first_t, first_dt) = s.first.unwrap_or((f64::NAN, f64::NAN));
        let longest = s.longest.map_or(f64::NAN, |(_, dt)| dt);
        (s.gaps, first_t, first_dt, longest, s.usual)
    }

    /// Each stream's tally, a list of dicts in the streams' order: ``name``, ``kind``
    /// (``"velocity"``, ``"depth"``, ``"fix"``, ``"heading"``), ``received``, ``queued``,
    /// ``accepted``, ``rejected`` (by the gate), ``late`` (stamped before the newest IMU
    /// sample when fed), ``refused`` (before the lag window), ``skipped`` (before the
    /// start), ``nis_sum`` and ``dof`` (the applied readings').
    fn tally<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for (t, s) in self.inner.tally().iter().zip(self.inner.sensors()) {
            let d = PyDict::new(py);
            d.set_item("name", s.name())?;
            d.set_item("kind", s.kind())?;
            d.set_item("received", t.received)?;
            d.set_item("queued", t.queued)?;
            d.set_item("accepted", t.accepted)?;
            d.set_item("rejected", t.rejected)?;
            d.set_item("late", t.late)?;
            d.set_item("refused", t.refused)?;
            d.set_item("skipped", t.skipped)?;
            d.set_item("nis_sum", t.nis_sum)?;
            d.set_item("dof", t.dof)?;
            list.append(d)?;
        }
        Ok(list)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyNavigator>()
}
