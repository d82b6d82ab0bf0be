//! The RTS smoother over a simulated run: what a run keeps for it as it steps
//! ([`SmootherLog`]), the backward pass at the end, and the smoothed solution's metrics
//! against the truth ([`SmoothedRecord`]), as the run reports its own.

use super::metrics::{nees3, se23_position_nees, solution_error};
use super::History;
use crate::attitude::exp_so3;
use crate::cancel::Cancel;
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{correct, corrected_position_velocity, Coordinates, Point};
use crate::ekf::{Applied, Ekf, FilterConfig, Formulation, Matrix15, ProcessNoise, Transition};
use crate::ekf::{Vector15, ACC_BIAS, ATT, GYRO_BIAS, POS, VEL};
use crate::measurement::Reading;
use crate::mechanization::NavState;
use crate::noise::NoiseStrategy;
use crate::pass::{Epoch, Observer, Updated};
use crate::smoother::{changed_sigma, smooth_into, Covariances, Forward, ForwardLog};
use crate::smoother::{KeptCloses, Sink};
use crate::trajectory::Truth;
use nalgebra::{SMatrix, SVector, Vector3};
use std::collections::HashMap;

/// A run's metrics after the RTS smoother: the [`RunSummary`] error metrics, the block
/// NEES at the DVL updates and the histories of the smoothed solution.
///
/// [`RunSummary`]: super::RunSummary
#[derive(Clone, Debug, PartialEq)]
pub struct SmoothedRecord {
    pub srmse: f64,
    pub smae: f64,
    pub final_horizontal_error: f64,
    pub max_horizontal_error: f64,
    /// As [`RunRecord::nees`](super::RunRecord::nees), at the same epochs.
    pub nees: Vec<[f64; 5]>,
    /// Error and σ at the recorded epochs (`imu_variance` empty).
    pub history: Option<History>,
}

/// What the smoother reads of a run, kept as it steps: the nodes and, under a covariance
/// step, the closes (see [`crate::smoother`]), the forward solution at every epoch, the
/// epochs of the DVL updates, and the raw IMU samples (every sample).
pub(super) struct SmootherLog {
    /// The nodes; under a covariance step, each close the filter made and its epoch
    /// (the backward pass reads them instead of rebuilding them: 2.0 kB each, one per
    /// step, room made for them at the start; None at every sample, where the
    /// backward pass rebuilds what it needs).
    pub(super) forward: ForwardLog,
    /// The raw IMU samples, where the backward pass rebuilds the covariances from
    /// them (every sample; empty under a covariance step).
    pub(super) imu: Vec<[f64; 6]>,
    pub(super) nav: Vec<NavState>,
    /// The bias estimates `[b_a, b_g]` at every epoch where the backward pass rebuilds
    /// the covariances (every sample; empty under a covariance step, where they are
    /// read only at the epochs of `whole`).
    pub(super) bias: Vec<[f64; 6]>,
    /// With the DVL calibration states, their estimate at every epoch (empty without).
    pub(super) calibration: Vec<DvlErrors>,
    /// At each epoch where the whole smoothed solution is read, in order (the recorded
    /// epochs and those of the DVL updates; the others read the velocity and position
    /// alone): the epoch, the filter's bias estimates and the IMU's true bias (the one
    /// errors are taken against).
    pub(super) whole: Vec<(usize, [f64; 6], [f64; 6])>,
    /// The epoch of each DVL update, None for a reading lost (as the run's `nees`).
    pub(super) update_epochs: Vec<Option<usize>>,
}

impl SmootherLog {
    /// Keep the forward solution of the epoch `epoch` just run and, where the whole
    /// solution is read (`recorded`, or a DVL update there), the true bias
    /// `true_bias`.
    pub(super) fn push(&mut self, epoch: usize, ekf: &Ekf, true_bias: [f64; 6], recorded: bool) {
        self.nav.push(ekf.nav);
        if self.forward.closes.is_none() {
            self.bias.push(ekf.bias());
        }
        if let Some(c) = &ekf.calibration {
            self.calibration.push(c.reported());
        }
        if recorded || self.update_epochs.last() == Some(&Some(epoch)) {
            self.whole.push((epoch, ekf.bias(), true_bias));
        }
    }

