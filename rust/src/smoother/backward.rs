//! The backward pass: one RTS recursion from the last node to the first, close by close,
//! whatever the closes are ([`super::closes`]: every IMU sample's, or a covariance
//! step's, rebuilt, kept or re-integrated) and wherever it writes (every epoch of the
//! forward pass, or the kept ones of a thinned pass: [`Rows`]).
//!
//! With `c` a close and `d` the next one (`δx̂_d` the error estimate fed back at `d`,
//! zero where no update was):
//!
//! ```text
//! A_c  = P⁺_c Φ_dᵀ (P⁻_d)⁻¹                 (Cholesky solves, no inverse)
//! δs_c = A_c (δs_d + δx̂_d)
//! Ps_c = P⁺_c + A_c (Ps_d − P⁻_d) A_cᵀ
//! ```
//!
//! chained between updates: where a close has no update `P⁺ = P⁻` and `δx̂ = 0`, so
//! `μ ← Φᵀ μ` and `Λ ← Φᵀ Λ Φ` carry `(P⁻_u)⁻¹ δs⁻_u` and
//! `(P⁻_u)⁻¹ (Ps_u − P⁻_u) (P⁻_u)⁻¹` of the next update `u` back, `δs_c = P_c μ` and
//! `Ps_c = P_c + P_c Λ P_c`; only at the nodes a Cholesky factor of `P⁻` is solved
//! with. Between two closes (inside a covariance step) the filter has no covariance:
//! the smoothed error there is interpolated linearly in time between `δs_c` (after
//! `c`'s updates) and `δs⁻_d = δs_d + δx̂_d` (before `d`'s), and the change to its
//! variances linearly in time between those at `c` and at `d`, as the forward σ is
//! interpolated. `docs/reference/smoother.md` ("The RTS smoother") writes it out with its sources.

use super::closes::{self, Close};
use super::forward::{Covariances, Forward};
use super::kept::KeptCloses;
use super::node::Node;
use super::sink::{change, change_of, Sink};
use super::smoothed::Smoothed;
use super::solve::at_update;
use super::transition::{symmetric, Decay, NavRows, Sample, Step};
use crate::cancel::Cancel;
use crate::ekf::calibration::N_CALIBRATED;
use crate::ekf::FilterConfig;
use crate::ekf::Point;
use crate::error::{Error, Result};
use nalgebra::{SMatrix, SVector};
use std::ops::Range;

/// The backward pass over `nodes` (from [`super::Nodes`], first at epoch 0 and last at
/// the last epoch), computing the covariance where `covariances` says; stops with
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
    let wanted = |i: usize| match covariances {
        Covariances::Every => true,
        Covariances::Where(f) => f(i),
    };
    let mut rows = Rows {
        sink: out,
        view: forward,
        kept: None,
        wanted: &wanted,
        time: &|i| forward.time(i),
        lazy: matches!(covariances, Covariances::Where(_)),
    };
    let vel0 = cfg.coordinates().at(&forward.nav[0]);
    let within = (forward, cfg, &wanted as &dyn Fn(usize) -> bool);
    match (calibrated, cfg.covariance_every_sample()) {
        (false, true) => every_sample::<15, S>(within, nodes, &mut rows, cancel),
        (true, true) => every_sample::<N_CALIBRATED, S>(within, nodes, &mut rows, cancel),
        (false, false) => pass::<15, NavRows, S>(
            nodes,
            |_, a, b, c| step_closes(forward, cfg, kept, (a, b), c, cancel),
            (vel0, cfg, &mut rows, cancel),
        ),
        (true, false) => pass::<N_CALIBRATED, NavRows, S>(
            nodes,
            |_, a, b, c| step_closes(forward, cfg, kept, (a, b), c, cancel),
            (vel0, cfg, &mut rows, cancel),
        ),
    }
}

