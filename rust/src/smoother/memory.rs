//! What the smoother holds, per value, for the estimate a call checks before it
//! allocates ([`crate::memory`]): a node of the forward pass, a close of the interval
//! the backward pass smooths, a smoothed epoch. Each is the size of the value kept and
//! of what it boxes.

use super::closes::Close;
use super::node::{Node, NodeCalibration};
use super::transition::{NavRows, Sample};
use super::KeptClose;
use crate::ekf::calibration::{Cross, N_CALIBRATED};
use crate::ekf::calibration::{DvlCov, DvlErrors};
use crate::ekf::Matrix15;
use crate::mechanization::NavState;
use nalgebra::SVector;
use std::mem::size_of;

/// What the allocator adds to a boxed value \[bytes\] (glibc's header and alignment).
pub const BOX_OVERHEAD: usize = 16;

/// The bytes of a boxed `T`.
const fn boxed<T>() -> usize {
    size_of::<T>() + BOX_OVERHEAD
}

/// What the nodes of a pass box besides their covariance (a covariance step closes at
/// every epoch with a reading, so no node after updates boxes one under way).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeKind {
    /// The strategy sets the per-step Q itself (Mehra): each node boxes it.
    pub discrete: bool,
    /// With the DVL calibration states: their blocks.
    pub calibrated: bool,
    /// The covariance before the node's updates (a Monte Carlo at every sample).
    pub prior: bool,
}

/// The bytes of one node of the forward pass ([`Node`] and what it boxes).
pub fn node_bytes(kind: NodeKind) -> usize {
    size_of::<Node>()
        + usize::from(kind.discrete) * boxed::<Matrix15>()
        + usize::from(kind.calibrated) * boxed::<NodeCalibration>()
        + usize::from(kind.prior) * boxed::<Matrix15>()
}

/// The bytes the backward pass holds per close of the interval it smooths: the close
/// (one IMU sample's at every sample, a covariance step's under one) and the mean
/// carried back through it; a thinned pass at every sample also re-integrates the
/// interval's solution.
pub fn close_bytes(calibrated: bool, every_sample: bool, thinned: bool) -> usize {
    let close = match (every_sample, calibrated) {
        (true, false) => size_of::<Close<15, Sample>>(),
        (true, true) => size_of::<Close<N_CALIBRATED, Sample>>(),
        (false, false) => size_of::<Close<15, NavRows>>(),
        (false, true) => size_of::<Close<N_CALIBRATED, NavRows>>(),
    };
    let mean = if calibrated {
        size_of::<SVector<f64, N_CALIBRATED>>()
    } else {
        size_of::<SVector<f64, 15>>()
    };
    close + mean + usize::from(thinned && every_sample) * size_of::<NavState>()
}

/// The bytes of one epoch of a smoothed solution ([`super::Smoothed`]): the solution,
/// the bias estimates, σ, and the calibration states' where the filter has them.
pub fn smoothed_epoch_bytes(calibrated: bool) -> usize {
    size_of::<NavState>()
        + size_of::<[f64; 21]>()
        + usize::from(calibrated) * size_of::<[DvlErrors; 2]>()
}

/// The bytes of the smoothed covariance kept at a node (`(epoch, P)`).
pub const fn node_covariance_bytes() -> usize {
    size_of::<(usize, Matrix15)>()
}

/// The bytes of the forward solution a thinned pass keeps at a node.
pub const fn node_state_bytes() -> usize {
    size_of::<NavState>() + size_of::<[f64; 6]>()
}

/// The bytes of a close of the covariance step the forward pass keeps
/// ([`KeptClose`], with its epoch; the calibration blocks boxed where the filter has
/// them).
pub fn kept_close_bytes(calibrated: bool) -> usize {
    size_of::<KeptClose>()
        + size_of::<usize>()
        + usize::from(calibrated) * boxed::<(Cross, DvlCov)>()
}
