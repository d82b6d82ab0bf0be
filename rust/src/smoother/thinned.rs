//! The backward pass over a forward pass that kept its solution at the nodes and at
//! some output epochs only (`Epochs::Step`): memory grows with the nodes and the kept
//! epochs, not with the IMU samples.
//!
//! Between two nodes `a` and `b` the forward filter only predicts: its solution there
//! is the strapdown mechanization of the IMU samples from the solution after `a`'s
//! feedback, with the bias (and DVL calibration) estimates of `a`. The backward pass
//! re-integrates it, the same operations on the same numbers, so the forward solution
//! of every epoch in `[a, b)` comes back bit for bit, and rebuilds the interval's
//! covariances from it as the every-epoch pass does: at every sample first the
//! solution (`Stretch`) and then the closes (`super::closes::samples`, the covariance
//! kept at the kept epochs and the nodes only); under a covariance step both in one
//! sweep, each sample added to the step as it is integrated (`rebuild_closes`, the
//! closes `super::closes::steps` would rebuild). The one backward pass
//! (`super::backward`) then writes the smoothed solution (and σ) at the kept epochs
//! alone: each equals the every-epoch pass's bit for bit. The smoothed covariances at
//! the nodes are not kept ([`Smoothed::node_covariance`] is empty).

use super::backward::{pass, Rows};
use super::closes::{self, integrate, Close};
use super::forward::Forward;
use super::node::{restart_at, Node, Nodes};
use super::smoothed::Smoothed;
use super::transition::{NavRows, Sample};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::calibration::DvlErrors;
use crate::ekf::calibration::N_CALIBRATED;
use crate::ekf::{Ekf, FilterConfig};
use crate::error::{Error, Result};
use crate::mechanization::{ImuSample, NavState};

/// The forward solution after each node's updates, in the order of the nodes: where
/// the node-only backward pass starts each interval's re-integration.
#[derive(Clone, Debug, Default)]
pub struct NodeStates {
    nav: Vec<NavState>,
    /// `[b_a, b_g]`.
    bias: Vec<[f64; 6]>,
}

impl NodeStates {
    /// Keep `ekf`'s solution for each node added since the last call (at most the one
    /// just added, at the epoch `ekf` stands at).
    pub fn sync(&mut self, nodes: &Nodes, ekf: &Ekf) {
        while self.nav.len() < nodes.0.len() {
            self.nav.push(ekf.nav);
            let (a, g) = (ekf.accel_bias, ekf.gyro_bias);
            self.bias.push([a[0], a[1], a[2], g[0], g[1], g[2]]);
        }
    }
}

/// What the node-only backward pass reads of the forward one.
pub struct Thinned<'a> {
    pub imu: &'a [[f64; 6]],
    pub imu_time: &'a [f64],
    pub t0: f64,
    pub states: &'a NodeStates,
    /// The kept epochs (indices among all, increasing, the first 0 and the last the
    /// pass's last) and the forward solution at each.
    pub epochs: &'a [usize],
    pub nav: &'a [NavState],
    pub bias: &'a [[f64; 6]],
    /// With the DVL calibration states, their estimate at each kept epoch (empty
    /// without).
    pub calibration: &'a [DvlErrors],
    /// The forward σ at each kept epoch, and the calibration states' (empty without),
    /// as [`Forward::sigma`].
    pub sigma: &'a [[f64; 15]],
    pub calibration_sigma: &'a [DvlErrors],
}

impl Thinned<'_> {
    /// The time \[s\] of epoch `i` (`t0` for the first).
    fn time(&self, i: usize) -> f64 {
        if i == 0 {
            self.t0
        } else {
            self.imu_time[i - 1]
        }
    }

    /// The row of epoch `i` among the kept ones, if it is kept.
    fn kept(&self, i: usize) -> Option<usize> {
        self.epochs.binary_search(&i).ok()
    }

    /// The kept solution as a [`Forward`] indexed by kept row (no IMU rows).
    fn at_kept(&self) -> Forward<'_> {
        Forward {
            imu: &[],
            imu_time: &[],
            t0: self.t0,
            nav: self.nav,
            bias: self.bias,
            calibration: self.calibration,
            sigma: self.sigma,
            calibration_sigma: self.calibration_sigma,
            dt: None,
        }
    }
}

/// One interval's forward solution, re-integrated; its buffer is reused.
#[derive(Default)]
pub(crate) struct Stretch {
    pub(crate) nav: Vec<NavState>,
}

impl Stretch {
    /// The forward pass from node `a` (the `j`-th) to the epoch `end`, as a
    /// [`Forward`] whose epoch 0 is `a`'s, and `a` moved there: the solution of every
    /// epoch in `[a, end)` integrated again from `a`'s, as the filter's prediction
    /// integrates it. Stops with [`Error::Cancelled`] within [`STEPS_PER_CHECK`] steps
    /// of `cancel` being set (a stretch without updates can be hours of IMU).
    pub(crate) fn rebuild<'s>(
        &'s mut self,
        src: &'s Thinned<'_>,
        j: usize,
        a: &Node,
        end: usize,
        cancel: &Cancel,
    ) -> Result<(Forward<'s>, Node)> {
        let bias = &src.states.bias[j];
        self.nav.clear();
        let mut nav = src.states.nav[j];
        for i in a.epoch..end {
            if (i - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
                cancel.check()?;
            }
            self.nav.push(nav);
            if i + 1 < end {
                let dt = src.imu_time[i] - src.time(i);
                nav = integrate(&nav, &src.imu[i], bias, dt);
            }
        }
        let forward = Forward {
            imu: &src.imu[a.epoch..end],
            imu_time: &src.imu_time[a.epoch..end],
            t0: src.time(a.epoch),
            nav: &self.nav,
            bias: &src.states.bias[j..=j],
            calibration: &[],
            sigma: &[],
            calibration_sigma: &[],
            dt: None,
        };
        let mut start = a.clone();
        start.epoch = 0;
        Ok((forward, start))
    }
}

