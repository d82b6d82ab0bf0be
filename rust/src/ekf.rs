//! The 15-state INS/DVL error-state EKF, closed loop.
//!
//! Error state `δx = [δp (NED m), δv (m/s), ψ (rad), δb_a (m/s²), δb_g (rad/s)]`, each
//! estimate minus truth; `Ĉ = (I − [ψ×]) C`. Propagation `Φ = I + FΔt`,
//! `Q_d = Γ Q^c Γᵀ Δt`; DVL updates in Joseph form with feedback and reset. Every
//! formula is in `docs/filter.md`.

use crate::attitude::{exp_so3, skew};
use crate::earth;
use crate::error::{check, Error, Result};
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

/// What the DVL measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aiding {
    /// Body-frame velocity at the DVL, `Ĉᵀ v̂ + ω̂ × r` (a real DVL).
    Body,
    /// NED velocity `v̂` (a DVL already rotated by an external attitude source).
    Nav,
}

/// Filter tuning that does not change while it runs.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    /// Initial 1σ of the 15 error states (units as the state).
    pub p0_sigma: [f64; 15],
    /// Accelerometer-bias random-walk PSD ε_a [(m/s²)²/s] (paper: 0.001).
    pub accel_bias_psd: f64,
    /// Gyro-bias random-walk PSD ε_g [(rad/s)²/s] (paper: 0.001).
    pub gyro_bias_psd: f64,
    /// DVL noise variance per axis [(m/s)²] (R).
    pub dvl_variance: [f64; 3],
    /// DVL lever arm in the body frame [m].
    pub lever_arm: Vector3<f64>,
    pub aiding: Aiding,
    /// Nominal IMU period [s]: the white-noise PSD is q·imu_dt.
    pub imu_dt: f64,
    /// Chi-square innovation gate: a DVL update whose NIS exceeds this is rejected (not
    /// applied, and unseen by the noise strategy). With 3 dof, 16.27 rejects 0.1 % of
    /// consistent updates. `None` (the default, as in the paper's table) applies all.
    pub innovation_gate: Option<f64>,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            p0_sigma: DEFAULT_P0_SIGMA,
            accel_bias_psd: 1e-3,
            gyro_bias_psd: 1e-3,
            dvl_variance: [0.01; 3],
            lever_arm: Vector3::zeros(),
            aiding: Aiding::Body,
            imu_dt: 0.01,
            innovation_gate: None,
        }
    }
}

/// Default initial 1σ: position 1 m, velocity 0.1 m/s, roll/pitch 1 mrad, yaw 5 mrad,
/// accelerometer bias 1e-3 m/s², gyro bias 1e-4 rad/s.
pub const DEFAULT_P0_SIGMA: [f64; 15] = [
    1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4,
];

impl FilterConfig {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("p0_sigma", &self.p0_sigma)?;
        check::non_negative("accel_bias_psd", &[self.accel_bias_psd])?;
        check::non_negative("gyro_bias_psd", &[self.gyro_bias_psd])?;
        check::finite("dvl_variance", &self.dvl_variance)?;
        if self.dvl_variance.iter().any(|v| *v <= 0.0) {
            return Err(Error::invalid(
                "dvl_variance",
                format!("must be > 0 on every axis, got {:?}", self.dvl_variance),
            ));
        }
        check::finite("lever_arm", self.lever_arm.as_slice())?;
        check::positive("imu_dt", self.imu_dt)?;
        if let Some(gate) = self.innovation_gate {
            check::positive("innovation_gate", gate)?;
        }
        Ok(())
    }

    /// `diag(p0_sigma²)`.
    pub fn p0(&self) -> Matrix15 {
        Matrix15::from_diagonal(&Vector15::from_iterator(
            self.p0_sigma.iter().map(|s| s * s),
        ))
    }

    /// Bias random-walk PSDs per channel `[ε_a ×3, ε_g ×3]`.
    pub fn bias_psd(&self) -> [f64; 6] {
        let (a, g) = (self.accel_bias_psd, self.gyro_bias_psd);
        [a, a, a, g, g, g]
    }
}

/// Result of one DVL update.
#[derive(Clone, Debug)]
pub struct UpdateInfo {
    /// `ν = z − h(x̂)` [m/s].
    pub innovation: Vector3<f64>,
    /// Innovation covariance `S = H P Hᵀ + R`.
    pub s: Matrix3<f64>,
    /// Normalized innovation squared `νᵀ S⁻¹ ν` (χ², 3 dof when consistent).
    pub nis: f64,
    pub gain: Gain,
    /// False when the innovation gate rejected the measurement: the state is unchanged.
    pub accepted: bool,
}

