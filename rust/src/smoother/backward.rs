//! The backward pass over a forward pass that kept every epoch: [`smooth`] and
//! [`smooth_into`] (any [`Sink`]), by the recursion of the covariance in force
//! (`super::every` at every IMU sample, `super::steps` over a covariance step).

use super::every;
use super::forward::{Covariances, Forward};
use super::kept::KeptCloses;
use super::node::Node;
use super::sink::Sink;
use super::smoothed::Smoothed;
use super::steps;
use crate::cancel::Cancel;
use crate::ekf::calibration::N_CALIBRATED;
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};

/// The backward pass over `nodes` (from [`super::Nodes`], first at epoch 0 and last at the
/// last epoch), computing the covariance where `covariances` says; stops with
/// [`Error::Cancelled`] soon after `cancel` is set. With the DVL calibration states
/// `forward.calibration` holds their estimate at every epoch.
pub fn smooth(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    covariances: Covariances<'_>,
    cancel: &Cancel,
) -> Result<Smoothed> {
    if forward.bias.len() != forward.nav.len() {
        return Err(Error::Numerical(
            "the smoother needs the bias estimates at every epoch".into(),
        ));
    }
    let mut out = Smoothed::start(forward, nodes.len());
    smooth_into(forward, cfg, nodes, None, covariances, &mut out, cancel)?;
    out.node_covariance.reverse();
    Ok(out)
}

/// The backward pass of [`smooth`] into `out`, reading under a covariance step the
/// closes the forward pass kept ([`KeptCloses`]) where `kept` gives them instead
/// of rebuilding them: the same numbers, bit for bit, without the rebuild's prediction
/// (not read at every sample).
pub fn smooth_into<S: Sink>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    kept: Option<&KeptCloses>,
    covariances: Covariances<'_>,
    out: &mut S,
    cancel: &Cancel,
) -> Result<()> {
    let n = forward.nav.len();
    if nodes.first().map(|n| n.epoch) != Some(0) || nodes.last().map(|n| n.epoch) != Some(n - 1) {
        return Err(Error::Numerical(
            "the smoother's nodes do not span the pass".into(),
        ));
    }
    if (kept.is_none() || cfg.covariance_every_sample()) && forward.bias.len() != n {
        return Err(Error::Numerical(
            "the smoother needs the bias estimates at every epoch to rebuild the \
             covariances"
                .into(),
        ));
    }
    let calibrated = cfg.dvl_calibration.is_some();
    if calibrated != (forward.calibration.len() == n) {
        return Err(Error::Numerical(
            "the smoother needs the calibration estimate at every epoch, and only with \
             the calibration states"
                .into(),
        ));
    }
    const CAL: usize = N_CALIBRATED;
    let (f, c) = (forward, covariances);
    match (calibrated, cfg.covariance_every_sample()) {
        (false, true) => every::smooth_every::<15, S>(f, cfg, nodes, c, out, cancel),
        (true, true) => every::smooth_every::<CAL, S>(f, cfg, nodes, c, out, cancel),
        (false, false) => steps::smooth_steps::<15, S>(f, cfg, nodes, kept, c, out, cancel),
        (true, false) => steps::smooth_steps::<CAL, S>(f, cfg, nodes, kept, c, out, cancel),
    }
}
