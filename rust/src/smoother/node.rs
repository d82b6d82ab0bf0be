//! The nodes of a forward pass: the epochs where its covariance was updated or its
//! process noise changed, with what the backward pass needs to restart the prediction
//! between them (see [`super`]).

use super::forward::Forward;
use crate::ekf::calibration::{Cross, N_CALIBRATED, SCALE};
use crate::ekf::calibration::{DvlCov, DvlErrors, N_DVL};
use crate::ekf::second_order::SecondOrder;
use crate::ekf::{CovarianceStep, Ekf, FilterConfig, Matrix15, ProcessNoise, Vector15};
use crate::error::Result;
use crate::mechanization::NavState;
use nalgebra::{SMatrix, SVector};

/// The process noise of an interval, owned (see [`ProcessNoise`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Noise {
    Continuous {
        imu_variance: [f64; 6],
        bias_psd: [f64; 6],
    },
    Discrete(Box<Matrix15>),
}

impl Noise {
    pub fn of(noise: ProcessNoise<'_>) -> Self {
        match noise {
            ProcessNoise::Continuous {
                imu_variance,
                bias_psd,
            } => Self::Continuous {
                imu_variance: *imu_variance,
                bias_psd: *bias_psd,
            },
            ProcessNoise::Discrete(q) => Self::Discrete(Box::new(*q)),
        }
    }

    /// Whether `noise` is this noise, bit for bit.
    pub fn is(&self, noise: ProcessNoise<'_>) -> bool {
        match (self, noise) {
            (
                Self::Continuous {
                    imu_variance: q,
                    bias_psd: b,
                },
                ProcessNoise::Continuous {
                    imu_variance,
                    bias_psd,
                },
            ) => q == imu_variance && b == bias_psd,
            (Self::Discrete(q), ProcessNoise::Discrete(other)) => **q == *other,
            _ => false,
        }
    }

    pub fn as_process_noise(&self) -> ProcessNoise<'_> {
        match self {
            Self::Continuous {
                imu_variance,
                bias_psd,
            } => ProcessNoise::Continuous {
                imu_variance,
                bias_psd,
            },
            Self::Discrete(q) => ProcessNoise::Discrete(q),
        }
    }
}

/// What the backward pass needs of one epoch of the forward pass (covariances in the
/// filter's own error coordinates).
#[derive(Clone, Debug)]
pub struct Node {
    /// The epoch's index in the forward output.
    pub epoch: usize,
    /// The covariance after the epoch's updates (the one before them is rebuilt by the
    /// backward pass, bit for bit, unless the forward pass kept it: `p_prior`).
    pub p_post: Matrix15,
    /// The sum of the error estimates fed back at the epoch (zero where none).
    pub correction: Vector15,
    /// The process noise in force from this epoch to the next node.
    pub noise: Noise,
    /// With a covariance step ([`FilterConfig::covariance_step`]): the step under way
    /// after the epoch's updates, None where one closed there (`p_post` is then the
    /// covariance at the last close). About 200 bytes, boxed.
    pub(crate) step: Option<Box<CovarianceStep>>,
    /// With the DVL calibration states: their blocks of the covariance after the
    /// updates and their estimate fed back (boxed, 320 bytes).
    pub calibration: Option<Box<NodeCalibration>>,
    /// The covariance before the epoch's updates (`p_post` where it had none), where
    /// the forward pass kept it ([`Nodes::before_step`]: a Monte Carlo at every sample
    /// without the calibration states); the backward pass then needs no covariance
    /// inside an interval where no σ is wanted (`every`).
    pub p_prior: Option<Box<Matrix15>>,
    /// With the second-order heading term: its state after the updates (boxed).
    pub(crate) second_order: Option<Box<SecondOrder>>,
}

/// The calibration part of a [`Node`].
#[derive(Clone, Debug)]
pub struct NodeCalibration {
    pub cross: Cross,
    pub cov: DvlCov,
    /// The sum of `[δk̂, δμ̂, δb̂]` fed back at the epoch.
    pub correction: DvlErrors,
}

impl Node {
    /// The covariance after the updates over the `N` states.
    pub(super) fn p<const N: usize>(&self) -> SMatrix<f64, N, N> {
        let cal = self.calibration.as_deref().map(|c| (&c.cross, &c.cov));
        lift(&self.p_post, cal)
    }

    /// The error estimate fed back, over the `N` states.
    pub(super) fn dx<const N: usize>(&self) -> SVector<f64, N> {
        let mut dx = SVector::<f64, N>::zeros();
        dx.fixed_rows_mut::<15>(0).copy_from(&self.correction);
        if let (true, Some(c)) = (N == N_CALIBRATED, &self.calibration) {
            for (i, v) in c.correction.iter().enumerate() {
                dx[SCALE + i] = *v;
            }
        }
        dx
    }
}

/// The 15-state covariance `p` with the calibration blocks `cal` as an `N`-state one
/// (the blocks dropped when `N` is 15).
pub(super) fn lift<const N: usize>(
    p: &Matrix15,
    cal: Option<(&Cross, &DvlCov)>,
) -> SMatrix<f64, N, N> {
    let mut full = SMatrix::<f64, N, N>::zeros();
    full.fixed_view_mut::<15, 15>(0, 0).copy_from(p);
    if let (true, Some((cross, cov))) = (N == N_CALIBRATED, cal) {
        full.fixed_view_mut::<15, N_DVL>(0, SCALE).copy_from(cross);
        full.fixed_view_mut::<N_DVL, 15>(SCALE, 0)
            .copy_from(&cross.transpose());
        full.fixed_view_mut::<N_DVL, N_DVL>(SCALE, SCALE)
            .copy_from(cov);
    }
    full
}