/// Mean NIS over the last [`NisMonitor::WINDOW`] updates above which the filter is
/// declared diverged: about 8× the consistent mean of 3, i.e. innovations some 3× larger
/// than the filter's own prediction of them, sustained for 20 updates. (For a consistent
/// filter the 20-update sum is χ² with 60 dof; exceeding 500 has probability < 1e-60.)
pub const DIVERGENCE_MEAN_NIS: f64 = 25.0;

/// Watches the NIS of every update, accepted or rejected by the gate, and remembers the
/// first time its windowed mean exceeds [`DIVERGENCE_MEAN_NIS`].
#[derive(Clone, Debug, Default)]
pub struct NisMonitor {
    recent: [f64; NisMonitor::WINDOW],
    count: usize,
    /// Time [s] at which divergence was first detected.
    pub diverged_at: Option<f64>,
}

impl NisMonitor {
    pub const WINDOW: usize = 20;

    /// Record the NIS of an update at time `t` [s].
    pub fn push(&mut self, nis: f64, t: f64) {
        self.recent[self.count % Self::WINDOW] = nis;
        self.count += 1;
        if self.count >= Self::WINDOW && self.diverged_at.is_none() {
            // Summed afresh, not kept running: one huge NIS must not leave rounding
            // debris behind. A NaN NIS counts as divergence.
            let mean = self.recent.iter().sum::<f64>() / Self::WINDOW as f64;
            if mean.is_nan() || mean > DIVERGENCE_MEAN_NIS {
                self.diverged_at = Some(t);
            }
        }
    }
}

/// The nonzero blocks of the error dynamics F (see `docs/filter.md`).
struct ErrorDynamics {
    pos_pos: Matrix3<f64>,
    vel_pos: Vector3<f64>,
    vel_vel: Matrix3<f64>,
    vel_att: Matrix3<f64>,
    vel_abias: Matrix3<f64>,
    att_att: Matrix3<f64>,
    att_gbias: Matrix3<f64>,
}

impl ErrorDynamics {
    fn new(nav: &NavState, rates: &FrameRates, f_body: &Vector3<f64>) -> Self {
        let radius = (rates.latitude.r_n * rates.latitude.r_e).sqrt() + nav.lla[2];
        let schuler = rates.gravity[2] / radius;
        let c = nav.dcm;
        Self {
            pos_pos: -skew(&rates.transport),
            vel_pos: Vector3::new(-schuler, -schuler, 2.0 * schuler),
            vel_vel: -skew(&(2.0 * rates.earth + rates.transport)),
            vel_att: skew(&(c * f_body)),
            vel_abias: -c,
            att_att: -skew(&rates.nav_rate()),
            att_gbias: c,
        }
    }

    /// Rows 0..9 of `F x` for a 15-vector `x` (the bias rows of F are zero): about 60
    /// multiply-adds instead of 225.
    #[inline(always)]
    fn apply(&self, x: &[f64]) -> [f64; 9] {
        #[inline(always)]
        fn mv(a: &Matrix3<f64>, x: &[f64]) -> [f64; 3] {
            let a = a.as_slice(); // column-major
            [
                a[0] * x[0] + a[3] * x[1] + a[6] * x[2],
                a[1] * x[0] + a[4] * x[1] + a[7] * x[2],
                a[2] * x[0] + a[5] * x[1] + a[8] * x[2],
            ]
        }
        let (xp, xv, xa) = (&x[POS..POS + 3], &x[VEL..VEL + 3], &x[ATT..ATT + 3]);
        let (xba, xbg) = (&x[ACC_BIAS..ACC_BIAS + 3], &x[GYRO_BIAS..GYRO_BIAS + 3]);
        let pp = mv(&self.pos_pos, xp);
        let (vv, va, vb) = (
            mv(&self.vel_vel, xv),
            mv(&self.vel_att, xa),
            mv(&self.vel_abias, xba),
        );
        let (aa, ab) = (mv(&self.att_att, xa), mv(&self.att_gbias, xbg));
        let mut o = [0.0; 9];
        for r in 0..3 {
            o[POS + r] = pp[r] + xv[r];
            o[VEL + r] = self.vel_pos[r] * xp[r] + vv[r] + va[r] + vb[r];
            o[ATT + r] = aa[r] + ab[r];
        }
        o
    }

