//! What a simulated run holds ([`RunMemory`]), for the estimate a Monte Carlo or an
//! ensemble checks before it allocates ([`crate::memory`]): its records (kept to the
//! end of the call), and while it steps, the run itself and, smoothed, its smoother's
//! log and backward pass.

use super::History;
use crate::ekf::FilterConfig;
use crate::mechanization::NavState;
use crate::memory::grown;
use crate::scenario::Scenario;
use crate::sensors::aiding::steps_per;
use crate::smoother::memory::{
    close_bytes, kept_close_bytes, node_bytes, node_covariance_bytes, NodeKind,
};
use crate::smoother::Node;
use std::mem::size_of;

/// What a run allocates besides its records and its smoother's log \[bytes\]: the
/// filter, the strategy and the simulated sensors.
pub const RUN_BYTES: usize = 8 * 1024;

/// What one run of a scenario holds \[bytes\].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunMemory {
    /// Its record's NIS and NEES at the DVL epochs (smoothed too) and the record.
    pub epochs: f64,
    /// Its histories (smoothed too).
    pub histories: f64,
    /// The run while it steps, without its smoother.
    pub running: f64,
    /// Its smoother's log and backward pass (none unless smoothed).
    pub smoother: f64,
}

impl RunMemory {
    /// [`RunMemory::of`] for a run and a record of `run` and `record` bytes.
    pub(super) fn with_sizes(
        scenario: &Scenario,
        cfg: &FilterConfig,
        (dvl_every, record_every, window): (Option<usize>, usize, usize),
        (smooth, discrete): (bool, bool),
        (run, record): (usize, usize),
    ) -> Self {
        let n = scenario.truth.len() as f64;
        let dvl = dvl_every.map_or(0.0, |every| (n / every.max(1) as f64).floor());
        let records = match record_every {
            0 => 0.0,
            every => (n / every as f64).floor() + 1.0,
        };
        let twice = if smooth { 2.0 } else { 1.0 };
        let calibrated = cfg.dvl_calibration.is_some();
        // NIS, five NEES blocks and (with the calibration states) their NEES; the
        // smoothed NEES again.
        let per_epoch = (1 + 5 + usize::from(calibrated)) as f64 * 8.0;
        let per_record = size_of::<[f64; 36]>() as f64;
        let smoother = if smooth {
            smoother_bytes(scenario, cfg, (dvl_every, dvl, records), discrete)
        } else {
            0.0
        };
        Self {
            epochs: twice * dvl * per_epoch + record as f64,
            histories: twice * records * per_record,
            // The window's samples are kept, copied out and handed over at each instant.
            running: (run + RUN_BYTES + 3 * window * size_of::<[f32; 6]>()) as f64,
            smoother,
        }
    }
}

/// What a run's smoother holds at its peak \[bytes\], at the end of the run: its log
/// (the forward solution at every epoch and, at every sample, the raw IMU and bias
/// estimates; the nodes; under a covariance step the closes) and the backward pass
/// over it (the terms of every epoch, the solutions where read whole, the smoothed
/// covariance at each node, the closes of the longest stretch without a reading).
/// `dvl`: the DVL epochs; `records`: the recorded epochs.
fn smoother_bytes(
    scenario: &Scenario,
    cfg: &FilterConfig,
    (dvl_every, dvl, records): (Option<usize>, f64, f64),
    discrete: bool,
) -> f64 {
    let truth = &scenario.truth;
    let n = truth.len() as f64;
    let epochs = n + 1.0;
    let calibrated = cfg.dvl_calibration.is_some();
    let every_sample = cfg.covariance_every_sample();
    let sensors = &scenario.sensors;
    let aiding = |period: Option<f64>| {
        period
            .and_then(|p| steps_per(p, truth.dt, "").ok())
            .map_or(0.0, |every| (n / every as f64).floor())
    };
    let depth = aiding(sensors.depth.as_ref().map(|d| d.period));
    let heading = aiding(sensors.heading.as_ref().map(|h| h.period));
    let fixes: f64 = (sensors.fixes.iter())
        .map(|f| match f.period > 0.0 {
            true => aiding(Some(f.period)),
            false => f.times.len() as f64,
        })
        .sum();
    let nodes = dvl + depth + heading + fixes + 2.0;
    let mut log = epochs * size_of::<NavState>() as f64;
    if every_sample {
        log += epochs * size_of::<[[f64; 6]; 2]>() as f64;
    } else {
        let per_step = (cfg.covariance_step / truth.dt).floor().max(1.0);
        log += (n / per_step + dvl + 2.0) * kept_close_bytes(calibrated) as f64;
    }
    if calibrated {
        log += grown(epochs) * size_of::<crate::ekf::calibration::DvlErrors>() as f64;
    }
    let whole = size_of::<(usize, [f64; 6], [f64; 6])>() as f64;
    log += grown(records + dvl) * whole + grown(dvl) * size_of::<Option<usize>>() as f64;
    let kind = NodeKind {
        discrete,
        calibrated,
        prior: every_sample && !calibrated,
    };
    let inline = size_of::<Node>() as f64;
    log += grown(nodes) * inline + nodes * (node_bytes(kind) as f64 - inline);
    // The backward pass: per epoch its index among the whole ones and its error terms;
    // the solutions read whole (twice: in a map too), σ at the recorded epochs, the
    // smoothed covariance at the nodes.
    let mut backward = epochs * (size_of::<u32>() + size_of::<Option<[f64; 3]>>()) as f64;
    let solution = size_of::<(usize, NavState, [f64; 6])>() as f64;
    backward += (records + dvl) * 2.0 * solution;
    backward += grown(records) * size_of::<(usize, [f64; 15])>() as f64;
    backward += nodes * node_covariance_bytes() as f64;
    let stretch = longest_stretch(scenario, dvl_every) as f64;
    let closes = if every_sample {
        stretch
    } else {
        (stretch * truth.dt / cfg.covariance_step).ceil() + 2.0
    };
    backward += grown(closes) * close_bytes(calibrated, every_sample, false) as f64;
    log + backward
}

/// The most IMU steps of a run without a reading: the DVL's period and its longest
/// outage, or the period of the depth sensor or the compass where shorter (a random
/// dropout's gaps are not counted); the whole run without any.
fn longest_stretch(scenario: &Scenario, dvl_every: Option<usize>) -> usize {
    let truth = &scenario.truth;
    let n = truth.len();
    let sensors = &scenario.sensors;
    let outage = (sensors.dvl.outages.iter())
        .map(|o| ((o[1] - o[0]) / truth.dt).ceil().max(0.0) as usize)
        .max()
        .unwrap_or(0);
    let mut stretch = dvl_every.map_or(n, |every| every.saturating_add(outage));
    let periods = [
        sensors.depth.as_ref().map(|d| d.period),
        sensors.heading.as_ref().map(|h| h.period),
    ];
    for every in periods.into_iter().flatten() {
        if let Ok(every) = steps_per(every, truth.dt, "") {
            stretch = stretch.min(every);
        }
    }
    stretch.min(n)
}

impl History {
    /// Empty, with room for `records` epochs.
    pub(super) fn with_capacity(records: usize) -> Self {
        Self {
            error: Vec::with_capacity(records),
            sigma: Vec::with_capacity(records),
            imu_variance: Vec::with_capacity(records),
        }
    }
}
