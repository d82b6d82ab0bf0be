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
//! steps without an update, where `P⁺ = P⁻` and `δx̂ = 0`. `docs/filter.md` ("The RTS
//! smoother") writes it out with its sources.

use super::interval::Interval as CovarianceStep;
use super::{correct, Ekf, FilterConfig, Matrix15, Vector15};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::error::{Error, Result};
use crate::mechanization::{ImuSample, NavState};
use crate::noise::ProcessNoise;
use nalgebra::Vector3;

pub(super) mod steps;

/// What the smoother cannot smooth yet, refused naming `arg`: the DVL calibration
/// states.
pub fn check_config(cfg: &FilterConfig, arg: &str) -> Result<()> {
    if cfg.dvl_calibration.is_some() {
        return Err(Error::invalid(
            arg,
            "the smoother does not smooth the DVL calibration states yet: smooth without \
             dvl_calibration",
        ));
    }
    Ok(())
}

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
    /// backward pass, bit for bit, and not kept).
    pub p_post: Matrix15,
    /// The sum of the error estimates fed back at the epoch (zero where none).
    pub correction: Vector15,
    /// The process noise in force from this epoch to the next node.
    pub noise: Noise,
    /// With a covariance step ([`FilterConfig::covariance_step`]): the step under way
    /// after the epoch's updates, None where one closed there (`p_post` is then the
    /// covariance at the last close). About 200 bytes, boxed.
    pub(in crate::ekf) interval: Option<Box<CovarianceStep>>,
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
            }),
        }
    }

    /// After the updates at `epoch`: `correction` the sum of the estimates fed back,
    /// `noise` the strategy's noise after them (Mehra and the adaptive strategy change
    /// it at updates).
    pub fn after_updates(
        &mut self,
        epoch: usize,
        ekf: &Ekf,
        correction: Vector15,
        noise: ProcessNoise<'_>,
    ) {
        self.0.push(Node {
            epoch,
            p_post: ekf.p,
            correction,
            noise: Noise::of(noise),
            interval: open_step(ekf),
        });
    }

    /// At the end of the pass, after the last epoch `epoch`: the node the backward
    /// pass starts from, with the covariance step under way closed (on a copy of the
    /// filter: the forward pass is not changed).
    pub fn finish(&mut self, epoch: usize, ekf: &Ekf) {
        let closed = ekf.interval.is_some().then(|| {
            let mut copy = ekf.clone();
            copy.bring_up_to_date();
            copy.p
        });
        if let Some(last) = self.0.last_mut().filter(|n| n.epoch == epoch) {
            if let Some(p) = closed {
                (last.p_post, last.interval) = (p, None);
            }
            return;
        }
        let noise = self.0.last().map(|n| n.noise.clone());
        self.0.push(Node {
            epoch,
            p_post: closed.unwrap_or(ekf.p),
            correction: Vector15::zeros(),
            noise: noise.unwrap_or(Noise::Discrete(Box::new(Matrix15::zeros()))),
            interval: None,
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
    /// The smoothed covariance at each node's epoch (in the order of the nodes), in
    /// the filter's own error coordinates about the forward solution's velocity.
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
    /// The step every sample was propagated over, when the forward pass used one
    /// (a simulation's `truth.dt`), so that the rebuilt steps are its steps bit for bit;
    /// None: each sample's stamped step.
    pub dt: Option<f64>,
}

impl Forward<'_> {
    /// The time [s] of epoch `i` (`t0` for the first).
    fn time(&self, i: usize) -> f64 {
        if i == 0 {
            self.t0
        } else {
            self.imu_time[i - 1]
        }
    }

    /// The step [s] from epoch `i` to `i + 1` (the one IMU row `i` is propagated over).
    fn step(&self, i: usize) -> f64 {
        self.dt.unwrap_or_else(|| self.imu_time[i] - self.time(i))
    }
}

/// Which epochs' smoothed covariance (σ) a backward pass computes; the nodes' it
/// always does. The mean it computes at every epoch.
#[derive(Clone, Copy)]
pub enum Covariances<'a> {
    /// Every epoch (`run_filter`): the product `Φ_{i→b}ᵀ` is carried back step by step.
    Every,
    /// Only the epochs where this holds (a Monte Carlo's recorded ones), the others'
    /// σ left NaN: the interval's forward product `G_i = Φ_{a→i}` is carried instead,
    /// and `Φ_{i→b} = G_b G_i⁻¹` formed at those epochs alone.
    Where(&'a dyn Fn(usize) -> bool),
}

/// The backward pass over `nodes` (from [`Nodes`], first at epoch 0 and last at the
/// last epoch), computing the covariance where `covariances` says; stops with
/// [`Error::Cancelled`] soon after `cancel` is set.
pub fn smooth(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    covariances: Covariances<'_>,
    cancel: &Cancel,
) -> Result<Smoothed> {
    let n = forward.nav.len();
    if nodes.first().map(|n| n.epoch) != Some(0) || nodes.last().map(|n| n.epoch) != Some(n - 1) {
        return Err(Error::Numerical(
            "the smoother's nodes do not span the pass".into(),
        ));
    }
    if !cfg.covariance_every_sample() {
        return steps::smooth_steps(forward, cfg, nodes, covariances, cancel);
    }
    let mut out = Smoothed {
        nav: forward.nav.to_vec(),
        bias: forward.bias.to_vec(),
        sigma: vec![[f64::NAN; 15]; n],
        node_covariance: Vec::with_capacity(nodes.len()),
    };
    let last = &nodes[nodes.len() - 1];
    // After the last epoch nothing is left to learn: δs = 0, Ps = P.
    let mut ds = Vector15::zeros();
    let mut ps = last.p_post;
    out.sigma[last.epoch] = classic_sigma(cfg, &forward.nav[last.epoch], &ps);
    out.node_covariance.push((last.epoch, ps));
    let wanted = match covariances {
        Covariances::Every => None,
        Covariances::Where(f) => Some(f),
    };
    for pair in nodes.windows(2).rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        let interval = Interval::rebuild(forward, cfg, a, b.epoch, wanted, cancel)?;
        let chol = interval.p_end.cholesky().ok_or_else(|| {
            Error::Numerical(format!(
                "the smoother: the covariance before epoch {} is not positive definite",
                b.epoch
            ))
        })?;
        // μ_i = Φ_{i→b}ᵀ (P⁻_b)⁻¹ δs⁻_b and δs_i = P_i μ_i; M as in the module's text.
        let mut mu = chol.solve(&(ds + b.correction));
        let m = chol.solve(&(ps - interval.p_end));
        let m = chol.solve(&m.transpose()).transpose();
        let m = (m + m.transpose()) * 0.5;
        let mut back = Matrix15::identity(); // Φ_{i→b}ᵀ, carried with Covariances::Every
        for i in (a.epoch..b.epoch).rev() {
            let k = i - a.epoch;
            let phi = &interval.phi[k];
            mu = phi.transpose() * mu;
            let dsi = interval.p[k] * mu;
            let transposed_product = if wanted.is_none() {
                back = transposed_step(phi, &back);
                Some(back)
            } else {
                interval.product_to_end(k)?
            };
            if let Some(bk) = transposed_product {
                let gain = interval.p[k] * bk;
                let psi = interval.p[k] + gain * m * gain.transpose();
                let psi = (psi + psi.transpose()) * 0.5;
                out.sigma[i] = classic_sigma(cfg, &forward.nav[i], &psi);
                if i == a.epoch {
                    ps = psi;
                    out.node_covariance.push((i, psi));
                }
            }
            apply(&mut out, i, &dsi, cfg);
            if i == a.epoch {
                ds = dsi;
            }
        }
    }
    out.node_covariance.reverse();
    Ok(out)
}

