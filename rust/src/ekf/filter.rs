//! The filter's state and its prediction: the navigation solution, the bias estimates,
//! the error covariance (and the DVL calibration states and the sensitivity beside it),
//! propagated over one IMU sample at a time (the covariance at every sample, or over a
//! covariance step: `super::step`), and the feedback of an error estimate.

use super::calibration::Calibration;
use super::dynamics::{add_imu_noise, ErrorDynamics};
use super::formulation::{Coordinates, Formulation, Point};
use super::process_noise::ProcessNoise;
use super::second_order::SecondOrder;
use super::state::{Matrix15, Vector15, ACC_BIAS, ATT, GYRO_BIAS, POS, VEL};
use super::step::{Covariance, CovarianceStep};
use super::transition::Transition;
use super::FilterConfig;
use crate::attitude::exp_so3;
use crate::earth;
use crate::error::{Error, Result};
use crate::mechanization::{step_with_rates, FrameRates, ImuSample, NavState};
use nalgebra::{Matrix3, Vector3};

/// Filter state: navigation solution, bias estimates, covariance. Nothing of the
/// output or of the smoother: a pass keeps what it reports (`crate::pass`).
#[derive(Clone, Debug)]
// A fixed layout: the covariance propagation (AVX2) reads and writes P's columns at
// every IMU step, and where P lies against a cache line moved a whole Monte Carlo by
// up to 7 %. P 48 bytes past a 64-byte boundary (after the two bias vectors) was the
// fastest of the placements measured, 64-byte aligned the slowest, the compiler's
// choice 3 % slower (`benches/compare_builds.py --monte-carlo`).
#[repr(C, align(64))]
pub struct Ekf {
    /// Accelerometer bias estimate \[m/s²\].
    pub accel_bias: Vector3<f64>,
    /// Gyro bias estimate \[rad/s\].
    pub gyro_bias: Vector3<f64>,
    /// The error covariance in the coordinates of [`FilterConfig::formulation`]
    /// ([`Ekf::covariance`] gives it in the classic ones users read).
    pub p: Matrix15,
    pub nav: NavState,
    /// Last bias-corrected gyro sample \[rad/s\] (for the lever-arm terms).
    pub(super) last_gyro: Vector3<f64>,
    /// The variance of that sample's white noise per body axis \[(rad/s)²\] under the
    /// step's process noise, and the step \[s\] (see [`Ekf::gyro_noise`]).
    pub(super) last_gyro_variance: Vector3<f64>,
    pub(super) last_dt: f64,
    pub(super) cfg: FilterConfig,
    /// `M = ∂P/∂λ` and the IMU variances `q` it is taken for (see
    /// [`Ekf::track_sensitivity`]).
    pub(super) sensitivity: Option<(Matrix15, [f64; 6])>,
    /// The DVL calibration states, when [`FilterConfig::dvl_calibration`] asks for them.
    pub calibration: Option<Calibration>,
    /// The calibration blocks of `M` (with [`Ekf::track_sensitivity`] and calibration).
    pub(super) sensitivity_calibration: Option<Calibration>,
    /// The covariance step under way (see [`FilterConfig::covariance_step`]): P, M and
    /// the calibration blocks stand at its start.
    pub(super) step: Option<CovarianceStep>,
    /// The second-order heading term, when [`FilterConfig::heading_second_order`] asks
    /// for it (P includes it; `super::second_order`). Boxed: the filter without it
    /// carries 8 bytes for it.
    pub second_order: Option<Box<SecondOrder>>,
}

/// The 1σ of the 15 states (classic coordinates) and of the DVL calibration states, if
/// any.
pub type ClosedSigma = ([f64; 15], Option<super::calibration::DvlErrors>);

/// [`Ekf::sigma`] of a covariance `p` in the coordinates of the point `at` (the
/// formulation and where its map is taken): the same operations, so that a σ computed
/// later from a copy of an epoch's P and point is the one computed there, bit for bit.
pub fn classic_sigma(at: &Point, p: &Matrix15) -> [f64; 15] {
    let variances = at.classic_variances(p);
    std::array::from_fn(|i| {
        let v = variances[i];
        if v < 0.0 {
            0.0
        } else {
            v.sqrt()
        }
    })
}