    /// `P ← Φ P Φᵀ` with `Φ = I + F Δt`, using that P is symmetric and that the bias
    /// rows of F are zero: `Φ P Φᵀ = P + Δt (A + Aᵀ) + Δt² F Aᵀ` with `A = F P`, whose
    /// rows 9..15 vanish, so `F Aᵀ` is needed on its 9×9 navigation block only and the
    /// bias-bias block of P is unchanged. The result is written symmetrized.
    fn propagate_covariance(&self, p: &mut Matrix15, dt: f64) {
        const NAV: usize = 9;
        // a[j][i] = (F P)[i, j], one column of F P per column of P (column-major).
        let mut a = [[0.0; NAV]; 15];
        for (col, x) in a.iter_mut().zip(p.as_slice().chunks_exact(15)) {
            *col = self.apply(x);
        }
        // b[j][i] = (F Aᵀ)[i, j]; column j of Aᵀ is row j of A.
        let mut b = [[0.0; NAV]; NAV];
        for (j, col) in b.iter_mut().enumerate() {
            let row_j: [f64; 15] = std::array::from_fn(|c| a[c][j]);
            *col = self.apply(&row_j);
        }
        let half_dt2 = 0.5 * (dt * dt);
        for j in 0..15 {
            for i in 0..=j.min(NAV - 1) {
                let v = if j < NAV {
                    p[(i, j)] + dt * (a[j][i] + a[i][j]) + half_dt2 * (b[j][i] + b[i][j])
                } else {
                    p[(i, j)] + dt * a[j][i]
                };
                p[(i, j)] = v;
                p[(j, i)] = v;
            }
        }
    }
}

/// Filter state: navigation solution, bias estimates, covariance.
#[derive(Clone, Debug)]
pub struct Ekf {
    pub nav: NavState,
    /// Accelerometer bias estimate [m/s²].
    pub accel_bias: Vector3<f64>,
    /// Gyro bias estimate [rad/s].
    pub gyro_bias: Vector3<f64>,
    pub p: Matrix15,
    /// Last bias-corrected gyro sample [rad/s] (for the lever-arm term).
    last_gyro: Vector3<f64>,
    cfg: FilterConfig,
}

impl Ekf {
    pub fn new(
        cfg: &FilterConfig,
        nav: NavState,
        accel_bias: Vector3<f64>,
        gyro_bias: Vector3<f64>,
    ) -> Result<Self> {
        cfg.validate()?;
        Ok(Self {
            nav,
            accel_bias,
            gyro_bias,
            p: cfg.p0(),
            last_gyro: Vector3::zeros(),
            cfg: cfg.clone(),
        })
    }

    pub fn config(&self) -> &FilterConfig {
        &self.cfg
    }

    /// 1σ of each error state, `sqrt(diag P)`.
    /// A negative rounding residue gives 0; a NaN variance stays NaN (never "known").
    pub fn sigma(&self) -> [f64; 15] {
        std::array::from_fn(|i| {
            let v = self.p[(i, i)];
            if v < 0.0 {
                0.0
            } else {
                v.sqrt()
            }
        })
    }

    /// Whether the navigation solution, the bias estimates and the variances are all
    /// finite. A non-finite P reaches its diagonal within a step, so the diagonal is
    /// enough.
    pub fn is_finite(&self) -> bool {
        let nav = &self.nav;
        nav.lla.iter().all(|x| x.is_finite())
            && nav.vel.iter().all(|x| x.is_finite())
            && nav.dcm.iter().all(|x| x.is_finite())
            && self.accel_bias.iter().all(|x| x.is_finite())
            && self.gyro_bias.iter().all(|x| x.is_finite())
            && (0..15).all(|i| self.p[(i, i)].is_finite())
    }

    /// Propagate over one raw IMU sample (`dt` [s]): covariance with F and Q_d from
    /// the state at the start of the step, then the strapdown step with the
    /// bias-corrected sample. A non-finite result (an overflow from absurd inputs or a
    /// diverged filter) is an `Error::Numerical`, never a silent NaN.
    pub fn propagate(&mut self, raw: &ImuSample, dt: f64, noise: ProcessNoise<'_>) -> Result<()> {
        let imu = ImuSample {
            accel: raw.accel - self.accel_bias,
            gyro: raw.gyro - self.gyro_bias,
        };
        let rates = FrameRates::at(&self.nav);
        let dynamics = ErrorDynamics::new(&self.nav, &rates, &imu.accel);
        dynamics.propagate_covariance(&mut self.p, dt);
        self.add_process_noise(noise, dt);
        self.nav = step_with_rates(&self.nav, &imu, dt, &rates);
        self.last_gyro = imu.gyro;
        if !self.is_finite() {
            return Err(Error::Numerical(
                "the prediction produced a non-finite state or covariance".into(),
            ));
        }
        Ok(())
    }

