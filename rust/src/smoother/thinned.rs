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
//! solution (`Stretch`) and then the covariances (`super::every`); under a
//! covariance step both in one sweep, each sample added to the step as it is
//! integrated (`rebuild_closes`, the closes `super::steps` would rebuild). It runs
//! the same recursion, writing the smoothed solution (and σ)
//! at the kept epochs alone: each equals the every-epoch pass's bit for bit. The
//! smoothed covariances at the nodes are not kept ([`Smoothed::node_covariance`] is
//! empty).

use super::every::{self, transposed_step};
use super::forward::Forward;
use super::node::{full_p, restart, restart_at, Node, Nodes};
use super::sink::change;
use super::sink::Sink;
use super::smoothed::Smoothed;
use super::steps::{self, symmetric, AtClose, Close, Later};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::calibration::N_CALIBRATED;
use crate::ekf::dynamics::ErrorDynamics;
use crate::ekf::{Ekf, FilterConfig};
use crate::error::{Error, Result};
use crate::mechanization::{step_with_rates, FrameRates, ImuSample, NavState};
use nalgebra::{SMatrix, SVector, Vector3};
use std::ops::Range;

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
    pub calibration: &'a [[f64; 4]],
    /// The forward σ at each kept epoch, and the calibration states' (empty without),
    /// as [`Forward::sigma`].
    pub sigma: &'a [[f64; 15]],
    pub calibration_sigma: &'a [[f64; 4]],
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

    /// The kept rows whose epochs lie in `epochs`.
    fn kept_in(&self, epochs: Range<usize>) -> Range<usize> {
        let from = self.epochs.partition_point(|&e| e < epochs.start);
        let to = self.epochs.partition_point(|&e| e < epochs.end);
        from..to
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
        let b = &src.states.bias[j];
        let accel_bias = Vector3::new(b[0], b[1], b[2]);
        let gyro_bias = Vector3::new(b[3], b[4], b[5]);
        self.nav.clear();
        let mut nav = src.states.nav[j];
        for i in a.epoch..end {
            if (i - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
                cancel.check()?;
            }
            self.nav.push(nav);
            if i + 1 < end {
                let raw = ImuSample::from_array(&src.imu[i]);
                let imu = ImuSample {
                    accel: raw.accel - accel_bias,
                    gyro: raw.gyro - gyro_bias,
                };
                let dt = src.imu_time[i] - src.time(i);
                nav = step_with_rates(&nav, &imu, dt, &FrameRates::at(&nav));
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
    const CAL: usize = N_CALIBRATED;
    match (cfg.dvl_calibration.is_some(), cfg.covariance_every_sample()) {
        (false, true) => smooth_every::<15>(src, cfg, nodes, cancel),
        (true, true) => smooth_every::<CAL>(src, cfg, nodes, cancel),
        (false, false) => smooth_steps::<15>(src, cfg, nodes, cancel),
        (true, false) => smooth_steps::<CAL>(src, cfg, nodes, cancel),
    }
}

/// [`super::every::smooth_every`] at the kept epochs.
fn smooth_every<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    cancel: &Cancel,
) -> Result<Smoothed> {
    let kept = src.at_kept();
    let mut out = Smoothed::start(&kept, 0);
    let last = &nodes[nodes.len() - 1];
    let mut ds = SVector::<f64, N>::zeros();
    let mut ps = last.p::<N>();
    out.set_sigma(src.epochs.len() - 1, (&ps, &ps), cfg, &kept);
    let mut stretch = Stretch::default();
    for (j, pair) in nodes.windows(2).enumerate().rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        let rows = src.kept_in(a.epoch..b.epoch);
        let (forward, start) = stretch.rebuild(src, j, a, b.epoch, cancel)?;
        let keep = |k: usize| k == 0 || src.kept(a.epoch + k).is_some();
        let interval = Rebuilt::<N>::every(&forward, cfg, &start, b.epoch - a.epoch, keep, cancel)?;
        let chol = interval.p_end.cholesky().ok_or_else(|| {
            Error::Numerical(format!(
                "the smoother: the covariance before epoch {} is not positive definite",
                b.epoch
            ))
        })?;
        let mut mu = chol.solve(&(ds + b.dx::<N>()));
        let m = chol.solve(&(ps - interval.p_end));
        let m = chol.solve(&m.transpose()).transpose();
        let mut lambda = (m + m.transpose()) * 0.5;
        // The kept rows and the covariances, taken from the end.
        let (mut row, mut at) = (rows.end, interval.p.len());
        for i in (a.epoch..b.epoch).rev() {
            let k = i - a.epoch;
            let (dynamics, dt) = &interval.steps[k];
            mu = transposed_step(dynamics, *dt, &mu);
            every::congruence(dynamics, *dt, &mut lambda);
            if at == 0 || interval.p[at - 1].0 != k {
                continue; // neither kept nor the node
            }
            at -= 1;
            let p = &interval.p[at].1;
            let dsi = p * mu;
            let kept_row = (row > rows.start && src.epochs[row - 1] == i).then(|| {
                row -= 1;
                row
            });
            if i == a.epoch {
                let psi = p + p * lambda * p;
                ps = (psi + psi.transpose()) * 0.5;
                ds = dsi;
                if let Some(r) = kept_row {
                    out.set_sigma(r, (&ps, p), cfg, &kept);
                }
            } else if let Some(r) = kept_row {
                out.set_sigma_of(r, p, &lambda, cfg, &kept);
            }
            if let Some(r) = kept_row {
                out.apply(r, &dsi, cfg);
            }
        }
    }
    Ok(out)
}

