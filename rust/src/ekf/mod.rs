//! The 15-state INS/DVL error-state EKF, closed loop.
//!
//! Error state `δx = [δp (NED m), δv (m/s), ψ (rad), δb_a (m/s²), δb_g (rad/s)]`, each
//! estimate minus truth; `Ĉ = (I − [ψ×]) C`; the velocity error in the coordinates of
//! the configured [`Formulation`] (`δv`, or `δV = δv − [v̂×]ψ`). Propagation
//! `Φ = I + FΔt`, `Q_d = Γ Q^c Γᵀ Δt` at every IMU sample, or over a covariance step
//! ([`FilterConfig::covariance_step`], `interval`); DVL updates in Joseph form with
//! feedback and reset. Every formula is in `docs/filter.md`.

use crate::attitude::{exp_so3, skew};
use crate::earth;
use crate::error::{Error, Result};
use crate::mechanization::{step_with_rates, FrameRates, ImuSample, NavState};
use crate::noise::{NoiseStrategy, ProcessNoise};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

pub type Matrix15 = SMatrix<f64, 15, 15>;
pub type Vector15 = SVector<f64, 15>;
/// Kalman gain of a 3-vector measurement.
pub type Gain = SMatrix<f64, 15, 3>;
type Rows3 = SMatrix<f64, 3, 15>;

/// Offsets of the 3-blocks of the error state.
pub const POS: usize = 0;
pub const VEL: usize = 3;
pub const ATT: usize = 6;
pub const ACC_BIAS: usize = 9;
pub const GYRO_BIAS: usize = 12;

pub mod calibration;
mod config;
mod divergence;
mod dynamics;
pub mod formulation;
mod interval;
pub mod position;
mod recorded;
mod recorded_data;
mod recorded_epochs;
mod recorded_rows;
pub mod smoother;
mod transition;

use calibration::{Calibration, N_CALIBRATED, SCALE};
pub use config::{Aiding, FilterConfig, DEFAULT_COVARIANCE_STEP};
pub use divergence::{NisMonitor, DIVERGENCE_MEAN_NIS};
use dynamics::{add_imu_noise, ErrorDynamics};
pub use formulation::Formulation;
use interval::Interval;
pub use recorded::{
    filter_recorded, filter_recorded_until, smooth_recorded_until, Epochs, FilterOutput,
    RecordedData,
};
pub use smoother::{KeptClose, KeptCloses};
use transition::Transition;

/// Result of one DVL update.
#[derive(Clone, Debug)]
pub struct UpdateInfo {
    /// `ν = z − h(x̂)` \[m/s\].
    pub innovation: Vector3<f64>,
    /// Innovation covariance `S = H P Hᵀ + R`.
    pub s: Matrix3<f64>,
    /// Normalized innovation squared `νᵀ S⁻¹ ν` (χ², 3 dof when consistent).
    pub nis: f64,
    pub gain: Gain,
    /// False when the innovation gate rejected the measurement: the state is unchanged.
    pub accepted: bool,
    /// `H M Hᵀ` with `M = ∂P⁻/∂λ` (see [`Ekf::track_sensitivity`]); None when untracked.
    pub sensitivity: Option<Matrix3<f64>>,
    /// The error estimate `δx̂ = −K ν` fed back, in the filter's own coordinates (the
    /// first 15 states); None when the gate rejected the measurement.
    pub correction: Option<Vector15>,
    /// With the DVL calibration states, their estimate `[δk̂, δμ̂]` fed back (None
    /// without them or when the gate rejected the measurement).
    pub calibration_correction: Option<[f64; 4]>,
}

