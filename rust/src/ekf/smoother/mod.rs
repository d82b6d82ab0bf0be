//! The Rauch–Tung–Striebel smoother over the closed-loop error-state filter.
//!
//! The forward pass ([`super::filter_recorded_until`] with smoothing on) keeps a
//! [`Node`] at every epoch where the covariance was updated or the process noise
//! changed: the covariance before and after the update, the error estimate fed back,
//! and the noise in force until the next node. Between nodes the filter only
//! predicts, so the backward pass rebuilds each interval's covariances and transitions
//! from the forward solution (kept at every epoch) and the node it starts from, and
//! never stores them for the whole pass: memory grows with the nodes (DVL epochs), not
//! with the IMU samples.
//!
//! After every update the forward filter resets its error estimate to zero, so every
//! error below is relative to the forward solution at its epoch. With `δs` the smoothed
//! error of the solution after an epoch's update (the prior's is `δs⁻ = δs + δx̂`, the
//! feedback being `x̂⁺ = x̂⁻ ⊖ δx̂`), an interval from node `a` to node `b` gives, at
//! each epoch `i` in it (`P_i` the forward covariance there, `Φ_{i→b}` the product of
//! the step transitions from `i` to `b`, `P⁻_b` the covariance before `b`'s update):
//!
//! ```text
//! A_i  = P_i Φ_{i→b}ᵀ (P⁻_b)⁻¹
//! δs_i = A_i δs⁻_b
//! Ps_i = P_i + A_i (Ps_b − P⁻_b) A_iᵀ
//! ```
//!
//! the fixed-interval RTS recursion `C_i = P⁺_i Φ_{i+1}ᵀ (P⁻_{i+1})⁻¹` chained over the
//! steps without an update, where `P⁺ = P⁻` and `δx̂ = 0` (`every`); under a covariance
//! step the grid is the steps' closes instead (`steps`). With the DVL calibration
//! states the recursion runs on all 19 (`N` below): their rows of F are zero and the
//! navigation rows do not read them, so every product with `Φ = I + F Δt` goes through
//! the sparse F of the first 15. `docs/filter.md` ("The RTS smoother") writes it out
//! with its sources.

use super::calibration::{correct_mounting, Cross, DvlMounting, N_CALIBRATED, SCALE};
use super::interval::Interval as CovarianceStep;
use super::{correct, Ekf, FilterConfig, Formulation, Matrix15, Vector15, ATT, VEL};
use crate::attitude::skew;
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::error::{Error, Result};
use crate::mechanization::NavState;
use crate::noise::ProcessNoise;
use nalgebra::{Matrix4, SMatrix, SVector, Vector3};

mod every;
mod kept;
mod sink;
pub(super) mod steps;
pub mod thinned;

#[cfg(test)]
pub(crate) use every::Interval;
pub use kept::{KeptClose, KeptCloses};
pub(crate) use sink::changed_sigma;
pub use sink::Sink;

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
    pub(in crate::ekf) interval: Option<Box<CovarianceStep>>,
    /// With the DVL calibration states: their blocks of the covariance after the
    /// updates and their estimate fed back (boxed, 320 bytes).
    pub calibration: Option<Box<NodeCalibration>>,
    /// The covariance before the epoch's updates (`p_post` where it had none), where
    /// the forward pass kept it ([`Ekf::keep_priors`]: a Monte Carlo at every sample
    /// without the calibration states); the backward pass then needs no covariance
    /// inside an interval where no σ is wanted (`every`).
    pub p_prior: Option<Box<Matrix15>>,
}

/// Keeping the covariance before each epoch's updates for the nodes.
impl Ekf {
    /// Keep, from now on, the covariance before the first update of each epoch, for
    /// [`Ekf::take_prior`] (1.8 kB per node: an epoch with updates, or where the noise
    /// changes).
    pub fn keep_priors(&mut self) {
        self.keep_prior = true;
    }

    /// The covariance kept before the updates since the last call (None: no update, or
    /// [`Ekf::keep_priors`] not asked for).
    pub fn take_prior(&mut self) -> Option<Box<Matrix15>> {
        self.prior.take()
    }

    /// Before an update: keep the covariance if asked and none is kept yet.
    pub(super) fn note_prior(&mut self) {
        if self.keep_prior && self.prior.is_none() {
            self.prior = Some(Box::new(self.p));
        }
    }