impl Ekf {
    pub fn new(
        cfg: &FilterConfig,
        nav: NavState,
        accel_bias: Vector3<f64>,
        gyro_bias: Vector3<f64>,
    ) -> Result<Self> {
        cfg.validate()?;
        let cfg = cfg.anchored(&nav.lla);
        let mut p = cfg.p0();
        cfg.coordinates().at(&nav).from_classic(&mut p);
        Ok(Self {
            nav,
            accel_bias,
            gyro_bias,
            p,
            last_gyro: Vector3::zeros(),
            last_gyro_variance: Vector3::zeros(),
            last_dt: 0.0,
            sensitivity: None,
            calibration: cfg.dvl_calibration.as_ref().map(Calibration::new),
            sensitivity_calibration: None,
            step: None,
            second_order: cfg.heading_second_order.then(Box::default),
            cfg,
        })
    }

    /// A filter at the solution `nav` with the bias estimates `bias` (`[b_a, b_g]`)
    /// whose covariance (the calibration blocks too, where given) and covariance step
    /// under way are given: where the smoother restarts the forward pass's prediction.
    pub fn restart(
        cfg: &FilterConfig,
        nav: NavState,
        bias: &[f64; 6],
        p: Matrix15,
        calibration: Option<(&super::calibration::Cross, &super::calibration::DvlCov)>,
        step: Option<CovarianceStep>,
        second_order: Option<Box<SecondOrder>>,
    ) -> Result<Self> {
        let b = bias;
        let mut ekf = Ekf::new(
            cfg,
            nav,
            Vector3::new(b[0], b[1], b[2]),
            Vector3::new(b[3], b[4], b[5]),
        )?;
        ekf.p = p;
        if let (Some(c), Some((cross, cov))) = (ekf.calibration.as_mut(), calibration) {
            (c.cross, c.cov) = (*cross, *cov);
        }
        ekf.step = step;
        if ekf.second_order.is_some() {
            debug_assert!(
                second_order.is_some(),
                "a node of a pass with the term has it"
            );
            if let Some(s) = second_order {
                ekf.second_order = Some(s);
            }
        }
        Ok(ekf)
    }

    /// Carry `M = ∂P/∂λ` beside P from now on: the derivative of the covariance with
    /// respect to a common scale λ on the IMU variances (the IMU part of Q^c being
    /// `λ·q·Δt_imu`). M starts at 0, is propagated as P is with the IMU noise of `q`
    /// alone, and goes through each applied update as `(I − K H) M (I − K H)ᵀ +
    /// K (∂R/∂λ) Kᵀ` (`∂R/∂λ` the DVL lever arm's gyro-noise term, else zero), which is
    /// exact to first order because ∂P⁺/∂K vanishes at the Kalman gain. Each velocity
    /// update then reports `∂S/∂λ = H M Hᵀ + ∂R/∂λ`
    /// ([`super::UpdateInfo::sensitivity`]); the adaptive strategy reads it.
    pub fn track_sensitivity(&mut self, q: [f64; 6]) {
        self.bring_up_to_date();
        self.sensitivity = Some((Matrix15::zeros(), q));
        self.sensitivity_calibration = self.calibration.as_ref().map(Calibration::zeroed_like);
    }

    /// The sensitivity `M = ∂P/∂λ` carried since [`Ekf::track_sensitivity`], if any.
    pub fn sensitivity_matrix(&self) -> Option<&Matrix15> {
        self.sensitivity.as_ref().map(|(m, _)| m)
    }

    /// The configuration, with the SE₂(3) anchor resolved.
    pub fn config(&self) -> &FilterConfig {
        &self.cfg
    }

    /// Where the map between the filter's error coordinates and the classic ones is
    /// taken now.
    #[inline]
    pub fn point(&self) -> Point {
        self.cfg.coordinates().at(&self.nav)
    }

    /// The last bias-corrected gyro sample \[rad/s, body\].
    pub fn last_gyro(&self) -> &Vector3<f64> {
        &self.last_gyro
    }

