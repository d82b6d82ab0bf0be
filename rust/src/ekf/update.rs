//! The measurement update, shared by every sensor: a [`Measurement`] gives, for one
//! reading at the filter's estimate, its innovation, its Jacobian rows over the error
//! state, its noise and its gate ([`Linearized`]); [`Ekf::apply`] runs the EKF update in
//! Joseph form on the 15 states (19 with the DVL calibration states), feeds the error
//! estimate back and resets it, and reports the NIS. A 3-vector reading (a velocity) is
//! one joint update; a reading of scalar components (a depth, a fix, a heading) is one
//! scalar update per component, each linearized at the estimate the previous one left:
//! with a diagonal R, the joint update and its sum of NIS (`docs/reference/filter.md`).

use super::calibration::{Calibration, DvlErrors, Rows3x19, N_CALIBRATED, N_DVL, SCALE};
use super::filter::Ekf;
use super::joseph::Support;
use super::state::{Gain, Row15, Rows3, Vector15};
use crate::error::{Error, Result};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// One reading, as the filter updates with it. Each kind of sensor implements it
/// (`crate::measurement`); the update, the NIS and the feedback are [`Ekf::apply`]'s.
pub trait Measurement {
    /// The reading's name in messages (`"DVL"`, `"depth"`, `"fix"`, ...).
    fn name(&self) -> &'static str;

    /// The scalar components updated one after another (1 for a joint update).
    fn components(&self) -> usize {
        1
    }

    /// Component `i` linearized at the filter's estimate `ekf` (after the feedback of
    /// the components before it).
    fn linearize(&self, i: usize, ekf: &Ekf) -> Linearized;
}

/// The Jacobian rows of a 3-vector measurement: over the 15 states, or over the 19 with
/// the DVL calibration states (a reading that sees them).
#[derive(Clone, Debug)]
pub enum VectorRows {
    Nav(Rows3),
    Calibrated(Rows3x19),
}

/// The Jacobian row of a scalar measurement: a unit row `e_i` (state `i` read
/// directly), or a row over the 15 states.
#[derive(Clone, Debug)]
pub enum ScalarRow {
    Unit(usize),
    Row(Row15),
}

impl ScalarRow {
    /// The row over the 15 states.
    pub fn dense(&self) -> Row15 {
        match self {
            Self::Unit(i) => {
                let mut h = Row15::zeros();
                h[(0, *i)] = 1.0;
                h
            }
            Self::Row(row) => *row,
        }
    }
}

/// One measurement (or one component of it) linearized at the estimate: innovation
/// `ν = z − h(x̂)`, Jacobian `H = ∂h/∂δx` (so that `ν ≈ −H δx` plus noise), noise R.
/// A temporary on the stack between a measurement and the update: its vector variant's
/// size (0.6 kB with the calibration states' rows) is not boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Linearized {
    /// A joint update of a 3-vector reading; a NIS above the χ² `gate` (3 dof) rejects
    /// it (nothing is applied).
    Vector {
        innovation: Vector3<f64>,
        rows: VectorRows,
        r: VectorNoise,
        gate: Option<f64>,
    },
    /// A scalar update (never gated) with variance `r`.
    Scalar {
        innovation: f64,
        row: ScalarRow,
        r: f64,
    },
}

/// The noise of a 3-vector reading: its covariance R and, where the filter carries the
/// sensitivity `M = ∂P/∂λ` ([`Ekf::track_sensitivity`]) and R depends on the IMU
/// variances (a lever arm's `ω̂ × r` reads the gyro's noise), `∂R/∂λ`.
#[derive(Clone, Copy, Debug)]
pub struct VectorNoise {
    pub r: Matrix3<f64>,
    pub per_scale: Option<Matrix3<f64>>,
}