/// An interval rebuilt as [`super::every`]'s `Interval::rebuild` does, every sample, keeping the
/// forward covariance only at the epochs the backward pass reads it at.
struct Rebuilt<const N: usize> {
    /// `(k, P)` at the kept epochs `a + k` (increasing k).
    p: Vec<(usize, SMatrix<f64, N, N>)>,
    steps: Vec<(ErrorDynamics, f64)>,
    p_end: SMatrix<f64, N, N>,
}

impl<const N: usize> Rebuilt<N> {
    /// The interval from node `a` (at epoch 0 of `forward`) to the epoch `end`, with
    /// `P_k` where `keep(k)`.
    fn every(
        forward: &Forward<'_>,
        cfg: &FilterConfig,
        a: &Node,
        end: usize,
        keep: impl Fn(usize) -> bool,
        cancel: &Cancel,
    ) -> Result<Self> {
        let mut ekf = restart(forward, cfg, a)?;
        let (mut p, mut steps) = (Vec::new(), Vec::with_capacity(end));
        let noise = a.noise.as_process_noise();
        for k in 0..end {
            if k % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
                cancel.check()?;
            }
            let raw = ImuSample::from_array(&forward.imu[k]);
            let dt = forward.step(k);
            if keep(k) {
                p.push((k, full_p::<N>(&ekf)));
            }
            let (step, _) = ekf.predict_covariance_from(&forward.nav[k], &raw, dt, noise);
            let step = step.ok_or_else(|| {
                Error::Numerical("the smoother: a covariance step where none was".into())
            })?;
            steps.push((step, dt));
        }
        Ok(Self {
            p,
            steps,
            p_end: full_p::<N>(&ekf),
        })
    }
}

/// [`super::steps::smooth_steps`] at the kept epochs.
fn smooth_steps<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    cancel: &Cancel,
) -> Result<Smoothed> {
    let kept = src.at_kept();
    let mut out = Smoothed::start(&kept, 0);
    let mut mu = SVector::<f64, N>::zeros();
    let mut lambda = SMatrix::<f64, N, N>::zeros();
    let mut later: Option<Later<N>> = None;
    let mut closes = Vec::new();
    for (j, pair) in nodes.windows(2).enumerate().rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        rebuild_closes::<N>(src, cfg, j, (a, b), &mut closes, cancel)?;
        for (k, close) in closes.iter().enumerate().rev() {
            let epoch = close.epoch;
            let at_node = epoch == b.epoch;
            let p = if at_node { b.p::<N>() } else { close.p_prior };
            let ds = p * mu;
            // Ps where it is read: at the nodes and at kept epochs between the close
            // before and the next one (σ there is interpolated between the two).
            let until = later.as_ref().map_or(epoch + 1, |l| l.epoch);
            let since = steps::previous_close(&closes, k, a);
            let (before, after) = (
                since.is_none_or(|s| !src.kept_in(s + 1..epoch).is_empty()),
                !src.kept_in(epoch..until).is_empty(),
            );
            let at = AtClose::read(close, (&p, &lambda), (at_node, before, after), cfg);
            fill(
                &mut out,
                src,
                cfg,
                epoch,
                &ds,
                at.near.as_ref(),
                later.as_ref(),
            );
            later = Some(at.back_through(close, (b, at_node), &ds, (&mut mu, &mut lambda))?);
        }
    }
    let p = nodes[0].p::<N>();
    let (ds, ps) = (p * mu, symmetric(&(p + p * lambda * p)));
    let near = change(&ps, &p, cfg, &src.states.nav[0].vel);
    fill(&mut out, src, cfg, 0, &ds, Some(&near), later.as_ref());
    Ok(out)
}