    /// The covariance of the white noise on [`Ekf::last_gyro`] \[(rad/s)², body\]
    /// (diagonal): the gyro's per-sample variance under the last step's process noise,
    /// `q_g·Δt_imu/Δt` (`Q^c = q·Δt_imu` over a step of `Δt`); zero under a discrete Q
    /// (Mehra's), which names no channel. With it, the `d_λ` of the same for the IMU
    /// variances whose scale the sensitivity is carried for
    /// ([`Ekf::track_sensitivity`]), where it is: what a lever arm's `ω̂ × r` adds to a
    /// reading's noise, and its derivative.
    pub fn gyro_noise(&self) -> (Matrix3<f64>, Option<Matrix3<f64>>) {
        // Before any step the sample is none and its noise zero (no division by 0).
        let stepped = self.last_dt > 0.0;
        let tracked = self.sensitivity.as_ref().filter(|_| stepped).map(|(_, q)| {
            let white = self.cfg.imu_dt / self.last_dt;
            Matrix3::from_diagonal(&Vector3::new(q[3], q[4], q[5])) * white
        });
        (Matrix3::from_diagonal(&self.last_gyro_variance), tracked)
    }

    /// The bias estimates `[b_a, b_g]`.
    pub fn bias(&self) -> [f64; 6] {
        let (a, g) = (self.accel_bias, self.gyro_bias);
        [a[0], a[1], a[2], g[0], g[1], g[2]]
    }

    /// The error covariance in the classic coordinates (`δv = v̂ − v`), whatever the
    /// formulation: the one users read and NEES is taken in.
    pub fn covariance(&self) -> Matrix15 {
        self.to_classic(&self.p)
    }

    /// The error covariance in the coordinates of `formulation` (mapped from the
    /// filter's own at the current velocity estimate when they differ).
    pub fn covariance_in(&self, formulation: Formulation) -> Matrix15 {
        if formulation == self.cfg.formulation {
            return self.p;
        }
        let mut p = self.covariance();
        let coordinates = Coordinates {
            formulation,
            ..self.cfg.coordinates()
        };
        coordinates.at(&self.nav).from_classic(&mut p);
        p
    }

    /// A matrix in the filter's error coordinates (a covariance, a discrete Q) mapped
    /// into the classic ones at the current velocity estimate.
    pub fn to_classic(&self, m: &Matrix15) -> Matrix15 {
        let mut m = *m;
        self.point().to_classic(&mut m);
        m
    }

    /// 1σ of each error state in the classic coordinates, `sqrt(diag P)`.
    /// A negative rounding residue gives 0; a NaN variance stays NaN (never "known").
    pub fn sigma(&self) -> [f64; 15] {
        classic_sigma(&self.point(), &self.p)
    }

    /// [`Ekf::sigma`] and the DVL calibration states' σ, if any.
    pub fn sigmas(&self) -> ClosedSigma {
        (
            self.sigma(),
            self.calibration.as_ref().map(Calibration::sigma),
        )
    }

    /// Whether the navigation solution, the bias estimates and the variances are all
    /// finite. A non-finite P reaches its diagonal within a step, so the diagonal is
    /// enough.
    pub fn is_finite(&self) -> bool {
        self.solution_is_finite() && self.covariance_is_finite()
    }

    /// The navigation solution and the bias estimates of [`Ekf::is_finite`].
    fn solution_is_finite(&self) -> bool {
        // `0·x` is ±0 for a finite x and NaN for ±∞ and NaN, so the sum is NaN exactly
        // when a value is not finite: one branch-free pass over the 21 values.
        let nav = &self.nav;
        let values = nav.lla.iter().chain(&nav.vel).chain(&nav.dcm);
        let sum: f64 = values
            .chain(&self.accel_bias)
            .chain(&self.gyro_bias)
            .map(|x| x * 0.0)
            .sum();
        !sum.is_nan()
    }

    /// The variances (and the calibration states) of [`Ekf::is_finite`].
    fn covariance_is_finite(&self) -> bool {
        (0..15).all(|i| self.p[(i, i)].is_finite())
            && self.calibration.as_ref().is_none_or(Calibration::is_finite)
    }

    /// Propagate over one raw IMU sample (`dt` \[s\]): covariance with F and Q_d from
    /// the state at the start of the step (or the sample added to the covariance step
    /// under way, closed when due), then the strapdown step with the bias-corrected
    /// sample. A non-finite result (an overflow from absurd inputs or a diverged filter)
    /// is an `Error::Numerical`, never a silent NaN.
    pub fn propagate(&mut self, raw: &ImuSample, dt: f64, noise: ProcessNoise<'_>) -> Result<()> {
        self.propagate_observed(raw, dt, noise, |_, _| {})
    }