/// Result of the joint update of a 3-vector reading (a velocity): what the noise
/// strategies read.
#[derive(Clone, Debug)]
pub struct UpdateInfo {
    /// `ν = z − h(x̂)`.
    pub innovation: Vector3<f64>,
    /// Innovation covariance `S = H P Hᵀ + R`.
    pub s: Matrix3<f64>,
    /// Normalized innovation squared `νᵀ S⁻¹ ν` (χ², 3 dof when consistent).
    pub nis: f64,
    /// The gain's first 15 rows, in the classic coordinates.
    pub gain: Gain,
    /// False when the innovation gate rejected the measurement: the state is unchanged.
    pub accepted: bool,
    /// `∂S/∂λ = H M Hᵀ + ∂R/∂λ` with `M = ∂P⁻/∂λ` (see [`Ekf::track_sensitivity`];
    /// `∂R/∂λ` the DVL lever arm's gyro-noise term, else zero); None when untracked.
    pub sensitivity: Option<Matrix3<f64>>,
    /// The error estimate `δx̂ = −K ν` fed back, in the filter's own coordinates (the
    /// first 15 states); None when the gate rejected the measurement.
    pub correction: Option<Vector15>,
    /// With the DVL calibration states, their estimate `[δk̂, δμ̂]` fed back (None
    /// without them or when the gate rejected the measurement).
    pub calibration_correction: Option<DvlErrors>,
}

/// What one reading's update did.
#[derive(Clone, Debug)]
pub struct Applied {
    /// The sum of its components' NIS (χ² with `dof` degrees of freedom when
    /// consistent).
    pub nis: f64,
    pub dof: usize,
    /// False when the gate rejected it (the state is unchanged).
    pub accepted: bool,
    /// The sums of the error estimates fed back (the first 15 states, in the filter's
    /// coordinates, and the DVL calibration states' `[δk̂, δμ̂]`, zero without them);
    /// None when the gate rejected it.
    pub correction: Option<(Vector15, DvlErrors)>,
    /// The joint update's report, for a 3-vector reading.
    pub report: Option<UpdateInfo>,
}

impl Ekf {
    /// Update with one reading (brought up to date first), feeding every accepted
    /// component's error estimate back before the next.
    pub fn apply<M: Measurement + ?Sized>(&mut self, m: &M) -> Result<Applied> {
        self.bring_up_to_date();
        let mut out = Applied {
            nis: 0.0,
            dof: 0,
            accepted: true,
            correction: None,
            report: None,
        };
        for i in 0..m.components() {
            match m.linearize(i, self) {
                Linearized::Vector {
                    innovation,
                    rows,
                    r,
                    gate,
                } => {
                    let info = self.vector_update(m.name(), &innovation, &rows, &r, gate)?;
                    out.nis += info.nis;
                    out.dof += 3;
                    out.accepted &= info.accepted;
                    if let Some(dx) = info.correction {
                        let cal = info.calibration_correction.unwrap_or_default();
                        add_correction(&mut out.correction, &dx, &cal);
                    }
                    out.report = Some(info);
                }
                Linearized::Scalar { innovation, row, r } => {
                    let (nis, dx, cal) = self.scalar_update(m.name(), innovation, &row, r)?;
                    out.nis += nis;
                    out.dof += 1;
                    add_correction(&mut out.correction, &dx, &cal.unwrap_or_default());
                }
            }
        }
        Ok(out)
    }

