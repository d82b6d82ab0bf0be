//! What a recorded pass would hold at its peak ([`estimate`]), checked once before the
//! pass allocates ([`crate::memory`]): the kept epochs, each stream's rows, the
//! covariances asked for, and, smoothed, the smoother's nodes and the longest stretch it
//! smooths at once, or the arrays made from the output (whichever is more: the
//! smoother's working memory is gone before they are made).

use super::data::RecordedData;
use super::epochs::Epochs;
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{FilterConfig, Matrix15, UpdateInfo};
use crate::mechanization::NavState;
use crate::memory::{grown, Estimate};
use crate::smoother::memory::{
    close_bytes, node_bytes, node_covariance_bytes, node_state_bytes, smoothed_epoch_bytes,
    NodeKind, BOX_OVERHEAD,
};
use crate::smoother::Node;
use std::mem::size_of;

/// The bytes per epoch of the arrays made from a solution kept as whole states (a
/// smoothed pass's, forward and smoothed): position, velocity and attitude (the bias
/// and σ arrays, and the rows of a pass that kept rows, take over the vectors).
const STATE_ARRAYS: usize = 9 * 8;
/// The bytes per row of the arrays made from a velocity stream's updates: innovation,
/// its covariance, the gain (3 + 9 + 45 values) and whether the gate accepted it.
const VELOCITY_ARRAYS: usize = 57 * 8 + 1;
/// The bytes per row of a stream's epoch and NIS arrays.
const ROW_ARRAYS: usize = 2 * 8;

/// What a pass holds whatever its length \[bytes\]: the filter, its strategy and the
/// buffers of one epoch.
const PASS_BYTES: f64 = 64.0 * 1024.0;

const EPOCHS: &str = "output_step";
const EPOCHS_REMEDY: &str = "keep fewer epochs: an output_step in seconds keeps one per \
                             period (or epochs=\"last\" the last alone)";
const SMOOTH: &str = "smooth";
const STREAMS_REMEDY: &str = "give the streams fewer rows (split the recording into sections)";

/// What a pass holds, in three groups: its output (kept to the end), the smoother's
/// working memory (its nodes and the stretch it smooths at once, dropped before the
/// output is handed over) and the arrays made from the output as it is handed over.
#[derive(Clone, Debug, Default)]
pub struct PassMemory {
    pub output: Estimate,
    pub working: Estimate,
    pub arrays: Estimate,
}

impl PassMemory {
    /// What the call holds at its peak: the output and the more of the working memory
    /// and the arrays.
    pub fn peak(&self) -> Estimate {
        let more = if self.working.bytes() > self.arrays.bytes() {
            &self.working
        } else {
            &self.arrays
        };
        let mut parts = self.output.parts.clone();
        parts.extend(more.parts.iter().cloned());
        Estimate {
            parts,
            fixed: self.output.fixed + more.fixed,
        }
    }
}