    /// [`Ekf::propagate`], calling `on_close` with the filter and the transition of a
    /// covariance step closed here, if one was (after the check: never on an error). A
    /// callback, not a returned transition: 1.4 kB in the result would be moved at
    /// every sample, closed or not (3 % of a Monte Carlo).
    #[inline]
    pub fn propagate_observed(
        &mut self,
        raw: &ImuSample,
        dt: f64,
        noise: ProcessNoise<'_>,
        on_close: impl FnOnce(&Self, &Transition),
    ) -> Result<()> {
        let imu = ImuSample {
            accel: raw.accel - self.accel_bias,
            gyro: raw.gyro - self.gyro_bias,
        };
        let rates = FrameRates::at(&self.nav);
        let every_sample = self.cfg.covariance_every_sample();
        if every_sample {
            self.propagate_covariance(&imu, &rates, dt, noise);
        } else {
            let white = self.cfg.imu_dt * dt;
            let tracked = self.sensitivity.is_some();
            self.step
                .get_or_insert_with(|| CovarianceStep::open(&self.nav, tracked))
                .add(&self.nav, &imu.accel, dt, white, noise);
            if let Some(s) = self.second_order.as_mut() {
                s.run(&self.nav.vel, dt);
            }
        }
        self.nav = step_with_rates(&self.nav, &imu, dt, &rates);
        self.last_gyro = imu.gyro;
        self.last_gyro_variance = noise.gyro_sample_variance(self.cfg.imu_dt, dt);
        self.last_dt = dt;
        // P changes at every sample, or where a covariance step closes.
        let mut covariance_changed = every_sample;
        let mut closed = None;
        if !every_sample && self.step.as_ref().is_some_and(|s| s.due(&self.cfg)) {
            closed = self.bring_up_to_date();
            covariance_changed = true;
        }
        if !self.solution_is_finite() || (covariance_changed && !self.covariance_is_finite()) {
            return Err(Error::Numerical(
                "the prediction produced a non-finite state or covariance".into(),
            ));
        }
        if let Some(phi) = closed {
            on_close(self, &phi);
        }
        Ok(())
    }

    /// The covariance part of [`Ekf::propagate`] at every IMU sample.
    fn propagate_covariance(
        &mut self,
        imu: &ImuSample,
        rates: &FrameRates,
        dt: f64,
        noise: ProcessNoise<'_>,
    ) {
        let dynamics = ErrorDynamics::new(&self.nav, rates, &imu.accel, &self.point());
        self.propagate_covariance_with(&dynamics, dt, noise);
    }

    /// The covariance part of [`Ekf::propagate`] over one raw IMU sample of `dt`
    /// seconds starting from the navigation solution `nav` (the forward pass's, which
    /// is not integrated again): the smoother's rebuild of a stretch of the forward
    /// pass, the same numbers bit for bit. Every sample: the step's error dynamics
    /// (`Φ = I + F Δt`); under a covariance step: the transition of a step closed as
    /// due.
    pub(crate) fn predict_covariance_from(
        &mut self,
        nav: &NavState,
        raw: &ImuSample,
        dt: f64,
        noise: ProcessNoise<'_>,
    ) -> (Option<ErrorDynamics>, Option<Transition>) {
        self.nav = *nav;
        let accel = raw.accel - self.accel_bias;
        if self.cfg.covariance_every_sample() {
            let rates = FrameRates::at(nav);
            let dynamics = ErrorDynamics::new(nav, &rates, &accel, &self.point());
            self.propagate_covariance_with(&dynamics, dt, noise);
            return (Some(dynamics), None);
        }
        let due = self.add_to_step(nav, raw, dt, noise);
        (None, if due { self.bring_up_to_date() } else { None })
    }