    /// The joint update of a 3-vector reading (see [`kalman_update`]), fed back.
    fn vector_update(
        &mut self,
        name: &str,
        innovation: &Vector3<f64>,
        rows: &VectorRows,
        r: &VectorNoise,
        gate: Option<f64>,
    ) -> Result<UpdateInfo> {
        let (info, dx) = match (rows, self.calibration.as_mut()) {
            (VectorRows::Nav(h), None) => {
                let m = self.sensitivity.as_mut().map(|(m, _)| m);
                let out = kalman_update(&mut self.p, m, h, innovation, r, gate, name)?;
                if let (Some(s), true) = (self.second_order.as_mut(), out.info.accepted) {
                    s.update(&out.info.gain, h);
                }
                (out.info, out.dx.map(|d| (d, None)))
            }
            (rows, Some(calibration)) => {
                let h = match rows {
                    VectorRows::Calibrated(h) => *h,
                    VectorRows::Nav(h) => pad(h),
                };
                let mut p = calibration.assemble(&self.p);
                let sensitivity = self.sensitivity.as_mut().map(|(m, _)| m);
                let mut m = match (&sensitivity, self.sensitivity_calibration.as_ref()) {
                    (Some(m15), Some(c)) => Some(c.assemble(m15)),
                    _ => None,
                };
                let out = kalman_update(&mut p, m.as_mut(), &h, innovation, r, gate, name)?;
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
                    (nav, Some(calibration_part(&d)))
                });
                (out.info, dx)
            }
            (VectorRows::Calibrated(_), None) => {
                return Err(Error::Numerical(format!(
                    "the {name} reading sees the DVL calibration states, which the filter \
                     does not have"
                )))
            }
        };
        let mut info = info;
        self.point().gain_to_classic(&mut info.gain);
        if let Some((dx, cal)) = dx {
            info.correction = Some(dx);
            info.calibration_correction = cal;
            self.feedback(&dx);
            if let (Some(c), Some(cal)) = (self.calibration.as_mut(), cal) {
                c.feedback(&cal);
            }
            let calibration_finite = self.calibration.as_ref().is_none_or(Calibration::is_finite);
            if !self.p[(0, 0)].is_finite() || !calibration_finite {
                return Err(Error::Numerical(format!(
                    "the {name} update produced a non-finite state"
                )));
            }
        }
        Ok(info)
    }

    /// One scalar update (see [`scalar_update`]), fed back: its NIS and the error
    /// estimates fed back (the calibration states' where the filter has them).
    fn scalar_update(
        &mut self,
        name: &str,
        innovation: f64,
        row: &ScalarRow,
        r: f64,
    ) -> Result<(f64, Vector15, Option<DvlErrors>)> {
        let (nis, dx, cal) = match self.calibration.as_mut() {
            None => {
                let m = self.sensitivity.as_mut().map(|(m, _)| m);
                let (nis, dx, gain) = scalar_update(&mut self.p, m, row, innovation, r, name)?;
                if let Some(s) = self.second_order.as_mut() {
                    s.update(&gain, &row.dense());
                }
                (nis, dx, None)
            }
            Some(calibration) => {
                let mut p = calibration.assemble(&self.p);
                let sensitivity = self.sensitivity.as_mut().map(|(m, _)| m);
                let mut m = match (&sensitivity, self.sensitivity_calibration.as_ref()) {
                    (Some(m15), Some(c)) => Some(c.assemble(m15)),
                    _ => None,
                };
                let (nis, d, _) = scalar_update(&mut p, m.as_mut(), row, innovation, r, name)?;
                calibration.split(&p, &mut self.p);
                if let (Some(full), Some(m15), Some(c)) = (
                    m.as_ref(),
                    sensitivity,
                    self.sensitivity_calibration.as_mut(),
                ) {
                    c.split(full, m15);
                }
                let d: SVector<f64, N_CALIBRATED> = d;
                let nav: Vector15 = d.fixed_rows::<15>(0).into_owned();
                (nis, nav, Some(calibration_part(&d)))
            }
        };
        self.feedback(&dx);
        if let (Some(c), Some(cal)) = (self.calibration.as_mut(), cal) {
            c.feedback(&cal);
        }
        if !self.is_finite() || !self.calibration.as_ref().is_none_or(Calibration::is_finite) {
            return Err(Error::Numerical(format!(
                "the {name} update produced a non-finite state"
            )));
        }
        Ok((nis, dx, cal))
    }
}

/// Add an error estimate fed back (`dx`, and the calibration states' `cal`) to a sum
/// started at zero.
fn add_correction(sum: &mut Option<(Vector15, DvlErrors)>, dx: &Vector15, cal: &DvlErrors) {
    let (nav, calibration) = sum.get_or_insert((Vector15::zeros(), [0.0; N_DVL]));
    *nav += dx;
    for (s, v) in calibration.iter_mut().zip(cal) {
        *s += v;
    }
}

/// `[δk̂, δμ̂, δb̂]` of a full error estimate.
fn calibration_part(d: &SVector<f64, N_CALIBRATED>) -> DvlErrors {
    std::array::from_fn(|k| d[SCALE + k])
}