/// The closes in `(a, b]` of the covariance step (`a` the `j`-th node), as
/// [`steps::rebuild`] makes them from the forward solution, with that solution
/// integrated again on the way as [`Stretch::rebuild`] integrates it: one sweep, the
/// same operations on the same numbers, so each close is the forward pass's bit for bit,
/// and no interval's worth of solutions is written and read back. Into `closes`, whose
/// buffer each interval reuses.
pub(crate) fn rebuild_closes<const N: usize>(
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    j: usize,
    (a, b): (&Node, &Node),
    closes: &mut Vec<Close<N>>,
    cancel: &Cancel,
) -> Result<()> {
    closes.clear();
    let mut nav = src.states.nav[j];
    let mut ekf = restart_at(nav, &src.states.bias[j], cfg, a)?;
    let (accel_bias, gyro_bias) = (ekf.accel_bias, ekf.gyro_bias);
    let noise = a.noise.as_process_noise();
    // The forward velocity at b after its updates (before them: `nav` after the last
    // sample, integrated as the forward pass integrated it).
    let at_b = src.states.nav[j + 1].vel;
    for i in a.epoch..b.epoch {
        if (i - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&src.imu[i]);
        let dt = src.imu_time[i] - src.time(i);
        let due = ekf.add_to_step(&nav, &raw, dt, noise);
        let imu = ImuSample {
            accel: raw.accel - accel_bias,
            gyro: raw.gyro - gyro_bias,
        };
        nav = step_with_rates(&nav, &imu, dt, &FrameRates::at(&nav));
        if due {
            if let Some(phi) = ekf.bring_up_to_date() {
                let vel = if i + 1 < b.epoch { nav.vel } else { at_b };
                closes.push(Close::of(&ekf, i + 1, &phi, (nav.vel, vel)));
            }
        }
    }
    if b.step.is_none() {
        if let Some(phi) = ekf.bring_up_to_date() {
            closes.push(Close::of(&ekf, b.epoch, &phi, (nav.vel, at_b)));
        }
    }
    Ok(())
}

/// [`super::steps`]'s `fill` at the kept epochs: the smoothed error `ds` at the close
/// `epoch`, interpolated up to the next close `later`, and σ from the change `near` to
/// the variances after the close's updates where given (interpolated towards the next
/// close's).
fn fill<const N: usize>(
    out: &mut Smoothed,
    src: &Thinned<'_>,
    cfg: &FilterConfig,
    epoch: usize,
    ds: &SVector<f64, N>,
    near: Option<&SVector<f64, N>>,
    later: Option<&Later<N>>,
) {
    let until = later.map_or(epoch + 1, |l| l.epoch);
    let t_close = src.time(epoch);
    let kept = src.at_kept();
    for row in src.kept_in(epoch..until) {
        let i = src.epochs[row];
        match later {
            Some(l) if i > epoch => {
                let w = (src.time(i) - t_close) / (src.time(l.epoch) - t_close);
                l.write_between(out, (row, &kept), w, (ds, near), cfg);
            }
            _ => {
                if let Some(near) = near {
                    out.set_change(row, near, &kept);
                }
                out.apply(row, ds, cfg);
            }
        }
    }
}