    /// [`Ekf::propagate_covariance`] with the step's error dynamics given.
    fn propagate_covariance_with(
        &mut self,
        dynamics: &ErrorDynamics,
        dt: f64,
        noise: ProcessNoise<'_>,
    ) {
        let p = &self.p;
        let heading_variance = self
            .second_order
            .as_deref()
            .map(|s| s.linear_heading_variance(p));
        dynamics.propagate_covariance(&mut self.p, dt);
        self.add_process_noise(noise, dt);
        if let (Some(s), Some(v)) = (self.second_order.as_deref_mut(), heading_variance) {
            s.step(&dynamics.apply(s.direction().as_slice()), dt);
            s.run(&self.nav.vel, dt);
            s.grow(&mut self.p, v);
        }
        if let Some(c) = self.calibration.as_mut() {
            c.propagate(dynamics, dt, true);
        }
        let at = self.point();
        if let Some((m, q)) = self.sensitivity.as_mut() {
            dynamics.propagate_covariance(m, dt);
            add_imu_noise(m, &self.nav, &at, q, self.cfg.imu_dt * dt);
            if let Some(c) = self.sensitivity_calibration.as_mut() {
                c.propagate(dynamics, dt, false);
            }
        }
    }

    fn add_process_noise(&mut self, noise: ProcessNoise<'_>, dt: f64) {
        match noise {
            ProcessNoise::Continuous {
                imu_variance: q,
                bias_psd,
            } => {
                let white = self.cfg.imu_dt * dt;
                let at = self.point();
                add_imu_noise(&mut self.p, &self.nav, &at, q, white);
                for (i, psd) in bias_psd.iter().enumerate() {
                    self.p[(ACC_BIAS + i, ACC_BIAS + i)] += psd * dt;
                }
            }
            ProcessNoise::Discrete(qd) => {
                let mut qd = (qd + qd.transpose()) * 0.5;
                self.point().from_classic(&mut qd);
                self.p += qd;
            }
        }
    }

    /// Apply an error estimate `δx̂` (estimate minus truth, in the formulation's
    /// coordinates) to the navigation solution and biases. The invariant velocity is
    /// corrected exactly, `v̂ ← Exp(ψ̂)(v̂ − δV̂)` (`δV = v̂ − Ĉ Cᵀ v` and `C = Exp(ψ) Ĉ`):
    /// to first order `v̂ − δV̂ − [v̂×]ψ̂`, but a rotation of the corrected velocity, so
    /// that a large attitude correction cannot scale the speed.
    pub(super) fn feedback(&mut self, dx: &Vector15) {
        let coordinates = self.cfg.coordinates();
        correct(
            &mut self.nav,
            &mut self.accel_bias,
            &mut self.gyro_bias,
            dx,
            &coordinates,
        );
    }
}

/// The covariance step's part of the filter: closing it, and reading P as if closed.
impl Ekf {
    /// Close the covariance step under way, if any: propagate P (and M and the
    /// calibration blocks) over the samples since it started; the closed step's
    /// transition Φ (None when no step was under way). The covariance readers
    /// ([`Ekf::covariance`], [`Ekf::sigma`], the field `p`) give the covariance at the
    /// end of the last closed step; a pass brings it up to date before an epoch's
    /// updates and at its end.
    pub fn bring_up_to_date(&mut self) -> Option<Transition> {
        let step = self.step.take()?;
        let sensitivity = self.sensitivity.as_mut().map(|(m, q)| {
            let calibration = self.sensitivity_calibration.as_mut();
            (m, &*q, calibration)
        });
        // The term grows inside the close: the 1.4 kB transition is returned, not moved.
        let p = &self.p;
        let second_order = self.second_order.as_deref_mut().map(|s| {
            let heading_variance = s.linear_heading_variance(p);
            (s, heading_variance)
        });
        step.close(Covariance {
            coordinates: self.cfg.coordinates(),
            p: &mut self.p,
            calibration: self.calibration.as_mut(),
            sensitivity,
            second_order,
        })
    }

    /// The covariance-step part of the smoother's rebuild (`Ekf::predict_covariance_from`
    /// under a covariance step): one raw IMU sample of `dt` seconds at the forward
    /// solution `nav` added to the step under way (one opened at `nav` if none); whether
    /// the step is now due ([`Ekf::bring_up_to_date`] closes it). The same operations as
    /// the forward pass's [`Ekf::propagate`], without moving its transition around.
    #[inline]
    pub fn add_to_step(
        &mut self,
        nav: &NavState,
        raw: &ImuSample,
        dt: f64,
        noise: ProcessNoise<'_>,
    ) -> bool {
        self.nav = *nav;
        let accel = raw.accel - self.accel_bias;
        let white = self.cfg.imu_dt * dt;
        let step = self
            .step
            .get_or_insert_with(|| CovarianceStep::open(nav, false));
        step.add(nav, &accel, dt, white, noise);
        if let Some(s) = self.second_order.as_mut() {
            s.run(&nav.vel, dt);
        }
        step.due(&self.cfg)
    }