/// Rows over the 15 states padded with zeros over the calibration states.
fn pad(h: &Rows3) -> Rows3x19 {
    let mut full = Rows3x19::zeros();
    full.fixed_view_mut::<3, 15>(0, 0).copy_from(h);
    full
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
/// `P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ` symmetrized and
/// `M ← (I − K H) M (I − K H)ᵀ + K (∂R/∂λ) Kᵀ` (the report's sensitivity
/// `∂S/∂λ = H M Hᵀ + ∂R/∂λ`).
/// For the 15 states and the 19 with the DVL calibration (N ≥ 15: the report's gain
/// is the first 15 rows).
fn kalman_update<const N: usize>(
    p: &mut SMatrix<f64, N, N>,
    m: Option<&mut SMatrix<f64, N, N>>,
    h: &SMatrix<f64, 3, N>,
    innovation: &Vector3<f64>,
    noise: &VectorNoise,
    gate: Option<f64>,
    name: &str,
) -> Result<Outcome<N>> {
    let support = Support::of(h);
    let pht = support.times_transpose(p, h);
    let s = support.left_times(h, &pht) + noise.r;
    let s_inv = s
        .cholesky()
        .ok_or_else(|| Error::Numerical("innovation covariance S is not positive definite".into()))?
        .inverse();
    let gain: SMatrix<f64, N, 3> = pht * s_inv;
    let mht = m.as_ref().map(|m| support.times_transpose(m, h));
    let sensitivity = mht.as_ref().map(|mht| {
        let hmh = support.left_times(h, mht);
        noise.per_scale.map_or(hmh, |dr| hmh + dr)
    });
    let nis = innovation.dot(&(s_inv * innovation));
    // Checked before anything is applied: a NaN would slip past the gate's `>`.
    if !nis.is_finite() {
        return Err(Error::Numerical(format!(
            "the {name} update has a non-finite NIS ({nis})"
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
    support.joseph(p, &pht, &gain, h, Some(&noise.r));
    if let (Some(m), Some(mht)) = (m, mht) {
        support.joseph(m, &mht, &gain, h, noise.per_scale.as_ref());
    }
    Ok(Outcome {
        info: report,
        dx: Some(-(gain * innovation)),
    })
}

/// The scalar update of an `N`-state covariance `p` (and of the sensitivity `m`, if
/// tracked) with the row `H` (over the first 15 states), innovation `ν` and variance
/// `r`: `S = H P Hᵀ + r`, `K = P Hᵀ / S`, Joseph form, symmetrized; its NIS `ν²/S`,
/// the error estimate `−K ν` and the gain's first 15 rows. A unit row `e_i` reads
/// column `i` of P directly (the same numbers as the product, without it).
fn scalar_update<const N: usize>(
    p: &mut SMatrix<f64, N, N>,
    m: Option<&mut SMatrix<f64, N, N>>,
    row: &ScalarRow,
    innovation: f64,
    r: f64,
    name: &str,
) -> Result<(f64, SVector<f64, N>, SMatrix<f64, 15, 1>)> {
    let mut h = SMatrix::<f64, 1, N>::zeros();
    h.fixed_columns_mut::<15>(0).copy_from(&row.dense());
    let support = Support::of(&h);
    let (pht, s) = match row {
        ScalarRow::Unit(i) => (p.column(*i).into_owned(), p[(*i, *i)] + r),
        ScalarRow::Row(_) => {
            let pht = support.times_transpose(p, &h);
            let s = support.left_times(&h, &pht)[(0, 0)] + r;
            (pht, s)
        }
    };
    if !(s > 0.0 && s.is_finite() && innovation.is_finite()) {
        return Err(Error::Numerical(format!(
            "the {name} update has an innovation variance of {s} and an innovation of \
             {innovation}"
        )));
    }
    let gain: SVector<f64, N> = pht / s;
    support.joseph(p, &pht, &gain, &h, Some(&SMatrix::<f64, 1, 1>::new(r)));
    if let Some(m) = m {
        let mht = support.times_transpose(m, &h);
        support.joseph(m, &mht, &gain, &h, None);
    }
    let first: SMatrix<f64, 15, 1> = gain.fixed_rows::<15>(0).into_owned();
    Ok((innovation * innovation / s, -(gain * innovation), first))
}
