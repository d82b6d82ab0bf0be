//! Where the backward pass's transitions come from: the closes between two nodes of
//! the forward pass ([`Close`]), each the transition `Φ` from the close before it and
//! the covariance it left. At every IMU sample each sample closes ([`samples`]); under
//! a covariance step the steps do, rebuilt ([`steps`]) or as the forward pass kept
//! them ([`kept`]). A thinned forward pass gives the same closes from its solution
//! re-integrated between its nodes (`super::thinned`).

use super::forward::Forward;
use super::kept::KeptCloses;
use super::node::{full_p, lift, restart, restart_at, Node};
use super::transition::{NavRows, Sample};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::dynamics::{add_imu_noise, ErrorDynamics};
use crate::ekf::{Ekf, FilterConfig, Matrix15, Point, ProcessNoise, Transition, ACC_BIAS};
use crate::error::{Error, Result};
use crate::mechanization::{step_with_rates, FrameRates, ImuSample, NavState};
use nalgebra::{SMatrix, Vector3};

/// A close of the forward pass's covariance: its epoch, the transition `phi` from the
/// close before it, the covariance it left over `N` states (before the epoch's
/// updates; None where the backward pass reads it nowhere: a thinned pass's epochs at
/// every sample that are neither kept nor a node's), and the point of the map to the
/// classic coordinates (the forward velocity, and in SE₂(3) displacement) at its epoch
/// before the updates there and after them: σ is read at the one the forward σ was
/// (the covariance the close left before the updates, the one after them after).
pub(crate) struct Close<const N: usize, T> {
    pub(crate) epoch: usize,
    pub(crate) phi: T,
    /// The time `phi` spans \[s\].
    pub(crate) dt: f64,
    pub(crate) p_prior: Option<SMatrix<f64, N, N>>,
    pub(crate) point_prior: Point,
    pub(crate) point: Point,
}

impl<const N: usize> Close<N, NavRows> {
    /// The close `ekf` just made at `epoch` with the transition `phi`, the forward
    /// point there before the epoch's updates and after them `(point_prior, point)`.
    pub(super) fn of(
        ekf: &Ekf,
        epoch: usize,
        phi: &Transition,
        (point_prior, point): (Point, Point),
    ) -> Self {
        Self {
            epoch,
            phi: phi.nav_rows(),
            dt: phi.dt,
            p_prior: Some(full_p::<N>(ekf)),
            point_prior,
            point,
        }
    }
}

/// The closes in `(a, b]` at every IMU sample, into `closes`: each sample's `Φ = I + F Δt`
/// rebuilt by the filter's prediction along the forward solution from `a` (read, not
/// integrated again: the same steps on the same numbers, so the covariance before
/// `b`'s update is the forward pass's, bit for bit), the covariance at each close where
/// `keep` holds for its epoch and at `b`. `forward`'s epochs count from `offset` (a
/// re-integrated stretch starts at `a`), `vel_b` is the forward solution's point at `b`
/// after its updates.
#[allow(clippy::too_many_arguments)]
pub(crate) fn samples<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    (a, b): (&Node, usize),
    (offset, vel_b): (usize, Point),
    keep: &dyn Fn(usize) -> bool,
    closes: &mut Vec<Close<N, Sample>>,
    cancel: &Cancel,
) -> Result<()> {
    closes.clear();
    let (from, to) = (a.epoch - offset, b - offset);
    let mut ekf = restart_at(forward.nav[from], &forward.bias[from], cfg, a)?;
    let noise = a.noise.as_process_noise();
    for i in from..to {
        if (i - from) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        // The step from epoch i to i + 1 reads IMU row i.
        let raw = ImuSample::from_array(&forward.imu[i]);
        let dt = forward.step(i);
        let (dynamics, _) = ekf.predict_covariance_from(&forward.nav[i], &raw, dt, noise);
        let dynamics = dynamics.ok_or_else(|| {
            Error::Numerical("the smoother: a covariance step where none was".into())
        })?;
        let epoch = i + 1 + offset;
        let vel = if epoch == b {
            vel_b
        } else {
            cfg.coordinates().at(&forward.nav[i + 1])
        };
        closes.push(Close {
            epoch,
            phi: Sample {
                dynamics,
                dt,
                q: None,
            },
            dt,
            p_prior: (epoch == b || keep(epoch)).then(|| full_p::<N>(&ekf)),
            point_prior: vel,
            point: vel,
        });
    }
    Ok(())
}