    /// The log as the observer of the epoch under way: its raw IMU sample `raw`, the
    /// IMU's true bias there and whether the epoch is recorded.
    pub(super) fn at_epoch(
        &mut self,
        raw: [f64; 6],
        true_bias: [f64; 6],
        recorded: bool,
    ) -> EpochLog<'_> {
        EpochLog {
            log: self,
            raw,
            true_bias,
            recorded,
        }
    }
}

/// A [`SmootherLog`] told of one epoch of the run's pass.
pub(super) struct EpochLog<'a> {
    log: &'a mut SmootherLog,
    raw: [f64; 6],
    true_bias: [f64; 6],
    recorded: bool,
}

impl Observer for EpochLog<'_> {
    fn before_step(&mut self, at: &Epoch<'_>, ekf: &Ekf, noise: ProcessNoise<'_>) {
        self.log.forward.before_step(at, ekf, noise);
        if self.log.forward.closes.is_none() {
            // Read only where the backward pass rebuilds the closes.
            self.log.imu.push(self.raw);
        }
    }

    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        self.log.forward.on_close(epoch, ekf, phi);
    }

    fn wants_prior(&self) -> bool {
        self.log.forward.wants_prior()
    }

    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        _i: usize,
        reading: &Reading,
        _applied: &mut Applied,
        _ekf: &Ekf,
        _strategy: &dyn NoiseStrategy,
    ) {
        if let Reading::Velocity(_) = reading {
            self.log.update_epochs.push(Some(at.index));
        }
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        self.log.forward.after_epoch(at, ekf, updated, noise);
        self.log.push(at.index, ekf, self.true_bias, self.recorded);
    }
}

/// How many epochs back [`Reduced::apply`] asks for its data ahead of time: about a
/// close of the default covariance step at 100 Hz.
const PREFETCH: usize = 10;

/// No entry in [`SmootherLog::whole`] at an epoch.
const NOT_WHOLE: u32 = u32::MAX;

/// Ask the CPU to bring `x` into its cache (a hint; nothing elsewhere).
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (x as *const T).cast::<i8>();
        // SAFETY: SSE is part of every x86_64 CPU, and a prefetch reads nothing (it
        // never faults, whatever the address).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            if std::mem::size_of::<T>() > 64 {
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            }
        }
    }
}

/// The smoothed solution of a run reduced to what its metrics read, as the backward
/// pass gives it ([`Sink`]): at every epoch the terms of the velocity and horizontal
/// position errors, and the whole solution only where it is read (the epochs whose
/// true bias the log kept). No copy of the forward solution is made.
struct Reduced<'a> {
    log: &'a SmootherLog,
    truth: &'a Truth,
    /// Where the whole solution is read: the index in the log's `whole` at each epoch
    /// (`NOT_WHOLE` elsewhere).
    whole: Vec<u32>,
    /// `[|δv|², Σ|δv_j|, δN² + δE²]` at each epoch the pass corrected.
    terms: Vec<Option<[f64; 3]>>,
    /// The forward σ at the recorded epochs (every `record_every`-th), the smoothed σ
    /// is changed from (empty without a history).
    forward_sigma: &'a [[f64; 15]],
    record_every: usize,
    /// The smoothed solution and bias estimates where the whole one is read.
    solutions: Vec<(usize, NavState, [f64; 6])>,
    sigma: Vec<(usize, [f64; 15])>,
    node_covariance: Vec<(usize, Matrix15)>,
}