/// The filter's covariance over the `N` states.
pub(super) fn full_p<const N: usize>(ekf: &Ekf) -> SMatrix<f64, N, N> {
    lift(&ekf.p, ekf.calibration.as_ref().map(|c| (&c.cross, &c.cov)))
}

/// The filter's calibration blocks for a node.
fn node_calibration(ekf: &Ekf, correction: DvlErrors) -> Option<Box<NodeCalibration>> {
    ekf.calibration.as_ref().map(|c| {
        Box::new(NodeCalibration {
            cross: c.cross,
            cov: c.cov,
            correction,
        })
    })
}

/// A filter started from node `a` on the forward solution: its covariance (the
/// calibration blocks too, and the covariance step under way) the node's.
pub(super) fn restart(forward: &Forward<'_>, cfg: &FilterConfig, a: &Node) -> Result<Ekf> {
    restart_at(forward.nav[a.epoch], &forward.bias[a.epoch], cfg, a)
}

/// [`restart`] from the solution `nav` and the bias estimates `b` (`[b_a, b_g]`) after
/// `a`'s updates.
pub(super) fn restart_at(nav: NavState, b: &[f64; 6], cfg: &FilterConfig, a: &Node) -> Result<Ekf> {
    let calibration = a.calibration.as_deref().map(|n| (&n.cross, &n.cov));
    let step = a.step.as_deref().cloned();
    let second_order = a.second_order.clone();
    Ekf::restart(cfg, nav, b, a.p_post, calibration, step, second_order)
}

/// The nodes of a forward pass, kept as it runs.
#[derive(Clone, Debug, Default)]
pub struct Nodes(pub Vec<Node>);

impl Nodes {
    /// Before the step that starts at `epoch`: a node there if the noise for the step
    /// differs from the last node's (the last node takes it if it is at `epoch`).
    /// `priors`: keep the covariance there as the node's prior ([`Node::p_prior`]).
    pub fn before_step(&mut self, epoch: usize, ekf: &Ekf, noise: ProcessNoise<'_>, priors: bool) {
        match self.0.last_mut() {
            Some(last) if last.noise.is(noise) => {}
            Some(last) if last.epoch == epoch => last.noise = Noise::of(noise),
            _ => self.0.push(Node {
                epoch,
                p_post: ekf.p,
                correction: Vector15::zeros(),
                noise: Noise::of(noise),
                step: open_step(ekf),
                calibration: node_calibration(ekf, [0.0; N_DVL]),
                p_prior: priors.then(|| Box::new(ekf.p)),
                second_order: node_second_order(ekf),
            }),
        }
    }

    /// After the updates at `epoch`: `correction` the sum of the estimates fed back
    /// (the calibration states' in `calibration`, zero without them), `noise` the
    /// strategy's noise after them (Mehra and the adaptive strategy change it at
    /// updates); `prior` the covariance before them where kept.
    pub fn after_updates(
        &mut self,
        epoch: usize,
        ekf: &Ekf,
        (correction, calibration): (Vector15, DvlErrors),
        noise: ProcessNoise<'_>,
        prior: Option<Box<Matrix15>>,
    ) {
        self.0.push(Node {
            epoch,
            p_post: ekf.p,
            correction,
            noise: Noise::of(noise),
            step: open_step(ekf),
            calibration: node_calibration(ekf, calibration),
            p_prior: prior,
            second_order: node_second_order(ekf),
        });
    }

    /// At the end of the pass, after the last epoch `epoch`: the node the backward
    /// pass starts from, with the covariance step under way closed (on a copy of the
    /// filter: the forward pass is not changed); `priors` as [`Nodes::before_step`].
    pub fn finish(&mut self, epoch: usize, ekf: &Ekf, priors: bool) {
        let closed = (!ekf.is_up_to_date()).then(|| {
            let mut copy = ekf.clone();
            copy.bring_up_to_date();
            copy
        });
        let ekf = closed.as_ref().unwrap_or(ekf);
        if let Some(last) = self.0.last_mut().filter(|n| n.epoch == epoch) {
            if closed.is_some() {
                let correction = last
                    .calibration
                    .as_ref()
                    .map_or([0.0; N_DVL], |c| c.correction);
                (last.p_post, last.step) = (ekf.p, None);
                last.calibration = node_calibration(ekf, correction);
                last.second_order = node_second_order(ekf);
            }
            return;
        }
        let noise = self.0.last().map(|n| n.noise.clone());
        self.0.push(Node {
            epoch,
            p_post: ekf.p,
            correction: Vector15::zeros(),
            noise: noise.unwrap_or(Noise::Discrete(Box::new(Matrix15::zeros()))),
            step: None,
            calibration: node_calibration(ekf, [0.0; N_DVL]),
            p_prior: priors.then(|| Box::new(ekf.p)),
            second_order: node_second_order(ekf),
        });
    }
}

/// The filter's second-order heading term, if it carries one, copied for a node.
fn node_second_order(ekf: &Ekf) -> Option<Box<SecondOrder>> {
    ekf.second_order.clone()
}

/// The covariance step under way in `ekf`, if any, copied for a node.
fn open_step(ekf: &Ekf) -> Option<Box<CovarianceStep>> {
    ekf.step_under_way().cloned().map(Box::new)
}