/// Filter state: navigation solution, bias estimates, covariance.
#[derive(Clone, Debug)]
pub struct Ekf {
    pub nav: NavState,
    /// Accelerometer bias estimate \[m/s²\].
    pub accel_bias: Vector3<f64>,
    /// Gyro bias estimate \[rad/s\].
    pub gyro_bias: Vector3<f64>,
    /// The error covariance in the coordinates of [`FilterConfig::formulation`]
    /// ([`Ekf::covariance`] gives it in the classic ones users read).
    pub p: Matrix15,
    /// Last bias-corrected gyro sample \[rad/s\] (for the lever-arm term).
    last_gyro: Vector3<f64>,
    cfg: FilterConfig,
    /// `M = ∂P/∂λ` and the IMU variances `q` it is taken for (see
    /// [`Ekf::track_sensitivity`]).
    sensitivity: Option<(Matrix15, [f64; 6])>,
    /// The DVL calibration states, when [`FilterConfig::dvl_calibration`] asks for them.
    pub calibration: Option<Calibration>,
    /// The calibration blocks of `M` (with [`Ekf::track_sensitivity`] and calibration).
    sensitivity_calibration: Option<Calibration>,
    /// The covariance step under way (see [`FilterConfig::covariance_step`]): P, M and
    /// the calibration blocks stand at its start.
    interval: Option<Interval>,
    /// With [`Ekf::track_next_close`]: the σ (and the calibration σ) at the last close
    /// of a covariance step, before any update applied at that epoch.
    closed_sigma: Option<ClosedSigma>,
    track_closes: bool,
    /// With [`Ekf::keep_closes`]: the closes of the covariance step since the last
    /// [`Ekf::take_closes`], for the smoother.
    kept_closes: Option<Vec<KeptClose>>,
    /// With [`Ekf::keep_priors`]: whether to keep the covariance before an epoch's
    /// first update, and the one kept since the last [`Ekf::take_prior`].
    keep_prior: bool,
    prior: Option<Box<Matrix15>>,
}

/// The 1σ of the 15 states (classic coordinates) and of the DVL calibration states, if
/// any, at the close of a covariance step (see [`Ekf::take_closed_sigma`]).
pub type ClosedSigma = ([f64; 15], Option<[f64; 4]>);