    fn add_process_noise(&mut self, noise: ProcessNoise<'_>, dt: f64) {
        match noise {
            ProcessNoise::Continuous {
                imu_variance: q,
                bias_psd,
            } => {
                let c = self.nav.dcm;
                let white = self.cfg.imu_dt * dt;
                let qa =
                    c * Matrix3::from_diagonal(&Vector3::new(q[0], q[1], q[2])) * c.transpose();
                let qg =
                    c * Matrix3::from_diagonal(&Vector3::new(q[3], q[4], q[5])) * c.transpose();
                // Added symmetrized, so that P stays exactly symmetric.
                let mut blk = |at: usize, m: Matrix3<f64>| {
                    let mut view = self.p.fixed_view_mut::<3, 3>(at, at);
                    view += (m + m.transpose()) * 0.5;
                };
                blk(VEL, qa * white);
                blk(ATT, qg * white);
                for (i, psd) in bias_psd.iter().enumerate() {
                    self.p[(ACC_BIAS + i, ACC_BIAS + i)] += psd * dt;
                }
            }
            ProcessNoise::Discrete(qd) => self.p += (qd + qd.transpose()) * 0.5,
        }
    }

    /// Predicted measurement and its Jacobian for the configured aiding.
    fn measurement_model(&self) -> (Vector3<f64>, Rows3) {
        let mut h = Rows3::zeros();
        match self.cfg.aiding {
            Aiding::Body => {
                let ct = self.nav.dcm.transpose();
                let r = self.cfg.lever_arm;
                h.fixed_view_mut::<3, 3>(0, VEL).copy_from(&ct);
                h.fixed_view_mut::<3, 3>(0, ATT)
                    .copy_from(&(-ct * skew(&self.nav.vel)));
                h.fixed_view_mut::<3, 3>(0, GYRO_BIAS).copy_from(&skew(&r));
                (ct * self.nav.vel + self.last_gyro.cross(&r), h)
            }
            Aiding::Nav => {
                h.fixed_view_mut::<3, 3>(0, VEL)
                    .copy_from(&Matrix3::identity());
                (self.nav.vel, h)
            }
        }
    }

    /// DVL update with measurement `z` [m/s] (body or NED per the aiding), Joseph form,
    /// then feedback of the error estimate and reset.
    pub fn update(&mut self, z: &Vector3<f64>) -> Result<UpdateInfo> {
        let (predicted, h) = self.measurement_model();
        let innovation = z - predicted;
        let r = Matrix3::from_diagonal(&Vector3::from_column_slice(&self.cfg.dvl_variance));
        let pht = self.p * h.transpose();
        let s = h * pht + r;
        let s_inv = s
            .cholesky()
            .ok_or_else(|| {
                Error::Numerical("innovation covariance S is not positive definite".into())
            })?
            .inverse();
        let gain: Gain = pht * s_inv;
        let nis = innovation.dot(&(s_inv * innovation));
        // Checked before anything is applied: a NaN would slip past the gate's `>`.
        if !nis.is_finite() {
            return Err(Error::Numerical(format!(
                "the DVL update has a non-finite NIS ({nis})"
            )));
        }
        if self.cfg.innovation_gate.is_some_and(|gate| nis > gate) {
            return Ok(UpdateInfo {
                innovation,
                s,
                nis,
                gain,
                accepted: false,
            });
        }
        let ikh = Matrix15::identity() - gain * h;
        self.p = ikh * self.p * ikh.transpose() + gain * r * gain.transpose();
        self.p = (self.p + self.p.transpose()) * 0.5;
        let dx: Vector15 = -(gain * innovation);
        self.feedback(&dx);
        if !nis.is_finite() || !self.p[(0, 0)].is_finite() {
            return Err(Error::Numerical(
                "the update produced a non-finite state".into(),
            ));
        }
        Ok(UpdateInfo {
            innovation,
            s,
            nis,
            gain,
            accepted: true,
        })
    }