    /// The covariance as a node's prior, where priors are kept.
    fn prior_here(&self) -> Option<Box<Matrix15>> {
        self.keep_prior.then(|| Box::new(self.p))
    }
}

/// The calibration part of a [`Node`].
#[derive(Clone, Debug)]
pub struct NodeCalibration {
    pub cross: Cross,
    pub cov: Matrix4<f64>,
    /// The sum of `[δk̂, δμ̂]` fed back at the epoch.
    pub correction: [f64; 4],
}

impl Node {
    /// The covariance after the updates over the `N` states.
    fn p<const N: usize>(&self) -> SMatrix<f64, N, N> {
        let cal = self.calibration.as_deref().map(|c| (&c.cross, &c.cov));
        lift(&self.p_post, cal)
    }

    /// The error estimate fed back, over the `N` states.
    fn dx<const N: usize>(&self) -> SVector<f64, N> {
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
fn lift<const N: usize>(p: &Matrix15, cal: Option<(&Cross, &Matrix4<f64>)>) -> SMatrix<f64, N, N> {
    let mut full = SMatrix::<f64, N, N>::zeros();
    full.fixed_view_mut::<15, 15>(0, 0).copy_from(p);
    if let (true, Some((cross, cov))) = (N == N_CALIBRATED, cal) {
        full.fixed_view_mut::<15, 4>(0, SCALE).copy_from(cross);
        full.fixed_view_mut::<4, 15>(SCALE, 0)
            .copy_from(&cross.transpose());
        full.fixed_view_mut::<4, 4>(SCALE, SCALE).copy_from(cov);
    }
    full
}

/// The filter's covariance over the `N` states.
fn full_p<const N: usize>(ekf: &Ekf) -> SMatrix<f64, N, N> {
    lift(&ekf.p, ekf.calibration.as_ref().map(|c| (&c.cross, &c.cov)))
}

/// The filter's calibration blocks for a node.
fn node_calibration(ekf: &Ekf, correction: [f64; 4]) -> Option<Box<NodeCalibration>> {
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
fn restart(forward: &Forward<'_>, cfg: &FilterConfig, a: &Node) -> Result<Ekf> {
    restart_at(forward.nav[a.epoch], &forward.bias[a.epoch], cfg, a)
}

/// [`restart`] from the solution `nav` and the bias estimates `b` (`[b_a, b_g]`) after
/// `a`'s updates.
fn restart_at(nav: NavState, b: &[f64; 6], cfg: &FilterConfig, a: &Node) -> Result<Ekf> {
    let mut ekf = Ekf::new(
        cfg,
        nav,
        Vector3::new(b[0], b[1], b[2]),
        Vector3::new(b[3], b[4], b[5]),
    )?;
    ekf.p = a.p_post;
    if let (Some(c), Some(n)) = (ekf.calibration.as_mut(), a.calibration.as_deref()) {
        (c.cross, c.cov) = (n.cross, n.cov);
    }
    ekf.interval = a.interval.as_deref().cloned();
    Ok(ekf)
}

/// The nodes of a forward pass, kept as it runs.
#[derive(Clone, Debug, Default)]
pub struct Nodes(pub Vec<Node>);

impl Nodes {
    /// Before the step that starts at `epoch`: a node there if the noise for the step
    /// differs from the last node's (the last node takes it if it is at `epoch`).
    pub fn before_step(&mut self, epoch: usize, ekf: &Ekf, noise: ProcessNoise<'_>) {
        match self.0.last_mut() {
            Some(last) if last.noise.is(noise) => {}
            Some(last) if last.epoch == epoch => last.noise = Noise::of(noise),
            _ => self.0.push(Node {
                epoch,
                p_post: ekf.p,
                correction: Vector15::zeros(),
                noise: Noise::of(noise),
                interval: open_step(ekf),
                calibration: node_calibration(ekf, [0.0; 4]),
                p_prior: ekf.prior_here(),
            }),
        }
    }

    /// After the updates at `epoch`: `correction` the sum of the estimates fed back
    /// (the calibration states' in `calibration`, zero without them), `noise` the
    /// strategy's noise after them (Mehra and the adaptive strategy change it at
    /// updates); `prior` the covariance before them where kept ([`Ekf::take_prior`]).
    pub fn after_updates(
        &mut self,
        epoch: usize,
        ekf: &Ekf,
        (correction, calibration): (Vector15, [f64; 4]),
        noise: ProcessNoise<'_>,
        prior: Option<Box<Matrix15>>,
    ) {
        self.0.push(Node {
            epoch,
            p_post: ekf.p,
            correction,
            noise: Noise::of(noise),
            interval: open_step(ekf),
            calibration: node_calibration(ekf, calibration),
            p_prior: prior,
        });
    }

    /// At the end of the pass, after the last epoch `epoch`: the node the backward
    /// pass starts from, with the covariance step under way closed (on a copy of the
    /// filter: the forward pass is not changed).
    pub fn finish(&mut self, epoch: usize, ekf: &Ekf) {
        let closed = ekf.interval.is_some().then(|| {
            let mut copy = ekf.clone();
            copy.bring_up_to_date();
            copy
        });
        let ekf = closed.as_ref().unwrap_or(ekf);
        if let Some(last) = self.0.last_mut().filter(|n| n.epoch == epoch) {
            if closed.is_some() {
                let correction = last.calibration.as_ref().map_or([0.0; 4], |c| c.correction);
                (last.p_post, last.interval) = (ekf.p, None);
                last.calibration = node_calibration(ekf, correction);
            }
            return;
        }
        let noise = self.0.last().map(|n| n.noise.clone());
        self.0.push(Node {
            epoch,
            p_post: ekf.p,
            correction: Vector15::zeros(),
            noise: noise.unwrap_or(Noise::Discrete(Box::new(Matrix15::zeros()))),
            interval: None,
            calibration: node_calibration(ekf, [0.0; 4]),
            p_prior: ekf.prior_here(),
        });
    }
}

/// The covariance step under way in `ekf`, if any, copied for a node.
fn open_step(ekf: &Ekf) -> Option<Box<CovarianceStep>> {
    ekf.interval.clone().map(Box::new)
}

/// The smoothed solution at every epoch of the forward pass.
#[derive(Clone, Debug, Default)]
pub struct Smoothed {
    pub nav: Vec<NavState>,
    /// `[b_a, b_g]` per epoch.
    pub bias: Vec<[f64; 6]>,
    /// 1σ of the 15 error states in the classic coordinates, per epoch.
    pub sigma: Vec<[f64; 15]>,
    /// With the DVL calibration states: `[k̂, roll, pitch, yaw]` per epoch, as
    /// [`super::FilterOutput::calibration`], and the 1σ of `[δk, δμ]` (empty without).
    pub calibration: Vec<[f64; 4]>,
    pub calibration_sigma: Vec<[f64; 4]>,
    /// The smoothed covariance at each node's epoch (in the order of the nodes), in
    /// the filter's own error coordinates about the forward solution's velocity (the
    /// 15 navigation and bias states).
    pub node_covariance: Vec<(usize, Matrix15)>,
}

/// What the backward pass reads of the forward one: its solution at every epoch and the
/// sensor rows it ran on.
pub struct Forward<'a> {
    pub imu: &'a [[f64; 6]],
    pub imu_time: &'a [f64],
    pub t0: f64,
    pub nav: &'a [NavState],
    pub bias: &'a [[f64; 6]],
    /// With the DVL calibration states, their estimate `[k̂, roll, pitch, yaw]` at every
    /// epoch (empty without).
    pub calibration: &'a [[f64; 4]],
    /// The forward σ of the 15 states at every epoch, and of the calibration states'
    /// (empty without them), that [`Smoothed`] changes into the smoothed σ (NaN at an
    /// epoch without it: empty where σ is not wanted, or a [`Sink`] reads the forward
    /// σ elsewhere).
    pub sigma: &'a [[f64; 15]],
    pub calibration_sigma: &'a [[f64; 4]],
    /// The step every sample was propagated over, when the forward pass used one
    /// (a simulation's `truth.dt`), so that the rebuilt steps are its steps bit for bit;
    /// None: each sample's stamped step.
    pub dt: Option<f64>,
}

impl Forward<'_> {
    /// The time \[s\] of epoch `i` (`t0` for the first).
    fn time(&self, i: usize) -> f64 {
        if i == 0 {
            self.t0
        } else {
            self.imu_time[i - 1]
        }
    }

    /// The step \[s\] from epoch `i` to `i + 1` (the one IMU row `i` is propagated over).
    fn step(&self, i: usize) -> f64 {
        self.dt.unwrap_or_else(|| self.imu_time[i] - self.time(i))
    }
}

/// Which epochs' smoothed covariance (σ) a backward pass computes; the nodes' it
/// always does. The mean it computes at every epoch.
#[derive(Clone, Copy)]
pub enum Covariances<'a> {
    /// Every epoch (`run_filter`): `Λ_i = Φ_{i→b}ᵀ M Φ_{i→b}` is carried back step by
    /// step, `Ps_i = P_i + P_i Λ_i P_i`.
    Every,
    /// Only the epochs where this holds (a Monte Carlo's recorded ones), the others'
    /// σ left NaN: the interval's forward product `G_i = Φ_{a→i}` is carried instead,
    /// and `Φ_{i→b} = G_b G_i⁻¹` formed at those epochs alone.
    Where(&'a dyn Fn(usize) -> bool),
}

/// The backward pass over `nodes` (from [`Nodes`], first at epoch 0 and last at the
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
/// closes the forward pass kept ([`Ekf::keep_closes`]) where `kept` gives them instead
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

impl Smoothed {
    /// The forward solution, to be corrected, with room for σ.
    fn start(forward: &Forward<'_>, nodes: usize) -> Self {
        let n = forward.nav.len();
        let calibrated = !forward.calibration.is_empty();
        Self {
            nav: forward.nav.to_vec(),
            bias: forward.bias.to_vec(),
            sigma: vec![[f64::NAN; 15]; n],
            calibration: forward.calibration.to_vec(),
            calibration_sigma: vec![[f64::NAN; 4]; if calibrated { n } else { 0 }],
            node_covariance: Vec::with_capacity(nodes),
        }
    }
}

impl Sink for Smoothed {
    /// Remove the smoothed error `ds` from the forward solution at epoch `i` (the
    /// filter's feedback: [`correct`], and the calibration's).
    fn apply<const N: usize>(&mut self, i: usize, ds: &SVector<f64, N>, cfg: &FilterConfig) {
        let b = self.bias[i];
        let (mut ab, mut gb) = (
            Vector3::new(b[0], b[1], b[2]),
            Vector3::new(b[3], b[4], b[5]),
        );
        let nav: Vector15 = ds.fixed_rows::<15>(0).into_owned();
        correct(&mut self.nav[i], &mut ab, &mut gb, &nav, cfg.formulation);
        self.bias[i] = [ab[0], ab[1], ab[2], gb[0], gb[1], gb[2]];
        if N == N_CALIBRATED {
            let c = self.calibration[i];
            let mut mounting = DvlMounting::from_angles(c[0], [c[1], c[2], c[3]]);
            let dc = std::array::from_fn(|k| ds[SCALE + k]);
            correct_mounting(&mut mounting, &dc);
            let a = mounting.angles();
            self.calibration[i] = [mounting.scale, a[0], a[1], a[2]];
        }
    }