/// [`Ekf::sigma`] of a covariance `p` in `formulation`'s coordinates at the velocity
/// estimate `vel` \[m/s, NED\]: the same operations, so that a σ computed later from a
/// copy of an epoch's P and velocity is the one computed there, bit for bit.
fn classic_sigma(formulation: Formulation, p: &Matrix15, vel: &Vector3<f64>) -> [f64; 15] {
    let mut p = *p;
    formulation::to_classic(formulation, &mut p, vel);
    std::array::from_fn(|i| {
        let v = p[(i, i)];
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
        let mut p = cfg.p0();
        formulation::from_classic(cfg.formulation, &mut p, &nav.vel);
        Ok(Self {
            nav,
            accel_bias,
            gyro_bias,
            p,
            last_gyro: Vector3::zeros(),
            cfg: cfg.clone(),
            sensitivity: None,
            calibration: cfg.dvl_calibration.as_ref().map(Calibration::new),
            sensitivity_calibration: None,
            interval: None,
            closed_sigma: None,
            track_closes: false,
            kept_closes: None,
            keep_prior: false,
            prior: None,
        })
    }

    /// Carry `M = ∂P/∂λ` beside P from now on: the derivative of the covariance with
    /// respect to a common scale λ on the IMU variances (the IMU part of Q^c being
    /// `λ·q·Δt_imu`). M starts at 0, is propagated as P is with the IMU noise of `q`
    /// alone, and goes through each applied update as `(I − K H) M (I − K H)ᵀ`, which is
    /// exact to first order because ∂P⁺/∂K vanishes at the Kalman gain. Each update then
    /// reports `H M Hᵀ` ([`UpdateInfo::sensitivity`]); the adaptive strategy reads it.
    pub fn track_sensitivity(&mut self, q: [f64; 6]) {
        self.bring_up_to_date();
        self.sensitivity = Some((Matrix15::zeros(), q));
        self.sensitivity_calibration = self.calibration.as_ref().map(Calibration::zeroed_like);
    }

    /// The sensitivity `M = ∂P/∂λ` carried since [`Ekf::track_sensitivity`], if any.
    pub fn sensitivity_matrix(&self) -> Option<&Matrix15> {
        self.sensitivity.as_ref().map(|(m, _)| m)
    }

    pub fn config(&self) -> &FilterConfig {
        &self.cfg
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
        formulation::from_classic(formulation, &mut p, &self.nav.vel);
        p
    }

    /// A matrix in the filter's error coordinates (a covariance, a discrete Q) mapped
    /// into the classic ones at the current velocity estimate.
    pub fn to_classic(&self, m: &Matrix15) -> Matrix15 {
        let mut m = *m;
        formulation::to_classic(self.cfg.formulation, &mut m, &self.nav.vel);
        m
    }

    /// 1σ of each error state in the classic coordinates, `sqrt(diag P)`.
    /// A negative rounding residue gives 0; a NaN variance stays NaN (never "known").
    pub fn sigma(&self) -> [f64; 15] {
        classic_sigma(self.cfg.formulation, &self.p, &self.nav.vel)
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
    /// sample. A non-finite result (an overflow from absurd inputs or a diverged
    /// filter) is an `Error::Numerical`, never a silent NaN.
    pub fn propagate(&mut self, raw: &ImuSample, dt: f64, noise: ProcessNoise<'_>) -> Result<()> {
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
            self.interval
                .get_or_insert_with(|| Interval::open(&self.nav, tracked))
                .add(&self.nav, &imu.accel, dt, white, noise);
        }
        self.nav = step_with_rates(&self.nav, &imu, dt, &rates);
        self.last_gyro = imu.gyro;
        // P changes at every sample, or where a covariance step closes.
        let mut covariance_changed = every_sample;
        if !every_sample && self.interval.as_ref().is_some_and(|i| i.due(&self.cfg)) {
            self.bring_up_to_date();
            covariance_changed = true;
        }
        if !self.solution_is_finite() || (covariance_changed && !self.covariance_is_finite()) {
            return Err(Error::Numerical(
                "the prediction produced a non-finite state or covariance".into(),
            ));
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
        let formulation = self.cfg.formulation;
        let dynamics = ErrorDynamics::new(&self.nav, rates, &imu.accel, formulation);
        self.propagate_covariance_with(&dynamics, dt, noise);
    }

    /// The covariance part of [`Ekf::propagate`] over one raw IMU sample of `dt`
    /// seconds starting from the navigation solution `nav` (the forward pass's, which
    /// is not integrated again): the smoother's rebuild of a stretch of the forward
    /// pass, the same numbers bit for bit. Every sample: the step's error dynamics
    /// (`Φ = I + F Δt`); under a covariance step: the transition of a step closed as
    /// due.
    fn predict_covariance_from(
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
            let formulation = self.cfg.formulation;
            let dynamics = ErrorDynamics::new(nav, &rates, &accel, formulation);
            self.propagate_covariance_with(&dynamics, dt, noise);
            return (Some(dynamics), None);
        }
        let due = self.add_to_step(nav, raw, dt, noise);
        (None, if due { self.close_interval() } else { None })
    }

    /// [`Ekf::propagate_covariance`] with the step's error dynamics given.
    fn propagate_covariance_with(
        &mut self,
        dynamics: &ErrorDynamics,
        dt: f64,
        noise: ProcessNoise<'_>,
    ) {
        let formulation = self.cfg.formulation;
        dynamics.propagate_covariance(&mut self.p, dt);
        self.add_process_noise(noise, dt);
        if let Some(c) = self.calibration.as_mut() {
            c.propagate(dynamics, dt, true);
        }
        if let Some((m, q)) = self.sensitivity.as_mut() {
            dynamics.propagate_covariance(m, dt);
            add_imu_noise(m, &self.nav, formulation, q, self.cfg.imu_dt * dt);
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
                add_imu_noise(&mut self.p, &self.nav, self.cfg.formulation, q, white);
                for (i, psd) in bias_psd.iter().enumerate() {
                    self.p[(ACC_BIAS + i, ACC_BIAS + i)] += psd * dt;
                }
            }
            ProcessNoise::Discrete(qd) => {
                let mut qd = (qd + qd.transpose()) * 0.5;
                formulation::from_classic(self.cfg.formulation, &mut qd, &self.nav.vel);
                self.p += qd;
            }
        }
    }

    /// Predicted measurement and its Jacobian for the configured aiding, in the
    /// formulation's coordinates: body aiding reads `δV` alone (`H_ψ = 0`) in the
    /// invariant one, NED aiding gains `H_ψ = [v̂×]` there.
    fn measurement_model(&self) -> (Vector3<f64>, Rows3) {
        let mut h = Rows3::zeros();
        let invariant = self.cfg.formulation == Formulation::Invariant;
        match self.cfg.aiding {
            Aiding::Body => {
                let ct = self.nav.dcm.transpose();
                let r = self.cfg.lever_arm;
                h.fixed_view_mut::<3, 3>(0, VEL).copy_from(&ct);
                if !invariant {
                    h.fixed_view_mut::<3, 3>(0, ATT)
                        .copy_from(&(-ct * skew(&self.nav.vel)));
                }
                h.fixed_view_mut::<3, 3>(0, GYRO_BIAS).copy_from(&skew(&r));
                (ct * self.nav.vel + self.last_gyro.cross(&r), h)
            }
            Aiding::Nav => {
                h.fixed_view_mut::<3, 3>(0, VEL)
                    .copy_from(&Matrix3::identity());
                if invariant {
                    h.fixed_view_mut::<3, 3>(0, ATT)
                        .copy_from(&skew(&self.nav.vel));
                }
                (self.nav.vel, h)
            }
        }
    }

    /// DVL update with measurement `z` \[m/s\] (body or NED per the aiding), Joseph form,
    /// then feedback of the error estimate and reset. With the DVL calibration states
    /// the update runs on the 19-state covariance (see [`calibration`]).
    pub fn update(&mut self, z: &Vector3<f64>) -> Result<UpdateInfo> {
        self.bring_up_to_date();
        self.note_prior();
        let r = Matrix3::from_diagonal(&Vector3::from_column_slice(&self.cfg.dvl_variance));
        let gate = self.cfg.innovation_gate;
        let (predicted, h) = self.measurement_model();
        let (info, dx) = match self.calibration.as_mut() {
            None => {
                let m = self.sensitivity.as_mut().map(|(m, _)| m);
                let out = kalman_update(&mut self.p, m, &h, &(z - predicted), &r, gate)?;
                (out.info, out.dx.map(|d| (d, None)))
            }
            Some(calibration) => {
                let (predicted, h) = calibration.measurement(&predicted, &h);
                let mut p = calibration.assemble(&self.p);
                let sensitivity = self.sensitivity.as_mut().map(|(m, _)| m);
                let mut m = match (&sensitivity, self.sensitivity_calibration.as_ref()) {
                    (Some(m15), Some(c)) => Some(c.assemble(m15)),
                    _ => None,
                };
                let out = kalman_update(&mut p, m.as_mut(), &h, &(z - predicted), &r, gate)?;
                calibration.split(&p, &mut self.p);
                if let (Some(full), Some(m15), Some(c)) = (
                    m.as_ref(),
                    sensitivity,
                    self.sensitivity_calibration.as_mut(),
                ) {
                    c.split(full, m15);
                }
                let dx = out.dx.map(|d: SVector<f64, N_CALIBRATED>| {
                    let nav: Vector15 = d.fixed_rows::<15>(0).into_owned();
                    (
                        nav,
                        Some([d[SCALE], d[SCALE + 1], d[SCALE + 2], d[SCALE + 3]]),
                    )
                });
                (out.info, dx)
            }
        };
        let mut info = info;
        formulation::gain_to_classic(self.cfg.formulation, &mut info.gain, &self.nav.vel);
        if let Some((dx, cal)) = dx {
            info.correction = Some(dx);
            info.calibration_correction = cal;
            self.feedback(&dx);
            if let (Some(c), Some(cal)) = (self.calibration.as_mut(), cal) {
                c.feedback(&cal);
            }
            let calibration_finite = self.calibration.as_ref().is_none_or(Calibration::is_finite);
            if !self.p[(0, 0)].is_finite() || !calibration_finite {
                return Err(Error::Numerical(
                    "the update produced a non-finite state".into(),
                ));
            }
        }
        Ok(info)
    }

    /// Apply an error estimate `δx̂` (estimate minus truth, in the formulation's
    /// coordinates) to the navigation solution and biases. The invariant velocity is
    /// corrected exactly, `v̂ ← Exp(ψ̂)(v̂ − δV̂)` (`δV = v̂ − Ĉ Cᵀ v` and `C = Exp(ψ) Ĉ`):
    /// to first order `v̂ − δV̂ − [v̂×]ψ̂`, but a rotation of the corrected velocity, so
    /// that a large attitude correction cannot scale the speed.
    fn feedback(&mut self, dx: &Vector15) {
        let formulation = self.cfg.formulation;
        correct(
            &mut self.nav,
            &mut self.accel_bias,
            &mut self.gyro_bias,
            dx,
            formulation,
        );
    }

    /// Run the filter with a noise strategy over one IMU sample and an optional
    /// measurement at the end of it; the strategy sees every applied update.
    pub fn step(
        &mut self,
        raw: &ImuSample,
        dt: f64,
        strategy: &mut dyn NoiseStrategy,
        measurement: Option<&Vector3<f64>>,
        steps_since_update: usize,
    ) -> Result<Option<UpdateInfo>> {
        self.propagate(raw, dt, strategy.process_noise())?;
        match measurement {
            None => Ok(None),
            Some(z) => {
                let info = self.update(z)?;
                if info.accepted {
                    strategy.after_update(&info, steps_since_update);
                }
                Ok(Some(info))
            }
        }
    }
}