/// [`pass`] at every IMU sample over the forward solution `forward` (σ wanted where
/// `wanted` holds): the covariance rebuilt at every sample, except between two nodes
/// where no σ is wanted and the later kept the covariance before its updates (a Monte
/// Carlo's run): there the mean alone, by the Bryson–Frazier form
/// ([`closes::samples_mean`]).
fn every_sample<const N: usize, S: Sink>(
    (forward, cfg, wanted): (&Forward<'_>, &FilterConfig, &dyn Fn(usize) -> bool),
    nodes: &[Node],
    rows: &mut Rows<'_, S>,
    cancel: &Cancel,
) -> Result<()> {
    let vel0 = cfg.coordinates().at(&forward.nav[0]);
    let every = |_: usize| true;
    let closes = |_, a: &Node, b: &Node, c: &mut Vec<Close<N, Sample>>| {
        let vel_b = cfg.coordinates().at(&forward.nav[b.epoch]);
        let inside = (a.epoch + 1..b.epoch).any(wanted);
        match (N, b.p_prior.as_deref(), inside) {
            (15, Some(prior), false) => {
                closes::samples_mean(forward, cfg, (a, b.epoch, prior), vel_b, c, cancel)
            }
            _ => closes::samples(forward, cfg, (a, b.epoch), (0, vel_b), &every, c, cancel),
        }
    };
    pass::<N, Sample, S>(nodes, closes, (vel0, cfg, rows, cancel))
}

/// The closes of a covariance step in `(a, b]`: as the forward pass kept them, or
/// rebuilt.
fn step_closes<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    kept: Option<&KeptCloses>,
    (a, b): (&Node, &Node),
    closes: &mut Vec<Close<N, NavRows>>,
    cancel: &Cancel,
) -> Result<()> {
    match kept {
        Some(kept) => {
            closes::kept(forward, cfg, kept, (a, b), closes);
            Ok(())
        }
        None => closes::steps(forward, cfg, (a, b), closes, cancel),
    }
}

/// Where the backward pass writes: the sink, the forward solution whose σ it changes
/// (`view`, indexed by the sink's rows), which epochs are its rows (`kept`: the kept
/// epochs of a thinned pass, increasing; None: every epoch), where σ is wanted, the
/// time \[s\] of every epoch, and how Λ may be carried.
pub(super) struct Rows<'a, S> {
    pub(super) sink: &'a mut S,
    pub(super) view: &'a Forward<'a>,
    pub(super) kept: Option<&'a [usize]>,
    pub(super) wanted: &'a dyn Fn(usize) -> bool,
    pub(super) time: &'a dyn Fn(usize) -> f64,
    /// Whether Λ may be carried lazily where σ is read at few epochs (see [`Lambda`]).
    pub(super) lazy: bool,
}

impl<S: Sink> Rows<'_, S> {
    /// The rows of the epochs in `epochs`.
    fn of(&self, epochs: Range<usize>) -> Range<usize> {
        match self.kept {
            None => epochs,
            Some(kept) => {
                let from = kept.partition_point(|&e| e < epochs.start);
                let to = kept.partition_point(|&e| e < epochs.end);
                from..to
            }
        }
    }

    /// The epoch of row `row`.
    fn epoch(&self, row: usize) -> usize {
        self.kept.map_or(row, |kept| kept[row])
    }

    /// Whether σ is wanted at a row among the epochs in `epochs`.
    fn wanted_in(&self, epochs: Range<usize>) -> bool {
        self.of(epochs).any(|row| (self.wanted)(self.epoch(row)))
    }

    /// Apply the smoothed error `ds` at the close `epoch` and interpolate it up to the
    /// next close `later`; σ, where wanted, from the change `near` to the variances
    /// after the close's updates (given where it was computed): at the close, and
    /// interpolated towards the next close's ([`Later::write_between`]) before it.
    fn fill<const N: usize>(
        &mut self,
        cfg: &FilterConfig,
        (epoch, ds, near): (usize, &SVector<f64, N>, Option<&SVector<f64, N>>),
        later: Option<&Later<N>>,
    ) {
        let end = later.map_or(epoch + 1, |l| l.epoch);
        let t_close = (self.time)(epoch);
        for row in self.of(epoch..end) {
            let i = self.epoch(row);
            let near = near.filter(|_| (self.wanted)(i));
            match later {
                Some(l) if i > epoch => {
                    let w = ((self.time)(i) - t_close) / ((self.time)(l.epoch) - t_close);
                    l.write_between(self.sink, (row, self.view), w, (ds, near), cfg);
                }
                _ => {
                    if let Some(near) = near {
                        self.sink.set_change(row, near, self.view);
                    }
                    self.sink.apply(row, ds, cfg);
                }
            }
        }
    }
}