    /// The covariance step under way, if any.
    pub fn step_under_way(&self) -> Option<&CovarianceStep> {
        self.step.as_ref()
    }

    /// The heading variance σ_ψD² \[rad²\] in P (the attitude error's down component):
    /// the same in every formulation's coordinates, whose maps to the classic ones
    /// leave the attitude rows alone. P's, so at an epoch inside a covariance step the
    /// step's start's.
    pub fn heading_variance(&self) -> f64 {
        self.p[(ATT + 2, ATT + 2)]
    }

    /// The horizontal position variance σ_N² + σ_E² \[m²\] in P, in the classic
    /// coordinates (SE₂(3)'s position error is mapped; the others' is the classic one).
    pub fn horizontal_variance(&self) -> f64 {
        if self.cfg.formulation.position_invariant() {
            let d = self.point().classic_variances(&self.p);
            d[POS] + d[POS + 1]
        } else {
            self.p[(POS, POS)] + self.p[(POS + 1, POS + 1)]
        }
    }

    /// Whether P stands at the current epoch (no covariance step under way).
    pub fn is_up_to_date(&self) -> bool {
        self.step.is_none()
    }

    /// [`Ekf::sigma`] brought up to date without closing the step under way (on a
    /// copy), so that reading it does not change the filter's later steps.
    pub fn sigma_up_to_date(&self) -> [f64; 15] {
        if self.step.is_none() {
            return self.sigma();
        }
        let mut copy = self.clone();
        copy.bring_up_to_date();
        copy.sigma()
    }

    /// [`Ekf::covariance`] brought up to date without closing the step under way (on
    /// a copy), as [`Ekf::sigma_up_to_date`].
    pub fn covariance_up_to_date(&self) -> Matrix15 {
        if self.step.is_none() {
            return self.covariance();
        }
        let mut copy = self.clone();
        copy.bring_up_to_date();
        copy.covariance()
    }
}

/// Remove an error estimate `δx̂` (estimate minus truth, in the coordinates
/// `coordinates`) from a navigation solution and its bias estimates: the filter's
/// feedback, and the smoother's correction of the forward solution. The invariant
/// velocity is corrected exactly, `v̂ ← Exp(ψ̂)(v̂ − δV̂)` (the filter's own feedback),
/// and in SE₂(3) the position too, `p̂ ← Exp(ψ̂)(p̂ − δP̂)` about the anchor.
pub fn correct(
    nav: &mut NavState,
    accel_bias: &mut Vector3<f64>,
    gyro_bias: &mut Vector3<f64>,
    dx: &Vector15,
    coordinates: &Coordinates,
) {
    let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
    let rotation = exp_so3(&block(ATT));
    (nav.lla, nav.vel) = corrected_position_velocity(nav, dx, coordinates, || rotation);
    nav.dcm = rotation * nav.dcm;
    *accel_bias -= block(ACC_BIAS);
    *gyro_bias -= block(GYRO_BIAS);
}

/// The position and velocity of [`correct`] alone, by the same operations (the same
/// bits), `rotation` giving `Exp(ψ̂)` where the formulation reads it (the invariant
/// ones).
pub fn corrected_position_velocity(
    nav: &NavState,
    dx: &Vector15,
    coordinates: &Coordinates,
    rotation: impl FnOnce() -> Matrix3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
    match coordinates.formulation {
        Formulation::Classic => (
            nav.lla - earth::ned_delta_to_lla_delta(&nav.lla, &block(POS)),
            nav.vel - block(VEL),
        ),
        Formulation::Invariant => (
            nav.lla - earth::ned_delta_to_lla_delta(&nav.lla, &block(POS)),
            rotation() * (nav.vel - block(VEL)),
        ),
        Formulation::Se23 => {
            let r = rotation();
            let disp = r * (coordinates.displacement(&nav.lla) - block(POS));
            (coordinates.position(&disp), r * (nav.vel - block(VEL)))
        }
    }
}