/// Remove an error estimate `δx̂` (estimate minus truth, in the coordinates of
/// `formulation`) from a navigation solution and its bias estimates: the filter's
/// feedback, and the smoother's correction of the forward solution. The invariant
/// velocity is corrected exactly, `v̂ ← Exp(ψ̂)(v̂ − δV̂)` (see [`Ekf::update`]).
pub fn correct(
    nav: &mut NavState,
    accel_bias: &mut Vector3<f64>,
    gyro_bias: &mut Vector3<f64>,
    dx: &Vector15,
    formulation: Formulation,
) {
    let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
    let rotation = exp_so3(&block(ATT));
    (nav.lla, nav.vel) = corrected_position_velocity(nav, dx, formulation, || rotation);
    nav.dcm = rotation * nav.dcm;
    *accel_bias -= block(ACC_BIAS);
    *gyro_bias -= block(GYRO_BIAS);
}

/// The position and velocity of [`correct`] alone, by the same operations (the same
/// bits), `rotation` giving `Exp(ψ̂)` where the formulation reads it (the invariant).
pub fn corrected_position_velocity(
    nav: &NavState,
    dx: &Vector15,
    formulation: Formulation,
    rotation: impl FnOnce() -> Matrix3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
    let lla = nav.lla - earth::ned_delta_to_lla_delta(&nav.lla, &block(POS));
    let vel = match formulation {
        Formulation::Classic => nav.vel - block(VEL),
        Formulation::Invariant => rotation() * (nav.vel - block(VEL)),
    };
    (lla, vel)
}