/// The backward pass over `nodes`, from the last to the first, the closes of each
/// interval `(a, b]` given by `closes_between` (`j` is `a`'s index among the nodes),
/// into `rows`; `vel0` the forward velocity at the first epoch.
pub(super) fn pass<const N: usize, T: Step<N>, S: Sink>(
    nodes: &[Node],
    mut closes_between: impl FnMut(usize, &Node, &Node, &mut Vec<Close<N, T>>) -> Result<()>,
    (vel0, cfg, rows, cancel): (Point, &FilterConfig, &mut Rows<'_, S>, &Cancel),
) -> Result<()> {
    // After the last epoch nothing is left to learn: μ = 0, Λ = 0.
    let decay = Decay::of::<N>(cfg);
    let mut mu = SVector::<f64, N>::zeros();
    let mut lambda = Lambda::new(rows.lazy && T::EVERY_EPOCH);
    // The next close (the interpolation's far end).
    let mut later: Option<Later<N>> = None;
    let mut closes = Vec::new();
    // μ at an interval's closes without a covariance (last first).
    let mut mus = Vec::new();
    for (j, pair) in nodes.windows(2).enumerate().rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        closes_between(j, a, b, &mut closes)?;
        mus.clear();
        // Whether the mean at a close without a covariance is read.
        let mut read = false;
        for (k, close) in closes.iter().enumerate().rev() {
            let at_node = close.epoch == b.epoch;
            // Borrowed, not copied: most closes of a Monte Carlo's run carry none.
            let node_p;
            let p = if at_node {
                node_p = b.p::<N>();
                Some(&node_p)
            } else {
                close.p_prior.as_ref()
            };
            let Some(p) = p else {
                // No covariance (a thinned pass's sample between kept epochs, or one
                // whose mean alone is read): its transition alone, and no epoch before
                // the next close; the mean, where read, after the interval.
                read |= !rows.of(close.epoch..close.epoch + 1).is_empty();
                mus.push(mu);
                mu = close.phi.transposed(&mu);
                decay.mean(close.dt, &mut mu);
                lambda.through(&close.phi, close.dt, &decay);
                later = Some(Later {
                    epoch: close.epoch,
                    ds_prior: SVector::zeros(),
                    change: None,
                });
                continue;
            };
            let ds = p * mu;
            // Ps where it is read: at the nodes and where σ is wanted between the close
            // before and the next one (σ there is interpolated between the two).
            let end = later.as_ref().map_or(close.epoch + 1, |l| l.epoch);
            let since = previous_close(&closes, k, a);
            let (before, after) = (
                since.is_none_or(|s| rows.wanted_in(s + 1..close.epoch)),
                rows.wanted_in(close.epoch..end),
            );
            let at = match at_node || before || after {
                true => AtClose::read(close, (p, lambda.get()), (at_node, before, after)),
                false => AtClose::default(),
            };
            rows.fill(cfg, (close.epoch, &ds, at.near.as_ref()), later.as_ref());
            if let (true, Some(ps)) = (at_node, at.ps.as_ref()) {
                rows.sink.keep_node(b.epoch, ps);
            }
            let carried = (&mut mu, &mut lambda, &decay);
            later = Some(at.back_through(close, (b, at_node), &ds, carried)?);
        }
        if read {
            mean_forward(&closes, &mut mus, a.p::<N>() * mu, rows, (cfg, &decay))?;
        }
    }
    // The first epoch: the prior, a close of its own.
    let p = nodes[0].p::<N>();
    let lambda = lambda.get();
    let (ds, ps) = (p * mu, symmetric(&(p + p * lambda * p)));
    let near = change(&ps, &p, &vel0);
    rows.fill(cfg, (0, &ds, Some(&near)), later.as_ref());
    rows.sink.keep_node(0, &ps);
    Ok(())
}

/// `Λ`, carried back through the closes: through each close's Φ as it comes
/// (`Λ ← Φᵀ Λ Φ`), or, `lazy`, as the product `K` of the transitions since it was last
/// read (`K ← K Φ`, one sparse product per IMU sample instead of two), `Λ ← Kᵀ Λ K`
/// where it is next read. The every-epoch pass and a thinned one carry it close by
/// close (their σ are the same bits); a Monte Carlo's, σ read at a few epochs,
/// lazily.
struct Lambda<const N: usize> {
    lambda: SMatrix<f64, N, N>,
    product: Option<SMatrix<f64, N, N>>,
    lazy: bool,
}