    /// Apply an error estimate `δx̂` (estimate minus truth) to the navigation solution
    /// and biases.
    fn feedback(&mut self, dx: &Vector15) {
        let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
        let dp = block(POS);
        self.nav.lla -= earth::ned_delta_to_lla_delta(&self.nav.lla, &dp);
        self.nav.vel -= block(VEL);
        self.nav.dcm = exp_so3(&block(ATT)) * self.nav.dcm;
        self.accel_bias -= block(ACC_BIAS);
        self.gyro_bias -= block(GYRO_BIAS);
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

/// Output of [`filter_recorded`]: the estimate after every IMU epoch and the updates.
#[derive(Clone, Debug, Default)]
pub struct FilterOutput {
    /// Epoch times [s]: `t0` then every IMU sample time.
    pub time: Vec<f64>,
    pub nav: Vec<NavState>,
    /// `[b_a, b_g]` estimates per epoch.
    pub bias: Vec<[f64; 6]>,
    pub sigma: Vec<[f64; 15]>,
    /// For each DVL row: the epoch index it was applied at (None if outside the run).
    pub dvl_epoch: Vec<Option<usize>>,
    pub updates: Vec<Option<UpdateInfo>>,
    /// For each DVL row: the per-IMU-step Q_d the strategy set after that update, where
    /// it sets one directly (Mehra).
    pub adaptive_q: Vec<Option<Matrix15>>,
    /// Covariance at the last epoch.
    pub final_covariance: Matrix15,
    /// Divergence watch over every update's NIS.
    pub nis_monitor: NisMonitor,
}

/// Inputs of one filter pass over recorded (or user-simulated) sensor arrays.
pub struct RecordedData<'a> {
    /// IMU samples; row k covers `(imu_time[k-1], imu_time[k]]`, `imu_time[-1] = t0`.
    pub imu: &'a [[f64; 6]],
    /// End time of every IMU sample [s], strictly increasing, after `t0`.
    pub imu_time: &'a [f64],
    /// DVL rows (body or NED velocity per the aiding) [m/s].
    pub dvl: &'a [[f64; 3]],
    /// DVL times [s], strictly increasing.
    pub dvl_time: &'a [f64],
    /// Time of the initial state [s].
    pub t0: f64,
    /// Start times [s] of a per-sample IMU variance schedule for an external strategy
    /// (the ProNet loop on recorded data); empty for none. Strictly increasing.
    pub q_time: &'a [f64],
    /// The schedule's IMU variances, one row per `q_time` [(m/s²)², (rad/s)²].
    pub q_values: &'a [[f64; 6]],
}

impl RecordedData<'_> {
    pub fn validate(&self) -> Result<()> {
        if self.imu.is_empty() {
            return Err(Error::invalid("imu", "needs at least one sample"));
        }
        if self.imu.len() != self.imu_time.len() {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "has {} rows but imu has {}",
                    self.imu_time.len(),
                    self.imu.len()
                ),
            ));
        }
        if self.dvl.len() != self.dvl_time.len() {
            return Err(Error::invalid(
                "dvl_time",
                format!(
                    "has {} rows but dvl has {}",
                    self.dvl_time.len(),
                    self.dvl.len()
                ),
            ));
        }
        for (i, row) in self.imu.iter().enumerate() {
            check::finite("imu", row)
                .map_err(|_| Error::invalid("imu", format!("row {i} is not finite: {row:?}")))?;
        }
        for (i, row) in self.dvl.iter().enumerate() {
            check::finite("dvl", row)
                .map_err(|_| Error::invalid("dvl", format!("row {i} is not finite: {row:?}")))?;
        }
        check::finite("t0", &[self.t0])?;
        check::increasing("imu_time", self.imu_time)?;
        check::increasing("dvl_time", self.dvl_time)?;
        if self.q_time.len() != self.q_values.len() {
            return Err(Error::invalid(
                "q_time",
                format!(
                    "has {} rows but q has {}",
                    self.q_time.len(),
                    self.q_values.len()
                ),
            ));
        }
        check::increasing("q_time", self.q_time)?;
        for (i, row) in self.q_values.iter().enumerate() {
            check::non_negative("q", row).map_err(|_| {
                Error::invalid(
                    "q",
                    format!("row {i} must be finite and >= 0 (variances), got {row:?}"),
                )
            })?;
        }
        if self.imu_time[0] <= self.t0 {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "the first sample time {} must be after t0 = {} (a positive time step)",
                    self.imu_time[0], self.t0
                ),
            ));
        }
        Ok(())
    }
}