impl<'a> Reduced<'a> {
    fn new(
        log: &'a SmootherLog,
        truth: &'a Truth,
        (forward_sigma, record_every): (&'a [[f64; 15]], usize),
    ) -> Self {
        let n = log.nav.len();
        let mut whole = vec![NOT_WHOLE; n];
        for (at, (k, _, _)) in log.whole.iter().enumerate() {
            whole[*k] = at as u32;
        }
        Self {
            log,
            truth,
            whole,
            terms: vec![None; n],
            forward_sigma,
            record_every,
            solutions: Vec::with_capacity(log.whole.len()),
            sigma: Vec::new(),
            node_covariance: Vec::with_capacity(log.forward.nodes.0.len()),
        }
    }

    /// Over epochs 1..n in order, from the velocity and horizontal position alone (the
    /// attitude's logarithm and the biases only where they are recorded): the sums of
    /// `|δv|²` and `Σ|δv_j|`, the largest `δN² + δE²`, and the last horizontal error.
    fn error_sums(&self) -> [f64; 4] {
        let nav = &self.log.nav;
        let (mut sum_sq, mut sum_abs, mut max_sq) = (0.0, 0.0, 0.0_f64);
        let mut horizontal = 0.0;
        for (k, at) in nav.iter().enumerate().skip(1) {
            let [v2, v1, sq] = self.terms[k].unwrap_or_else(|| self.terms_of(k, &at.lla, &at.vel));
            sum_sq += v2;
            sum_abs += v1;
            max_sq = max_sq.max(sq);
            horizontal = sq.sqrt();
        }
        [sum_sq, sum_abs, max_sq, horizontal]
    }

    /// The error terms of the solution (`lla`, `vel`) at epoch `k`.
    fn terms_of(&self, k: usize, lla: &Vector3<f64>, vel: &Vector3<f64>) -> [f64; 3] {
        let truth = &self.truth.states[k];
        let dv = vel - truth.vel;
        let dp = self.truth.ned_scale[k].error(lla, &truth.lla);
        [
            dv.norm_squared(),
            dv.abs().sum(),
            dp[0] * dp[0] + dp[1] * dp[1],
        ]
    }
}

impl Sink for Reduced<'_> {
    fn apply<const N: usize>(&mut self, i: usize, ds: &SVector<f64, N>, cfg: &FilterConfig) {
        // The pass goes back close by close, forward inside each (and forward through
        // an interval taken by the Bryson–Frazier form, where this asks for epochs
        // already read: a wasted hint, no more): ask early for the epochs of the next
        // close back (the run's log is far out of the cache).
        if let Some(ahead) = i.checked_sub(PREFETCH) {
            prefetch(&self.log.nav[ahead]);
            prefetch(&self.truth.states[ahead]);
            prefetch(&self.truth.ned_scale[ahead]);
        }
        let dx: Vector15 = ds.fixed_rows::<15>(0).into_owned();
        let nav = &self.log.nav[i];
        let (lla, vel) = if self.whole[i] != NOT_WHOLE {
            let (mut s, b) = (*nav, self.log.whole[self.whole[i] as usize].1);
            let (mut ab, mut gb) = (
                Vector3::new(b[0], b[1], b[2]),
                Vector3::new(b[3], b[4], b[5]),
            );
            correct(&mut s, &mut ab, &mut gb, &dx, &cfg.coordinates());
            let bias = [ab[0], ab[1], ab[2], gb[0], gb[1], gb[2]];
            self.solutions.push((i, s, bias));
            (s.lla, s.vel)
        } else {
            let psi = || exp_so3(&Vector3::new(dx[ATT], dx[ATT + 1], dx[ATT + 2]));
            corrected_position_velocity(nav, &dx, &cfg.coordinates(), psi)
        };
        self.terms[i] = Some(self.terms_of(i, &lla, &vel));
    }

    /// σ at a recorded epoch `i`: its forward σ in the run's history changed by
    /// `change` (no σ kept elsewhere: only the histories read it).
    fn set_change<const N: usize>(
        &mut self,
        i: usize,
        change: &SVector<f64, N>,
        _forward: &Forward<'_>,
    ) {
        let every = self.record_every;
        let recorded = every > 0 && i.is_multiple_of(every);
        if let Some(sigma) = self
            .forward_sigma
            .get(i / every.max(1))
            .filter(|_| recorded)
        {
            let smoothed = std::array::from_fn(|j| changed_sigma(sigma[j], change[j]));
            self.sigma.push((i, smoothed));
        }
    }