/// `Φᵀ B` for a step transition Φ whose bias rows are the identity's (F has none):
/// the navigation rows' product and the bias rows of B, 2,025 multiply-adds, not 3,375.
fn transposed_step(phi: &Matrix15, b: &Matrix15) -> Matrix15 {
    let nav_rows = phi.fixed_rows::<9>(0);
    let mut out = nav_rows.transpose() * b.fixed_rows::<9>(0);
    for r in 9..15 {
        let row = b.row(r).into_owned();
        let mut target = out.row_mut(r);
        target += row;
    }
    out
}

/// `Φ G` for such a Φ: the navigation rows change, the bias rows stay.
fn step_product(phi: &Matrix15, g: &mut Matrix15) {
    let nav = phi.fixed_rows::<9>(0) * *g;
    g.fixed_rows_mut::<9>(0).copy_from(&nav);
}

/// The forward covariances `P_i` (epochs `a..b`, `P_a` the node's after its update)
/// and the transitions `Φ` of the steps `i → i+1`, rebuilt from the forward solution;
/// with a covariance predicate, the product `G_i = Φ_{a→i}` at the epochs it holds
/// for, and `G_b`.
pub(super) struct Interval {
    pub(super) p: Vec<Matrix15>,
    pub(super) phi: Vec<Matrix15>,
    /// The covariance after the last step (before the end node's update).
    pub(super) p_end: Matrix15,
    /// `(i − a, G_i)` at the wanted epochs inside the interval.
    g: Vec<(usize, Matrix15)>,
    g_end: Matrix15,
}