/// What a pass over `data` keeping `epochs` would hold, `smooth`ed or not;
/// `discrete`: its strategy sets the per-step Q itself (Mehra), which each velocity
/// row's record and each node keep.
pub fn estimate(
    data: &RecordedData<'_>,
    epochs: Epochs,
    cfg: &FilterConfig,
    smooth: bool,
    discrete: bool,
) -> PassMemory {
    let n = data.imu.len();
    let span = data.imu_time.last().map_or(0.0, |t| t - data.t0);
    let calibrated = cfg.dvl_calibration.is_some();
    let thinned = matches!(epochs, Epochs::Step(_));
    let kept = epochs.kept(n, span) as f64;
    let rows: usize = data.streams.iter().map(|s| s.len()).sum();
    let velocity: usize = data
        .streams
        .iter()
        .filter(|s| s.is_velocity())
        .map(|s| s.len())
        .sum();
    let (rows, velocity) = (rows as f64, velocity as f64);
    let covariances = data.covariance_time.len() as f64;
    // The forward output at each kept epoch: time, the solution (position, velocity
    // and attitude rows; smoothed, the whole state), bias estimates and σ (the
    // calibration states' too), with an output step its index, and smoothed the
    // smoothed solution's.
    let solution = if smooth {
        size_of::<NavState>()
    } else {
        size_of::<[f64; 9]>()
    };
    let mut epoch = size_of::<f64>() + solution + size_of::<[f64; 21]>();
    epoch += usize::from(calibrated) * size_of::<[DvlErrors; 2]>()
        + usize::from(thinned) * size_of::<usize>();
    if smooth {
        epoch += smoothed_epoch_bytes(calibrated);
    }
    let row = size_of::<Option<usize>>() + size_of::<f64>();
    let update = size_of::<Option<UpdateInfo>>() + size_of::<Option<Box<Matrix15>>>();
    let covariance = size_of::<Option<usize>>() + size_of::<Option<Matrix15>>();
    let q = size_of::<Matrix15>();
    // Each group's parts: the same arguments, what each value adds in it.
    let group = |(epoch, row, update, q, covariance): (usize, usize, usize, usize, usize)| {
        let mut e = Estimate::default();
        e.add(EPOCHS, "kept epochs", (kept, epoch as f64), EPOCHS_REMEDY);
        e.add("streams", "stream rows", (rows, row as f64), STREAMS_REMEDY);
        e.add(
            "streams",
            "velocity updates",
            (velocity, update as f64),
            STREAMS_REMEDY,
        );
        if discrete {
            e.add(
                "strategy",
                "per-step Q of Mehra's updates",
                (velocity, q as f64),
                "a strategy that does not keep its Q at every velocity update (constant, \
                 adaptive), or fewer velocity rows",
            );
        }
        e.add(
            "covariance_time",
            "covariances",
            (covariances, covariance as f64),
            "ask for fewer covariance_time",
        );
        e
    };
    let mut output = group((epoch, row, update, q + BOX_OVERHEAD, covariance));
    output.fixed = PASS_BYTES;
    let thinned_index = usize::from(thinned) * size_of::<i64>();
    let arrays = group((
        STATE_ARRAYS * 2 * usize::from(smooth) + thinned_index,
        ROW_ARRAYS,
        VELOCITY_ARRAYS,
        q,
        q,
    ));
    let working = if smooth {
        working(data, cfg, (thinned, discrete), (rows, span))
    } else {
        Estimate::default()
    };
    PassMemory {
        output,
        working,
        arrays,
    }
}

/// The smoother's working memory over `data`: its nodes (at most one per row of the
/// streams and the q schedule `rows`, and the two ends) and the closes of the longest
/// stretch between two, each with what the backward pass carries through it.
fn working(
    data: &RecordedData<'_>,
    cfg: &FilterConfig,
    (thinned, discrete): (bool, bool),
    (rows, span): (f64, f64),
) -> Estimate {
    let n = data.imu.len();
    let calibrated = cfg.dvl_calibration.is_some();
    let every_sample = cfg.covariance_every_sample();
    let nodes = (rows + data.q_time.len() as f64 + 2.0).min(n as f64 + 2.0);
    let kind = NodeKind {
        discrete,
        calibrated,
        prior: false,
    };
    // The nodes' vector grows as they come; what they box does not.
    let inline = size_of::<Node>() as f64;
    let mut node = (node_bytes(kind) as f64 - inline) + inline * grown(nodes) / nodes;
    node += if thinned {
        node_state_bytes() as f64 * grown(nodes) / nodes
    } else {
        node_covariance_bytes() as f64
    };
    let stretch = longest_stretch(data) as f64;
    let closes = if every_sample {
        stretch
    } else {
        let per_step = (cfg.covariance_step / (span / n as f64)).floor().max(1.0);
        (stretch / per_step).ceil() + 2.0
    };
    let mut e = Estimate::default();
    e.add(
        SMOOTH,
        "smoother nodes",
        (nodes, node),
        "smooth shorter passes (split the recording into sections), or smooth=False",
    );
    e.add(
        SMOOTH,
        "closes of the longest stretch without a reading",
        (
            grown(closes),
            close_bytes(calibrated, every_sample, thinned) as f64,
        ),
        "the smoother holds the longest stretch without an update at once: split the pass \
         at that gap, or smooth=False",
    );
    e
}