    fn keep_node<const N: usize>(&mut self, epoch: usize, ps: &SMatrix<f64, N, N>) {
        let p = ps.fixed_view::<15, 15>(0, 0).into_owned();
        self.node_covariance.push((epoch, p));
    }
}

/// [`block_nees`] of a smoothed solution `nav` whose covariance `p` is in the
/// filter's coordinates about the point `about` (the forward solution's).
///
/// [`block_nees`]: super::block_nees
fn smoothed_block_nees(
    nav: &NavState,
    p: &Matrix15,
    about: &Point,
    coordinates: &Coordinates,
    truth: &NavState,
    error: &[f64; 15],
) -> [f64; 5] {
    let formulation = coordinates.formulation;
    let mut classic = *p;
    about.to_classic(&mut classic);
    let mut nees = [POS, VEL, ATT, ACC_BIAS, GYRO_BIAS].map(|b| {
        nees3(
            &Vector3::new(error[b], error[b + 1], error[b + 2]),
            &classic,
            b,
        )
    });
    // The velocity block of SE₂(3)'s covariance is the invariant one's.
    let invariant = if formulation.velocity_invariant() {
        *p
    } else {
        let mut q = classic;
        Point::velocity(Formulation::Invariant, &nav.vel).from_classic(&mut q);
        q
    };
    let dv = nav.vel - nav.dcm * (truth.dcm.transpose() * truth.vel);
    nees[1] = nees3(&dv, &invariant, VEL);
    if formulation.position_invariant() {
        nees[0] = se23_position_nees(coordinates, nav, truth, p);
    }
    nees
}

/// The smoothed solution's metrics against the truth, as a forward run reports them
/// (an epoch the pass left as it was, the last without a covariance step, is the
/// forward solution's).
fn smoothed_metrics(
    s: Reduced<'_>,
    coordinates: Coordinates,
    record_every: usize,
) -> SmoothedRecord {
    let (log, truth) = (s.log, s.truth);
    let n = log.nav.len() - 1;
    let solutions: HashMap<usize, (NavState, [f64; 6])> = s
        .solutions
        .iter()
        .map(|(k, nav, b)| (*k, (*nav, *b)))
        .collect();
    // Every epoch read whole has its entry in the log's `whole`.
    let whole = |k: usize| {
        let at = log.whole.binary_search_by_key(&k, |(e, _, _)| *e);
        at.map_or(([f64::NAN; 6], [f64::NAN; 6]), |at| {
            (log.whole[at].1, log.whole[at].2)
        })
    };
    let solution = |k: usize| {
        let forward = || (log.nav[k], whole(k).0);
        solutions.get(&k).copied().unwrap_or_else(forward)
    };
    let error = |k: usize| {
        let (nav, bias) = solution(k);
        solution_error(&nav, &bias, &truth.states[k], &whole(k).1)
    };
    let [sum_sq, sum_abs, max_sq, horizontal] = s.error_sums();
    let covariance: HashMap<usize, &Matrix15> =
        s.node_covariance.iter().map(|(k, p)| (*k, p)).collect();
    let nees = log
        .update_epochs
        .iter()
        .map(
            |&k| match k.and_then(|k| covariance.get(&k).map(|p| (k, p))) {
                Some((k, p)) => {
                    let about = coordinates.at(&log.nav[k]);
                    smoothed_block_nees(
                        &solution(k).0,
                        p,
                        &about,
                        &coordinates,
                        &truth.states[k],
                        &error(k),
                    )
                }
                None => [f64::NAN; 5],
            },
        )
        .collect();
    let history = (record_every > 0).then(|| {
        let sigma: HashMap<usize, [f64; 15]> = s.sigma.iter().copied().collect();
        let epochs = (0..=n).step_by(record_every);
        History {
            error: epochs.clone().map(error).collect(),
            sigma: epochs
                .map(|k| sigma.get(&k).copied().unwrap_or([f64::NAN; 15]))
                .collect(),
            imu_variance: Vec::new(),
        }
    });
    let steps = n.max(1) as f64;
    SmoothedRecord {
        srmse: (sum_sq / steps).sqrt(),
        smae: sum_abs / steps,
        final_horizontal_error: horizontal,
        max_horizontal_error: max_sq.sqrt(),
        nees,
        history,
    }
}