impl<const N: usize> Lambda<N> {
    fn new(lazy: bool) -> Self {
        Self {
            lambda: SMatrix::zeros(),
            product: None,
            lazy,
        }
    }

    /// Carry Λ back through `phi` (spanning `dt` seconds, over which `decay` acts).
    fn through<T: Step<N>>(&mut self, phi: &T, dt: f64, decay: &Decay) {
        match self.lazy {
            true => {
                let k = self.product.get_or_insert_with(SMatrix::identity);
                phi.accumulate(k);
                decay.accumulate(dt, k);
            }
            false => {
                phi.congruence(&mut self.lambda);
                decay.congruence(dt, &mut self.lambda);
            }
        }
    }

    /// Λ here.
    fn get(&mut self) -> &SMatrix<f64, N, N> {
        if let Some(k) = self.product.take() {
            self.lambda = symmetric(&(k.transpose() * self.lambda * k));
        }
        &self.lambda
    }

    /// Λ replaced (at an update).
    fn set(&mut self, lambda: SMatrix<f64, N, N>) {
        (self.lambda, self.product) = (lambda, None);
    }
}

/// The smoothed mean at the closes of an interval that carry no covariance (`mus`: `μ`
/// at each, last first), forward from the smoothed error `ds` at the interval's first
/// node: `δs_{i+1} = Φ_i δs_i + Q_i μ_{i+1}` (Bryson–Frazier: `P_{i+1} μ_{i+1}`
/// without `P`), each written where read, up to the first close with a covariance.
fn mean_forward<const N: usize, T: Step<N>, S: Sink>(
    closes: &[Close<N, T>],
    mus: &mut Vec<SVector<f64, N>>,
    mut ds: SVector<f64, N>,
    rows: &mut Rows<'_, S>,
    (cfg, decay): (&FilterConfig, &Decay),
) -> Result<()> {
    for close in closes.iter().take_while(|c| c.p_prior.is_none()) {
        let mu = mus
            .pop()
            .ok_or_else(|| Error::Numerical("the smoother: μ lost".into()))?;
        ds = close
            .phi
            .next_mean(&ds, &mu)
            .ok_or_else(|| Error::Numerical("the smoother: a step without its noise".into()))?;
        decay.next_mean(close.dt, &mu, &mut ds);
        for row in rows.of(close.epoch..close.epoch + 1) {
            rows.sink.apply(row, &ds, cfg);
        }
    }
    Ok(())
}

/// What the backward pass reads at a close: the smoothed covariance `Ps = P + P Λ P`
/// (`P` the forward one after the close's updates) where it is read, and the change
/// the smoother makes to each state's variance there (see [`super::sink`]) where σ is
/// wanted in the steps around it. Each change is read at the forward velocity the
/// forward σ it changes was read at: `near` after the updates (from `P`, at the
/// velocity after them: the near end of the step after the close), `far` before them
/// (from the covariance the close left, at the velocity before them: the far end of
/// the step before it; the smoothed covariance is the same before and after the
/// updates).
#[derive(Default)]
struct AtClose<const N: usize> {
    ps: Option<SMatrix<f64, N, N>>,
    near: Option<SVector<f64, N>>,
    far: Option<SVector<f64, N>>,
}

impl<const N: usize> AtClose<N> {
    /// At `close`, from the forward covariance after its updates `p` and `Λ` there;
    /// `at_node`: the close is a node's (updates, or a noise change, after it);
    /// `before`/`after`: σ is wanted in the step before the close / after it.
    fn read<T: Step<N>>(
        close: &Close<N, T>,
        (p, lambda): (&SMatrix<f64, N, N>, &SMatrix<f64, N, N>),
        (at_node, before, after): (bool, bool, bool),
    ) -> Self {
        if T::EVERY_EPOCH && !at_node {
            // Nothing between two closes and no update here: the change after the close
            // alone, read directly (`Ps` not formed).
            let near = after.then(|| change_of(p, lambda, &close.point));
            return Self {
                ps: None,
                near,
                far: None,
            };
        }
        let ps = (at_node || before || after).then(|| symmetric(&(p + p * lambda * p)));
        let (near, far) = match &ps {
            Some(ps) => {
                let near = change(ps, p, &close.point);
                let far = match (at_node, close.p_prior.as_ref()) {
                    (true, Some(prior)) => before.then(|| change(ps, prior, &close.point_prior)),
                    _ => before.then_some(near),
                };
                (after.then_some(near), far)
            }
            None => (None, None),
        };
        Self { ps, near, far }
    }