/// The closes in `(a, b]` at every IMU sample where only the smoothed mean is read
/// between the two nodes and `b` kept the covariance before its updates (`prior`): no
/// covariance is predicted, each sample's Φ and the noise `Q` the filter added after it
/// are built at the forward solution (as [`samples`] builds them), the covariance at
/// `b` is the kept one; the backward pass then takes the mean by the Bryson–Frazier
/// form ([`super::transition::Step::next_mean`]).
pub(crate) fn samples_mean<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    (a, b, prior): (&Node, usize, &Matrix15),
    vel_b: Point,
    closes: &mut Vec<Close<N, Sample>>,
    cancel: &Cancel,
) -> Result<()> {
    // The closes are overwritten in place, not pushed: a Monte Carlo's run rebuilds
    // one per IMU sample, each 4 kB with its Q, and a push would move every byte.
    closes.truncate(b - a.epoch);
    let bias = &forward.bias[a.epoch];
    let accel_bias = Vector3::new(bias[0], bias[1], bias[2]);
    let noise = a.noise.as_process_noise();
    for (n, i) in (a.epoch..b).enumerate() {
        if (i - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let (nav, dt) = (&forward.nav[i], forward.step(i));
        let accel = ImuSample::from_array(&forward.imu[i]).accel - accel_bias;
        let at = cfg.coordinates().at(nav);
        let dynamics = ErrorDynamics::new(nav, &FrameRates::at(nav), &accel, &at);
        let epoch = i + 1;
        let (vel, p_prior) = match epoch == b {
            true => (vel_b, Some(lift::<N>(prior, None))),
            false => (cfg.coordinates().at(&forward.nav[epoch]), None),
        };
        if n == closes.len() {
            closes.push(Close {
                epoch,
                phi: Sample {
                    dynamics,
                    dt,
                    q: Some(Matrix15::zeros()),
                },
                dt,
                p_prior,
                point_prior: vel,
                point: vel,
            });
        } else {
            let c = &mut closes[n];
            (c.epoch, c.phi.dynamics, c.phi.dt, c.dt) = (epoch, dynamics, dt, dt);
            (c.p_prior, c.point_prior, c.point) = (p_prior, vel, vel);
            c.phi
                .q
                .get_or_insert_with(Matrix15::zeros)
                .as_mut_slice()
                .fill(0.0);
        }
        if let Some(q) = closes[n].phi.q.as_mut() {
            discrete_noise(cfg, nav, noise, dt, q);
        }
    }
    Ok(())
}

/// The discrete noise `Q` the filter adds after `Φ` at one sample of `dt` seconds at
/// the solution `nav` (its prediction's), added to `q` (zeros).
fn discrete_noise(
    cfg: &FilterConfig,
    nav: &NavState,
    noise: ProcessNoise<'_>,
    dt: f64,
    q: &mut Matrix15,
) {
    match noise {
        ProcessNoise::Continuous {
            imu_variance,
            bias_psd,
        } => {
            add_imu_noise(
                q,
                nav,
                &cfg.coordinates().at(nav),
                imu_variance,
                cfg.imu_dt * dt,
            );
            for (i, psd) in bias_psd.iter().enumerate() {
                q[(ACC_BIAS + i, ACC_BIAS + i)] += psd * dt;
            }
        }
        ProcessNoise::Discrete(qd) => {
            *q = (qd + qd.transpose()) * 0.5;
            cfg.coordinates().at(nav).from_classic(q);
        }
    }
}

/// The closes in `(a, b]` of the covariance step that the forward pass kept (see
/// [`KeptCloses::note`]), as [`steps`] makes them (the velocity before the updates
/// the one the forward pass kept at the close).
pub(super) fn kept<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    kept: &KeptCloses,
    (a, b): (&Node, &Node),
    closes: &mut Vec<Close<N, NavRows>>,
) {
    closes.clear();
    let lo = kept.epochs.partition_point(|e| *e <= a.epoch);
    let hi = kept.epochs.partition_point(|e| *e <= b.epoch).max(lo);
    closes.extend((lo..hi).map(|k| {
        let c = &kept.closes[k];
        let epoch = kept.epochs[k];
        Close {
            epoch,
            phi: c.phi,
            dt: c.dt,
            p_prior: Some(lift(&c.p(), c.calibration.as_deref().map(|(x, v)| (x, v)))),
            point_prior: c.point,
            point: cfg.coordinates().at(&forward.nav[epoch]),
        }
    }));
}