/// The backward pass over `nodes` (from the forward pass that kept `src`): the smoothed
/// solution and σ at the kept epochs, each as [`super::smooth`] gives it with
/// [`super::Covariances::Every`]; stops with [`Error::Cancelled`] soon after `cancel`
/// is set.
pub fn smooth(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    cancel: &Cancel,
) -> Result<Smoothed> {
    let last = src.imu.len();
    let spans = nodes.first().map(|n| n.epoch) == Some(0)
        && nodes.last().map(|n| n.epoch) == Some(last)
        && src.states.nav.len() == nodes.len()
        && src.epochs.first() == Some(&0)
        && src.epochs.last() == Some(&last)
        && src.nav.len() == src.epochs.len();
    if !spans {
        return Err(Error::Numerical(
            "the smoother's nodes or kept epochs do not span the pass".into(),
        ));
    }
    let kept = src.at_kept();
    let mut out = Smoothed::rows(&kept);
    let mut rows = Rows {
        sink: &mut out,
        view: &kept,
        kept: Some(src.epochs),
        wanted: &|_| true,
        time: &|i| src.time(i),
        lazy: false,
    };
    const CAL: usize = N_CALIBRATED;
    match (cfg.dvl_calibration.is_some(), cfg.covariance_every_sample()) {
        (false, true) => every_sample::<15>(src, cfg, nodes, &mut rows, cancel)?,
        (true, true) => every_sample::<CAL>(src, cfg, nodes, &mut rows, cancel)?,
        (false, false) => steps::<15>(src, cfg, nodes, &mut rows, cancel)?,
        (true, false) => steps::<CAL>(src, cfg, nodes, &mut rows, cancel)?,
    }
    Ok(out)
}

/// The backward pass at every IMU sample, each interval's solution re-integrated
/// ([`Stretch`]) and its covariance rebuilt at the kept epochs and the nodes only.
fn every_sample<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    rows: &mut Rows<'_, Smoothed>,
    cancel: &Cancel,
) -> Result<()> {
    let mut stretch = Stretch::default();
    let keep = |e: usize| src.kept(e).is_some();
    let closes = |j: usize, a: &Node, b: &Node, c: &mut Vec<Close<N, Sample>>| {
        let (forward, _) = stretch.rebuild(src, j, a, b.epoch, cancel)?;
        let vel_b = cfg.coordinates().at(&src.states.nav[j + 1]);
        closes::samples(
            &forward,
            cfg,
            (a, b.epoch),
            (a.epoch, vel_b),
            &keep,
            c,
            cancel,
        )
    };
    let vel0 = cfg.coordinates().at(&src.states.nav[0]);
    pass::<N, Sample, Smoothed>(nodes, closes, (vel0, cfg, rows, cancel))
}

/// The backward pass under a covariance step, each interval's closes rebuilt in the
/// same sweep as its solution is re-integrated ([`rebuild_closes`]).
fn steps<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    rows: &mut Rows<'_, Smoothed>,
    cancel: &Cancel,
) -> Result<()> {
    let closes = |j: usize, a: &Node, b: &Node, c: &mut Vec<Close<N, NavRows>>| {
        rebuild_closes(src, cfg, j, (a, b), c, cancel)
    };
    let vel0 = cfg.coordinates().at(&src.states.nav[0]);
    pass::<N, NavRows, Smoothed>(nodes, closes, (vel0, cfg, rows, cancel))
}

/// The closes in `(a, b]` of the covariance step (`a` the `j`-th node), as
/// [`closes::steps`] makes them from the forward solution, with that solution
/// integrated again on the way as [`Stretch::rebuild`] integrates it: one sweep, the
/// same operations on the same numbers, so each close is the forward pass's bit for bit,
/// and no interval's worth of solutions is written and read back. Into `closes`, whose
/// buffer each interval reuses.
pub(crate) fn rebuild_closes<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    j: usize,
    (a, b): (&Node, &Node),
    closes: &mut Vec<Close<N, NavRows>>,
    cancel: &Cancel,
) -> Result<()> {
    closes.clear();
    let mut nav = src.states.nav[j];
    let bias = &src.states.bias[j];
    let mut ekf = restart_at(nav, bias, cfg, a)?;
    let noise = a.noise.as_process_noise();
    // The forward velocity at b after its updates (before them: `nav` after the last
    // sample, integrated as the forward pass integrated it).
    let at_b = cfg.coordinates().at(&src.states.nav[j + 1]);
    for i in a.epoch..b.epoch {
        if (i - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&src.imu[i]);
        let dt = src.imu_time[i] - src.time(i);
        let due = ekf.add_to_step(&nav, &raw, dt, noise);
        nav = integrate(&nav, &src.imu[i], bias, dt);
        if due {
            if let Some(phi) = ekf.bring_up_to_date() {
                let here = cfg.coordinates().at(&nav);
                let after = if i + 1 < b.epoch { here } else { at_b };
                closes.push(Close::of(&ekf, i + 1, &phi, (here, after)));
            }
        }
    }
    if b.step.is_none() {
        if let Some(phi) = ekf.bring_up_to_date() {
            closes.push(Close::of(
                &ekf,
                b.epoch,
                &phi,
                (cfg.coordinates().at(&nav), at_b),
            ));
        }
    }
    Ok(())
}