impl Interval {
    /// The interval from node `a` to the epoch `end`, rebuilt by the filter's own
    /// prediction from the forward solution at `a`: the same steps on the same numbers,
    /// so its last covariance is the forward pass's before `end`'s update, bit for bit.
    pub(super) fn rebuild(
        forward: &Forward<'_>,
        cfg: &FilterConfig,
        a: &Node,
        end: usize,
        wanted: Option<&dyn Fn(usize) -> bool>,
        cancel: &Cancel,
    ) -> Result<Self> {
        let b = &forward.bias[a.epoch];
        let mut ekf = Ekf::new(
            cfg,
            forward.nav[a.epoch],
            Vector3::new(b[0], b[1], b[2]),
            Vector3::new(b[3], b[4], b[5]),
        )?;
        ekf.p = a.p_post;
        let steps = end - a.epoch;
        let (mut p, mut phi) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
        let mut g_at = Vec::new();
        let mut g = Matrix15::identity();
        for epoch in a.epoch..end {
            if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
                cancel.check()?;
            }
            // The step from epoch i to i + 1 reads IMU row i.
            let raw = ImuSample::from_array(&forward.imu[epoch]);
            let dt = forward.step(epoch);
            p.push(ekf.p);
            let step = ekf.transition(&raw, dt);
            if let Some(wanted) = wanted {
                if epoch > a.epoch && wanted(epoch) {
                    g_at.push((epoch - a.epoch, g));
                }
                step_product(&step, &mut g);
            }
            phi.push(step);
            ekf.propagate(&raw, dt, a.noise.as_process_noise())?;
        }
        Ok(Self {
            p,
            phi,
            p_end: ekf.p,
            g: g_at,
            g_end: g,
        })
    }

    /// `Φ_{i→b}ᵀ` for the epoch `a + k` where it was wanted: `G_bᵀ` at the start,
    /// `(G_b G_i⁻¹)ᵀ` inside; None where it was not.
    fn product_to_end(&self, k: usize) -> Result<Option<Matrix15>> {
        if k == 0 {
            return Ok(Some(self.g_end.transpose()));
        }
        let Ok(at) = self.g.binary_search_by_key(&k, |(i, _)| *i) else {
            return Ok(None);
        };
        let g = self.g[at].1;
        let inverse = g.try_inverse().ok_or_else(|| {
            Error::Numerical("the smoother: a transition product is singular".into())
        })?;
        Ok(Some((self.g_end * inverse).transpose()))
    }
}

/// Remove the smoothed error `ds` from the forward solution at epoch `i`.
fn apply(out: &mut Smoothed, i: usize, ds: &Vector15, cfg: &FilterConfig) {
    let b = out.bias[i];
    let (mut ab, mut gb) = (
        Vector3::new(b[0], b[1], b[2]),
        Vector3::new(b[3], b[4], b[5]),
    );
    correct(&mut out.nav[i], &mut ab, &mut gb, ds, cfg.formulation);
    out.bias[i] = [ab[0], ab[1], ab[2], gb[0], gb[1], gb[2]];
}

fn classic_sigma(cfg: &FilterConfig, nav: &NavState, p: &Matrix15) -> [f64; 15] {
    let mut c = *p;
    super::formulation::to_classic(cfg.formulation, &mut c, &nav.vel);
    std::array::from_fn(|i| c[(i, i)].max(0.0).sqrt())
}