/// The closes in `(a, b]` of the covariance step, rebuilt by the filter's prediction
/// along the forward solution from `a` (and the step `a` was inside, if any), the noise
/// of `a` throughout; `b`'s step is closed at `b` where the forward pass closed it
/// (the velocity there before `b`'s updates from [`before_updates`]; no
/// update between the nodes: before and after are the same elsewhere).
pub(crate) fn steps<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    (a, b): (&Node, &Node),
    closes: &mut Vec<Close<N, NavRows>>,
    cancel: &Cancel,
) -> Result<()> {
    closes.clear();
    let mut ekf = restart(forward, cfg, a)?;
    let noise = a.noise.as_process_noise();
    let at_b = cfg.coordinates().at(&before_updates(forward, b.epoch));
    let mut push = |ekf: &Ekf, epoch: usize, phi: Transition| {
        let vel = cfg.coordinates().at(&forward.nav[epoch]);
        let vel_prior = if epoch == b.epoch { at_b } else { vel };
        closes.push(Close::of(ekf, epoch, &phi, (vel_prior, vel)));
    };
    for epoch in a.epoch..b.epoch {
        if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&forward.imu[epoch]);
        let dt = forward.step(epoch);
        let (_, closed) = ekf.predict_covariance_from(&forward.nav[epoch], &raw, dt, noise);
        if let Some(phi) = closed {
            push(&ekf, epoch + 1, phi);
        }
    }
    if b.step.is_none() {
        if let Some(phi) = ekf.bring_up_to_date() {
            push(&ekf, b.epoch, phi);
        }
    }
    Ok(())
}

/// The forward solution at `epoch` (≥ 1) before its updates: the strapdown step from
/// the solution after the updates of the epoch before, with its bias estimates, as the
/// forward pass took it (the same operations on the same numbers).
fn before_updates(forward: &Forward<'_>, epoch: usize) -> NavState {
    let (nav, b) = (&forward.nav[epoch - 1], &forward.bias[epoch - 1]);
    integrate(nav, &forward.imu[epoch - 1], b, forward.step(epoch - 1))
}

/// The strapdown step of a forward solution `nav` with the bias-corrected `raw` sample
/// (the bias estimates `[b_a, b_g]`) over `dt` seconds.
pub(super) fn integrate(nav: &NavState, raw: &[f64; 6], bias: &[f64; 6], dt: f64) -> NavState {
    let raw = ImuSample::from_array(raw);
    let imu = ImuSample {
        accel: raw.accel - Vector3::new(bias[0], bias[1], bias[2]),
        gyro: raw.gyro - Vector3::new(bias[3], bias[4], bias[5]),
    };
    step_with_rates(nav, &imu, dt, &FrameRates::at(nav))
}