/// What [`kalman_update`] did: the update's report (its gain the first 15 rows) and
/// the error estimate `δx̂ = −K ν` to feed back, None when the gate rejected it.
struct Outcome<const N: usize> {
    info: UpdateInfo,
    dx: Option<SVector<f64, N>>,
}

/// The EKF update of an `N`-state covariance `p` (and of the sensitivity `m`, if
/// tracked) by a 3-vector measurement with Jacobian `h`, innovation `ν` and noise `r`:
/// `S = H P Hᵀ + R`, `K = P Hᵀ S⁻¹`, NIS `νᵀ S⁻¹ ν`; unless the gate rejects it,
/// `P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ` symmetrized and `M ← (I − K H) M (I − K H)ᵀ`.
/// For the 15 states and the 19 with the DVL calibration (N ≥ 15: the report's gain
/// is the first 15 rows).
fn kalman_update<const N: usize>(
    p: &mut SMatrix<f64, N, N>,
    m: Option<&mut SMatrix<f64, N, N>>,
    h: &SMatrix<f64, 3, N>,
    innovation: &Vector3<f64>,
    r: &Matrix3<f64>,
    gate: Option<f64>,
) -> Result<Outcome<N>> {
    let pht = *p * h.transpose();
    let s = h * pht + r;
    let s_inv = s
        .cholesky()
        .ok_or_else(|| Error::Numerical("innovation covariance S is not positive definite".into()))?
        .inverse();
    let gain: SMatrix<f64, N, 3> = pht * s_inv;
    let sensitivity = m.as_ref().map(|m| h * **m * h.transpose());
    let nis = innovation.dot(&(s_inv * innovation));
    // Checked before anything is applied: a NaN would slip past the gate's `>`.
    if !nis.is_finite() {
        return Err(Error::Numerical(format!(
            "the DVL update has a non-finite NIS ({nis})"
        )));
    }
    let accepted = gate.is_none_or(|gate| nis <= gate);
    let report = UpdateInfo {
        innovation: *innovation,
        s,
        nis,
        gain: gain.fixed_rows::<15>(0).into_owned(),
        accepted,
        sensitivity,
        correction: None,
        calibration_correction: None,
    };
    if !accepted {
        return Ok(Outcome {
            info: report,
            dx: None,
        });
    }
    let ikh = SMatrix::<f64, N, N>::identity() - gain * h;
    *p = ikh * *p * ikh.transpose() + gain * r * gain.transpose();
    *p = (*p + p.transpose()) * 0.5;
    if let Some(m) = m {
        *m = ikh * *m * ikh.transpose();
        *m = (*m + m.transpose()) * 0.5;
    }
    Ok(Outcome {
        info: report,
        dx: Some(-(gain * innovation)),
    })
}

#[cfg(test)]
pub(crate) mod tests;