/// Run the filter over recorded arrays from an initial state. A DVL row is applied after
/// the IMU step that reaches the epoch nearest to its time (first epoch with
/// `t ≥ t_dvl − Δt/2`); rows outside the run are skipped and reported as `None`.
/// A q schedule row takes effect from the epoch nearest to its time on (it is set
/// before the step that starts there), so it needs a strategy that takes q from outside.
pub fn filter_recorded(
    data: &RecordedData<'_>,
    initial: NavState,
    initial_bias: [f64; 6],
    cfg: &FilterConfig,
    strategy: &mut dyn NoiseStrategy,
) -> Result<FilterOutput> {
    data.validate()?;
    if !data.q_time.is_empty() && !strategy.takes_outside_q() {
        return Err(Error::invalid(
            "strategy",
            "a q schedule needs an external strategy (Strategy.external)",
        ));
    }
    check::finite("initial state", initial.lla.as_slice())?;
    check::finite("initial state", initial.vel.as_slice())?;
    check::finite("initial bias", &initial_bias)?;
    let mut ekf = Ekf::new(
        cfg,
        initial,
        Vector3::new(initial_bias[0], initial_bias[1], initial_bias[2]),
        Vector3::new(initial_bias[3], initial_bias[4], initial_bias[5]),
    )?;
    let n = data.imu.len();
    let mut out = FilterOutput {
        time: Vec::with_capacity(n + 1),
        nav: Vec::with_capacity(n + 1),
        bias: Vec::with_capacity(n + 1),
        sigma: Vec::with_capacity(n + 1),
        dvl_epoch: vec![None; data.dvl.len()],
        updates: vec![None; data.dvl.len()],
        adaptive_q: vec![None; data.dvl.len()],
        final_covariance: Matrix15::zeros(),
        nis_monitor: NisMonitor::default(),
    };
    let record = |out: &mut FilterOutput, ekf: &Ekf, t: f64| {
        out.time.push(t);
        out.nav.push(ekf.nav);
        let (a, g) = (ekf.accel_bias, ekf.gyro_bias);
        out.bias.push([a[0], a[1], a[2], g[0], g[1], g[2]]);
        out.sigma.push(ekf.sigma());
    };
    record(&mut out, &ekf, data.t0);
    let mut next_dvl = 0;
    let mut t_prev = data.t0;
    let mut steps_since_update = 0;
    let mut next_q = 0;
    let mut q_in_force: Option<[f64; 6]> = None;
    for (k, (sample, &t)) in data.imu.iter().zip(data.imu_time).enumerate() {
        let dt = t - t_prev;
        // DVL rows that fell before the first epoch cannot be used.
        while next_dvl < data.dvl.len() && data.dvl_time[next_dvl] < data.t0 - 0.5 * dt {
            next_dvl += 1;
        }
        while next_q < data.q_time.len() && data.q_time[next_q] <= t_prev + 0.5 * dt {
            q_in_force = Some(data.q_values[next_q]);
            next_q += 1;
        }
        if let Some(q) = q_in_force.take() {
            strategy.set_imu_variance(&q)?;
        }
        ekf.propagate(&ImuSample::from_array(sample), dt, strategy.process_noise())
            .map_err(|e| match e {
                Error::Numerical(m) => Error::Numerical(format!("{m} (t = {t} s)")),
                other => other,
            })?;
        steps_since_update += 1;
        // Apply every DVL row whose nearest epoch is this one.
        while next_dvl < data.dvl.len() && data.dvl_time[next_dvl] <= t + 0.5 * dt {
            let z = Vector3::from_column_slice(&data.dvl[next_dvl]);
            let info = ekf.update(&z).map_err(|e| match e {
                Error::Numerical(m) => {
                    Error::Numerical(format!("{m} (DVL row {next_dvl}, t = {t} s)"))
                }
                other => other,
            })?;
            out.nis_monitor.push(info.nis, t);
            if info.accepted {
                strategy.after_update(&info, steps_since_update);
                steps_since_update = 0;
            }
            out.adaptive_q[next_dvl] = strategy.discrete_q().copied();
            out.dvl_epoch[next_dvl] = Some(k + 1);
            out.updates[next_dvl] = Some(info);
            next_dvl += 1;
        }
        record(&mut out, &ekf, t);
        t_prev = t;
    }
    out.final_covariance = ekf.p;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::dcm_from_euler;
    use crate::noise::StrategySpec;

    fn dense_f(d: &ErrorDynamics) -> Matrix15 {
        let mut f = Matrix15::zeros();
        let mut put =
            |r: usize, c: usize, m: &Matrix3<f64>| f.fixed_view_mut::<3, 3>(r, c).copy_from(m);
        put(POS, POS, &d.pos_pos);
        put(POS, VEL, &Matrix3::identity());
        put(VEL, POS, &Matrix3::from_diagonal(&d.vel_pos));
        put(VEL, VEL, &d.vel_vel);
        put(VEL, ATT, &d.vel_att);
        put(VEL, ACC_BIAS, &d.vel_abias);
        put(ATT, ATT, &d.att_att);
        put(ATT, GYRO_BIAS, &d.att_gbias);
        f
    }

    fn moving_state() -> NavState {
        NavState {
            lla: Vector3::new(0.55, 0.6, -10.0),
            vel: Vector3::new(1.0, 0.5, 0.1),
            dcm: dcm_from_euler(0.05, -0.1, 0.8),
        }
    }

    #[test]
    fn block_sparse_propagation_equals_dense_phi_p_phi_t() {
        let nav = moving_state();
        let rates = FrameRates::at(&nav);
        let d = ErrorDynamics::new(&nav, &rates, &Vector3::new(0.1, 0.2, -9.8));
        let f = dense_f(&d);
        let a = Matrix15::from_fn(|i, j| {
            ((i * 7 + j * 3) % 11) as f64 * 0.1 + if i == j { 2.0 } else { 0.0 }
        });
        let p = a * a.transpose();
        let dt = 0.01;
        let phi = Matrix15::identity() + f * dt;
        let want = phi * p * phi.transpose();
        let mut got = p;
        d.propagate_covariance(&mut got, dt);
        assert!((got - want).abs().max() < 1e-12 * want.abs().max());
        assert_eq!(got, got.transpose());
    }

    /// Numerical Jacobian of the body-velocity measurement with respect to the error
    /// state agrees with H.
    #[test]
    fn measurement_jacobian_matches_finite_differences() {
        let cfg = FilterConfig {
            lever_arm: Vector3::new(0.5, -0.3, 1.2),
            ..FilterConfig::default()
        };
        let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
        ekf.last_gyro = Vector3::new(0.01, -0.02, 0.05);
        let (h0, h) = ekf.measurement_model();
        let eps = 1e-6;
        for j in 0..15 {
            let mut e = ekf.clone();
            let mut dx = Vector15::zeros();
            dx[j] = eps;
            // feedback applies −δx: the state moves to "truth" = estimate − δx, so
            // h(estimate) − h(estimate − δx) ≈ H δx.
            e.feedback(&dx);
            e.last_gyro = ekf.last_gyro
                + if j >= GYRO_BIAS {
                    Vector3::from_fn(|i, _| if i == j - GYRO_BIAS { eps } else { 0.0 })
                } else {
                    Vector3::zeros()
                };
            let (h1, _) = e.measurement_model();
            let col = (h0 - h1) / eps;
            for i in 0..3 {
                assert!(
                    (col[i] - h[(i, j)]).abs() < 1e-5,
                    "H[{i},{j}] = {} vs numeric {}",
                    h[(i, j)],
                    col[i]
                );
            }
        }
    }

    /// Covariance stays symmetric and positive definite through propagation and updates.
    /// A body-frame DVL reading of the filter's own prediction plus `sigmas` standard
    /// deviations of its innovation on the first axis.
    fn reading(ekf: &Ekf, sigmas: f64) -> Vector3<f64> {
        let (predicted, h) = ekf.measurement_model();
        let s = h * ekf.p * h.transpose()
            + Matrix3::from_diagonal(&Vector3::from_column_slice(&ekf.cfg.dvl_variance));
        predicted + Vector3::new(sigmas * s[(0, 0)].sqrt(), 0.0, 0.0)
    }

    #[test]
    fn innovation_gate_rejects_a_ten_sigma_reading_and_leaves_the_state_alone() {
        let cfg = FilterConfig {
            innovation_gate: Some(16.27),
            ..FilterConfig::default()
        };
        let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
        let before = ekf.clone();
        let info = ekf.update(&reading(&ekf, 10.0)).unwrap();
        assert!(!info.accepted);
        // (S⁻¹)₀₀ ≥ 1/S₀₀ for an SPD S, so the NIS of a 10σ first-axis innovation is ≥ 100.
        assert!(
            info.nis >= 100.0 - 1e-9,
            "NIS of a 10σ innovation: {}",
            info.nis
        );
        assert_eq!((ekf.nav, ekf.p), (before.nav, before.p));
        // 3σ is inside the gate (NIS 9 < 16.27): applied.
        let info = ekf.update(&reading(&ekf, 3.0)).unwrap();
        assert!(info.accepted);
        assert_ne!(ekf.p, before.p);
        // Without a gate the 10σ reading is applied.
        let mut ungated = before.clone();
        ungated.cfg.innovation_gate = None;
        assert!(ungated.update(&reading(&ungated, 10.0)).unwrap().accepted);
        assert_ne!(ungated.nav.vel, before.nav.vel);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let cfg = FilterConfig {
                innovation_gate: Some(bad),
                ..FilterConfig::default()
            };
            assert!(cfg.validate().is_err(), "gate {bad} accepted");
        }
    }

    #[test]
    fn nis_monitor_flags_a_sustained_large_nis_only() {
        let mut m = NisMonitor::default();
        // A consistent filter: mean 3, with single outliers.
        for k in 0..200 {
            m.push(if k % 37 == 0 { 60.0 } else { 3.0 }, k as f64);
        }
        assert_eq!(m.diverged_at, None);
        // Innovations 4× their predicted σ (NIS ≈ 48) from t = 200 s on.
        for k in 200..260 {
            m.push(48.0, k as f64);
        }
        let t = m.diverged_at.expect("a sustained NIS of 48 is divergence");
        assert!((200.0..220.0).contains(&t), "detected at {t}");
        // The first detection is kept; a NaN NIS also counts.
        m.push(f64::NAN, 999.0);
        assert_eq!(m.diverged_at, Some(t));
        let mut m = NisMonitor::default();
        for k in 0..NisMonitor::WINDOW {
            m.push(if k == 5 { f64::NAN } else { 3.0 }, k as f64);
        }
        assert!(m.diverged_at.is_some());
    }

    #[test]
    fn covariance_stays_symmetric_positive_definite() {
        let cfg = FilterConfig::default();
        let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
        let mut strat = StrategySpec::Constant {
            q: [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6],
        }
        .build(cfg.bias_psd());
        let sample = ImuSample::from_array(&[0.0, 0.0, -9.79, 0.0, 0.0, 0.0]);
        for k in 1..=2000 {
            let z = (k % 100 == 0).then(|| Vector3::new(1.0, 0.0, 0.0));
            ekf.step(&sample, 0.01, strat.as_mut(), z.as_ref(), 100)
                .unwrap();
            assert_eq!(ekf.p, ekf.p.transpose());
        }
        let eig = ekf.p.symmetric_eigenvalues();
        assert!(eig.min() > 0.0, "min eigenvalue {}", eig.min());
    }

    #[test]
    fn recorded_data_is_validated() {
        let imu = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 3];
        let data = |imu_time: &'static [f64], t0: f64| -> Result<()> {
            RecordedData {
                imu: &imu[..imu_time.len().min(3)],
                imu_time,
                dvl: &[],
                dvl_time: &[],
                t0,
                q_time: &[],
                q_values: &[],
            }
            .validate()
        };
        assert!(data(&[0.01, 0.02, 0.03], 0.0).is_ok());
        let err = data(&[0.01, 0.01, 0.03], 0.0).unwrap_err();
        assert!(
            matches!(&err, Error::InvalidArgument { arg, .. } if arg == "imu_time"),
            "{err}"
        );
        let err = data(&[0.01, 0.02, 0.03], 0.01).unwrap_err();
        assert!(err.to_string().contains("positive time step"), "{err}");
        let imu4 = [[0.0; 6]; 4];
        let err = RecordedData {
            imu: &imu4,
            imu_time: &[0.1, 0.2],
            dvl: &[],
            dvl_time: &[],
            t0: 0.0,
            q_time: &[],
            q_values: &[],
        }
        .validate()
        .unwrap_err();
        assert!(err.to_string().starts_with("imu_time"), "{err}");
    }

    /// A q schedule switches an external strategy's q at the epoch nearest each row's
    /// time, and nothing else: before the switch the run equals the prior's constant
    /// run bit for bit, from it on the new q's constant run's covariance growth.
    #[test]
    fn q_schedule_sets_external_q_from_its_epoch_on() {
        let n = 300;
        let imu = vec![[0.01, 0.0, -9.79, 0.0, 1e-4, 0.0]; n];
        let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
        let dvl = vec![[0.0; 3]; 3];
        let dvl_time = [0.995, 2.0, 3.004];
        let cfg = FilterConfig::default();
        let init = moving_state();
        let (qa, qb) = ([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6], [4e-4; 6]);
        let run = |spec: StrategySpec, q_time: &[f64], q_values: &[[f64; 6]]| {
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                dvl: &dvl,
                dvl_time: &dvl_time,
                t0: 0.0,
                q_time,
                q_values,
            };
            filter_recorded(
                &data,
                init,
                [0.0; 6],
                &cfg,
                spec.build(cfg.bias_psd()).as_mut(),
            )
        };
        let constant_a = run(StrategySpec::Constant { q: qa }, &[], &[]).unwrap();
        let external = |q_time: &[f64], q_values: &[[f64; 6]]| {
            run(StrategySpec::External { prior_q: qa }, q_time, q_values).unwrap()
        };
        // Setting the prior's own q at t0 changes nothing.
        assert_eq!(external(&[0.0], &[qa]).sigma, constant_a.sigma);
        // Switching at 1.504 s (nearest epoch 1.50): the first 150 steps are the prior's.
        let switched = external(&[1.504], &[qb]);
        assert_eq!(switched.sigma[..=150], constant_a.sigma[..=150]);
        assert!(switched.sigma[151][3] > constant_a.sigma[151][3]);
        // A schedule with a strategy that does not take q from outside is refused.
        let err = run(StrategySpec::Constant { q: qa }, &[0.0], &[qa]).unwrap_err();
        assert!(err.to_string().starts_with("strategy"), "{err}");
        let err = run(
            StrategySpec::External { prior_q: qa },
            &[1.0, 0.5],
            &[qa, qb],
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("q_time"), "{err}");
        let err = run(StrategySpec::External { prior_q: qa }, &[1.0], &[[-1.0; 6]]).unwrap_err();
        assert!(err.to_string().starts_with("q: row 0"), "{err}");
    }

    #[test]
    fn config_rejects_bad_values() {
        let c = FilterConfig {
            dvl_variance: [0.01, 0.0, 0.01],
            ..FilterConfig::default()
        };
        assert!(c.validate().is_err());
        let mut c = FilterConfig::default();
        c.p0_sigma[4] = -1.0;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("p0_sigma"));
        let c = FilterConfig {
            imu_dt: 0.0,
            ..FilterConfig::default()
        };
        assert!(c.validate().is_err());
    }
}