impl SmootherLog {
    /// What the backward pass reads of the forward one (the run's epochs so far).
    fn forward<'a>(&'a self, truth: &'a Truth) -> Forward<'a> {
        let k = self.nav.len() - 1;
        Forward {
            imu: &self.imu,
            imu_time: &truth.time[1..=k],
            t0: truth.time[0],
            nav: &self.nav,
            bias: &self.bias,
            calibration: &self.calibration,
            sigma: &[],
            calibration_sigma: &[],
            dt: Some(truth.dt),
        }
    }
}

impl SmootherLog {
    /// An empty log for a run of `cfg` over `truth` (a DVL reading every `dvl_every`
    /// IMU steps): under a covariance step, room for a close per step and one before
    /// each DVL update; at every sample, room for the raw samples and bias estimates,
    /// and (with 15 states) the covariance before each node's updates kept.
    pub(super) fn new(cfg: &FilterConfig, truth: &Truth, dvl_every: Option<usize>) -> Self {
        let n = truth.len() + 1;
        let mut log = SmootherLog {
            forward: ForwardLog::default(),
            imu: Vec::new(),
            nav: Vec::with_capacity(n),
            bias: Vec::new(),
            calibration: Vec::new(),
            whole: Vec::new(),
            update_epochs: Vec::new(),
        };
        if cfg.covariance_every_sample() {
            log.imu.reserve(n);
            log.bias.reserve(n);
            // The backward pass skips the covariance where no σ is wanted.
            log.forward.priors = cfg.dvl_calibration.is_none();
        } else {
            let per_step = (cfg.covariance_step / truth.dt).floor().max(1.0) as usize;
            let updates = dvl_every.map_or(0, |every| n / every.max(1));
            log.forward.closes = Some(KeptCloses::with_capacity(n / per_step + updates + 2));
        }
        log
    }

    /// The smoothed metrics of a run over `truth` whose forward σ at every
    /// `record_every`-th epoch is `history_sigma`. A smoother that fails numerically
    /// gives NaN metrics.
    pub(super) fn smoothed_record(
        &self,
        truth: &Truth,
        cfg: &FilterConfig,
        (history_sigma, record_every): (&[[f64; 15]], usize),
    ) -> SmoothedRecord {
        let forward = self.forward(truth);
        // σ where the histories read it; the NEES reads the nodes' covariances.
        let every = record_every;
        let recorded = |k: usize| every > 0 && k.is_multiple_of(every);
        let covariances = Covariances::Where(&recorded);
        let (nodes, cancel) = (&self.forward.nodes.0, &Cancel::default());
        let mut reduced = Reduced::new(self, truth, (history_sigma, every));
        let kept = self.forward.closes.as_ref();
        let smoothed = smooth_into(
            &forward,
            cfg,
            nodes,
            kept,
            covariances,
            &mut reduced,
            cancel,
        );
        if smoothed.is_err() {
            let nan = f64::NAN;
            let history = (record_every > 0).then(|| History {
                error: vec![[nan; 15]; history_sigma.len()],
                sigma: vec![[nan; 15]; history_sigma.len()],
                imu_variance: Vec::new(),
            });
            return SmoothedRecord {
                srmse: nan,
                smae: nan,
                final_horizontal_error: nan,
                max_horizontal_error: nan,
                nees: vec![[nan; 5]; self.update_epochs.len()],
                history,
            };
        }
        smoothed_metrics(reduced, cfg.coordinates(), record_every)
    }
}

#[cfg(test)]
#[path = "smoothing_tests.rs"]
mod tests;