    /// σ at epoch `i`: the forward σ there (`forward.sigma`) changed by `change`.
    fn set_change<const N: usize>(
        &mut self,
        i: usize,
        change: &SVector<f64, N>,
        forward: &Forward<'_>,
    ) {
        let sigma = forward.sigma.get(i).copied().unwrap_or([f64::NAN; 15]);
        self.sigma[i] = std::array::from_fn(|j| changed_sigma(sigma[j], change[j]));
        if let (true, Some(out)) = (N == N_CALIBRATED, self.calibration_sigma.get_mut(i)) {
            let sigma = forward.calibration_sigma.get(i).copied();
            let sigma = sigma.unwrap_or([f64::NAN; 4]);
            *out = std::array::from_fn(|k| changed_sigma(sigma[k], change[SCALE + k]));
        }
    }

    /// Keep the smoothed covariance at a node's epoch (its 15-state block).
    fn keep_node<const N: usize>(&mut self, epoch: usize, ps: &SMatrix<f64, N, N>) {
        let p = ps.fixed_view::<15, 15>(0, 0).into_owned();
        self.node_covariance.push((epoch, p));
    }
}

/// `U P`, the rows of a covariance in the filter's coordinates mapped to the classic
/// ones at `nav`'s velocity (`U = I + [v̂×]` at (velocity, attitude) in the invariant
/// formulation, `I` in the classic one).
fn classic_rows<const N: usize>(
    cfg: &FilterConfig,
    nav: &NavState,
    p: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    let mut up = *p;
    if cfg.formulation == Formulation::Invariant {
        let att = up.fixed_rows::<3>(ATT).into_owned();
        let mut vel = up.fixed_rows_mut::<3>(VEL);
        vel += skew(&nav.vel) * att;
    }
    up
}