    /// Carry `μ` and `Λ` back through `close` (of the interval that ends at the node
    /// `b`; `at_node`: the close is `b`'s): through `b`'s updates there
    /// ([`at_update`], from `Ps` and `δs⁻ = δs + δx̂`, `ds` the smoothed error after
    /// them), then through the step's Φ. The close as the one before it sees it.
    fn back_through<T: Step<N>>(
        self,
        close: &Close<N, T>,
        (b, at_node): (&Node, bool),
        ds: &SVector<f64, N>,
        (mu, lambda, decay): (&mut SVector<f64, N>, &mut Lambda<N>, &Decay),
    ) -> Result<Later<N>> {
        let mut ds_prior = *ds;
        if let (true, Some(ps), Some(prior)) = (at_node, self.ps.as_ref(), close.p_prior.as_ref()) {
            ds_prior += b.dx::<N>();
            let (m, l) = at_update(prior, ps, &ds_prior).ok_or_else(|| {
                Error::Numerical(format!(
                    "the smoother: the covariance before epoch {} is not positive definite",
                    b.epoch
                ))
            })?;
            *mu = m;
            lambda.set(l);
        }
        *mu = close.phi.transposed(mu);
        decay.mean(close.dt, mu);
        lambda.through(&close.phi, close.dt, decay);
        Ok(Later {
            epoch: close.epoch,
            ds_prior,
            change: self.far,
        })
    }
}

/// A close already smoothed, seen from the one before it: its epoch, the smoothed error
/// before its updates `δs⁻` and the change the smoother makes to the variances there
/// before them ([`AtClose::far`], where σ is wanted in the step before it).
struct Later<const N: usize> {
    epoch: usize,
    ds_prior: SVector<f64, N>,
    change: Option<SVector<f64, N>>,
}

impl<const N: usize> Later<N> {
    /// Write the smoothed solution at the row `row` of `at` (its forward solution), an
    /// epoch a fraction `w` of the way in time from the close before (its smoothed
    /// error `ds`, and the change `near` to the variances after its updates, None where
    /// σ is not wanted) to this close: the error linear in time from `ds` to this
    /// close's `δs⁻`, the change to the variances linear in time from `near` to this
    /// close's before its updates, added to the forward variances at the epoch. The
    /// smoothed covariance given all the data is the same before and after an epoch's
    /// updates (they move the forward estimate by a known amount, not what the
    /// smoother knows); the forward pass interpolates its own variances between the
    /// same two ends (`docs/reference/smoother.md`, "With a covariance step").
    fn write_between(
        &self,
        out: &mut impl Sink,
        (row, at): (usize, &Forward<'_>),
        w: f64,
        (ds, near): (&SVector<f64, N>, Option<&SVector<f64, N>>),
        cfg: &FilterConfig,
    ) {
        if let Some(near) = near {
            debug_assert!(
                self.change.is_some(),
                "σ wanted between closes, none at the far one"
            );
            let far = self.change.as_ref().unwrap_or(near);
            out.set_sigma_between(row, (near, far, w), at);
        }
        out.apply(row, &(ds * (1.0 - w) + self.ds_prior * w), cfg);
    }
}

/// The epoch of the close before the `k`-th of `closes` (the closes in `(a, b]`): the
/// one before it there, else `a`'s where no covariance step was under way after `a`
/// (the step closed at `a`, or `a` is the first epoch); None where unknown (`a` inside
/// a step).
fn previous_close<const N: usize, T>(closes: &[Close<N, T>], k: usize, a: &Node) -> Option<usize> {
    match k {
        0 => a.step.is_none().then_some(a.epoch),
        _ => Some(closes[k - 1].epoch),
    }
}