/// The most IMU samples between two nodes of the smoother. A node comes at every epoch
/// with a row of any stream or of the q schedule, so the longest stretch is at most the
/// shortest of each source's longest stretch without a row (from `t0` to its first row
/// in the run, between two rows, from its last to the end); without a source, the pass.
fn longest_stretch(data: &RecordedData<'_>) -> usize {
    let n = data.imu.len();
    let (start, end) = (data.t0, data.imu_time[n - 1]);
    let mut shortest = (start, end);
    let sources = data.streams.iter().map(|s| s.time).chain([data.q_time]);
    for times in sources.filter(|t| !t.is_empty()) {
        let mut widest = (start, start);
        let mut previous = start;
        let inside = times.iter().copied().filter(|&t| t > start && t < end);
        for t in inside.chain([end]) {
            if t - previous > widest.1 - widest.0 {
                widest = (previous, t);
            }
            previous = t;
        }
        if widest.1 - widest.0 < shortest.1 - shortest.0 {
            shortest = widest;
        }
    }
    let at = |t: f64| data.imu_time.partition_point(|&s| s <= t);
    at(shortest.1) - at(shortest.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recorded::Stream;

    #[test]
    fn the_longest_stretch_is_the_shortest_of_each_streams_longest_gap() {
        let imu = vec![[0.0; 6]; 1000];
        let imu_time: Vec<f64> = (1..=1000).map(|k| k as f64 * 0.01).collect();
        let rows = [[0.0; 3]; 4];
        let cfg = FilterConfig::default();
        // DVL rows at 1, 2, 3 and 9 s: a 6 s gap; depth at 5 s alone: 5 s gaps.
        let dvl_time = [1.0, 2.0, 3.0, 9.0];
        let depth_time = [5.0];
        let depth = [0.0];
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            t0: 0.0,
            streams: vec![
                Stream::dvl(&rows, &dvl_time, &cfg),
                Stream::depth(&depth, &depth_time, 0.1),
            ],
            ..RecordedData::default()
        };
        // From 0 to 5 s (or 5 s to the end): 500 samples.
        assert_eq!(longest_stretch(&data), 500);
        let alone = RecordedData {
            streams: Vec::new(),
            ..data.clone()
        };
        assert_eq!(longest_stretch(&alone), 1000);
    }

    #[test]
    fn every_epoch_smoothed_costs_more_than_thinned_and_names_output_step() {
        let imu = vec![[0.0; 6]; 360_000];
        let imu_time: Vec<f64> = (1..=360_000).map(|k| k as f64 * 0.01).collect();
        let dvl_time: Vec<f64> = (1..=18_000).map(|k| k as f64 * 0.2).collect();
        let dvl = vec![[0.0; 3]; dvl_time.len()];
        let cfg = FilterConfig::default();
        let data = RecordedData {
            imu: &imu,
            imu_time: &imu_time,
            t0: 0.0,
            streams: vec![Stream::dvl(&dvl, &dvl_time, &cfg)],
            ..RecordedData::default()
        };
        let every = estimate(&data, Epochs::All, &cfg, true, false).peak();
        let thinned = estimate(&data, Epochs::Step(1.0), &cfg, true, false).peak();
        let forward = estimate(&data, Epochs::All, &cfg, false, false).peak();
        assert!(
            every.bytes() > 2.0 * thinned.bytes(),
            "{every:?} {thinned:?}"
        );
        assert!(every.bytes() > forward.bytes());
        assert_eq!(every.largest().unwrap().0, "output_step");
        // ~600-900 bytes per IMU sample every epoch smoothed (docs/results/performance.md;
        // an update's record carries the seven DVL error states' correction).
        let per_sample = every.bytes() / 360_000.0;
        assert!((600.0..950.0).contains(&per_sample), "{per_sample}");
    }
}
