//! The coordinates of the velocity error, and the maps between them.
//!
//! Two formulations of the same 15-state error share the position, attitude and bias
//! errors and differ in the velocity error:
//!
//! - [`Formulation::Classic`]: `δv = v̂ − v`, the NED velocity error (the ψ-angle
//!   model of Benson 1975 / Titterton & Weston). Its F and H depend on the estimate
//!   (`F_vψ = [Ĉf̂×]`, `H_ψ = −Ĉᵀ[v̂×]`), so the unobservable heading / vertical gyro
//!   bias direction moves with every correction and the filter gains heading
//!   information it does not have when heading is unobservable.
//! - [`Formulation::Invariant`]: the modified velocity error `δV = δv − [v̂×]ψ`
//!   (Scherzinger & Reid's modified ψ-angle model, 1994; the velocity part of the
//!   right-invariant error of Barrau & Bonnabel, 2017, to first order). `δV ≈ Ĉ δv_b`
//!   is the error of the body-frame velocity, so the DVL reads it with
//!   `H = [0, Ĉᵀ, 0, 0, [r×]]` and the dynamics lose their dependence on the specific
//!   force: `F_Vψ = −[g×] − [v̂×][ω_ie×]`, `F_pψ = [v̂×]`, `F_V,bg = −[v̂×]Ĉ`.
//!
//! The covariance lives in the formulation's coordinates; `x_inv = T(v̂) x_classic`
//! with `T = I` except the block (velocity rows, attitude columns) `−[v̂×]`. Users read
//! the classic coordinates: the prior is given in them and [`to_classic`] maps every
//! covariance the filter reports. Every formula is in `docs/filter.md`.

use super::state::{Gain, Matrix15, ATT, VEL};
use crate::attitude::skew;
use nalgebra::{Matrix3, Vector3};

/// Which velocity error the filter's state and covariance are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Formulation {
    /// `δv = v̂ − v`: pronet's filter until 2026-12, kept to reproduce its results.
    Classic,
    /// `δV = δv − [v̂×]ψ`: consistent in heading whether or not heading is observable
    /// (the default).
    #[default]
    Invariant,
}

impl Formulation {
    /// The name used in configs, TOML and the command line.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Classic => "classic",
            Formulation::Invariant => "invariant",
        }
    }

    /// Parse [`Formulation::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "classic" => Some(Formulation::Classic),
            "invariant" => Some(Formulation::Invariant),
            _ => None,
        }
    }
}

/// `P ← T P Tᵀ` for `T = I + E` with `E` the single block `s` at (velocity rows,
/// attitude columns): the velocity rows gain `s` times the attitude rows, then the
/// velocity columns gain the attitude columns times `sᵀ`. The result is symmetrized.
fn shear(p: &mut Matrix15, s: &Matrix3<f64>) {
    let att_rows = p.fixed_rows::<3>(ATT).into_owned();
    let mut vel_rows = p.fixed_rows_mut::<3>(VEL);
    vel_rows += s * att_rows;
    let att_cols = p.fixed_columns::<3>(ATT).into_owned();
    let mut vel_cols = p.fixed_columns_mut::<3>(VEL);
    vel_cols += att_cols * s.transpose();
    *p = (*p + p.transpose()) * 0.5;
}

/// A covariance in classic coordinates mapped into `f`'s, at the velocity estimate `v`
/// \[m/s, NED\].
pub fn from_classic(f: Formulation, p: &mut Matrix15, v: &Vector3<f64>) {
    if f == Formulation::Invariant {
        shear(p, &(-skew(v)));
    }
}

/// A covariance in `f`'s coordinates mapped into the classic ones, at the velocity
/// estimate `v` \[m/s, NED\]: `T⁻¹ P T⁻ᵀ` with `T⁻¹ = I + [v̂×]` in the same block.
pub fn to_classic(f: Formulation, p: &mut Matrix15, v: &Vector3<f64>) {
    if f == Formulation::Invariant {
        shear(p, &skew(v));
    }
}

/// The diagonal of [`to_classic`]'s covariance (the variances in the classic
/// coordinates) without the rest of it: the velocity rows are the only ones the map
/// changes, and their diagonal is computed with its operations, in its order (the same
/// numbers, bit for bit: tested).
pub fn classic_variances(f: Formulation, p: &Matrix15, v: &Vector3<f64>) -> [f64; 15] {
    let mut d: [f64; 15] = std::array::from_fn(|i| p[(i, i)]);
    if f == Formulation::Invariant {
        let s = skew(v);
        for (i, d) in d[VEL..VEL + 3].iter_mut().enumerate() {
            // Row VEL + i after `vel_rows += s · att_rows`, at column c.
            let row = |c: usize| {
                p[(VEL + i, c)]
                    + (s[(i, 0)] * p[(ATT, c)]
                        + s[(i, 1)] * p[(ATT + 1, c)]
                        + s[(i, 2)] * p[(ATT + 2, c)])
            };
            // Then `vel_cols += att_cols · sᵀ` at its own column.
            *d = row(VEL + i)
                + (row(ATT) * s[(i, 0)] + row(ATT + 1) * s[(i, 1)] + row(ATT + 2) * s[(i, 2)]);
        }
    }
    d
}

/// A Kalman gain in `f`'s coordinates mapped into the classic ones at the velocity
/// estimate `v` \[m/s, NED\]: `K ← T⁻¹ K`, whose velocity rows gain `[v̂×]` times its
/// attitude rows (so that `−K ν` is the classic error estimate).
pub fn gain_to_classic(f: Formulation, k: &mut Gain, v: &Vector3<f64>) {
    if f == Formulation::Invariant {
        let att = k.fixed_rows::<3>(ATT).into_owned();
        let mut vel = k.fixed_rows_mut::<3>(VEL);
        vel += skew(v) * att;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::Vector15;

    fn t_matrix(v: &Vector3<f64>) -> Matrix15 {
        let mut t = Matrix15::identity();
        t.fixed_view_mut::<3, 3>(VEL, ATT).copy_from(&(-skew(v)));
        t
    }

    #[test]
    fn the_maps_are_t_p_tt_and_its_inverse() {
        let v = Vector3::new(1.5, -0.4, 0.2);
        let a = Matrix15::from_fn(|i, j| ((i * 5 + j * 7) % 13) as f64 * 0.1);
        let p = a * a.transpose() + Matrix15::identity();
        let t = t_matrix(&v);
        let mut got = p;
        from_classic(Formulation::Invariant, &mut got, &v);
        let want = t * p * t.transpose();
        assert!((got - want).abs().max() < 1e-13 * want.abs().max());
        to_classic(Formulation::Invariant, &mut got, &v);
        assert!((got - p).abs().max() < 1e-13 * p.abs().max());
        let mut same = p;
        from_classic(Formulation::Classic, &mut same, &v);
        to_classic(Formulation::Classic, &mut same, &v);
        assert_eq!(same, p);
    }

    #[test]
    fn the_classic_variances_are_the_mapped_diagonal() {
        let v = Vector3::new(1.5, -0.4, 0.2);
        let a = Matrix15::from_fn(|i, j| ((i * 5 + j * 7) % 13) as f64 * 0.1 - 0.6);
        let p = a * a.transpose() + Matrix15::identity();
        for f in [Formulation::Classic, Formulation::Invariant] {
            let mut mapped = p;
            to_classic(f, &mut mapped, &v);
            let want: [f64; 15] = std::array::from_fn(|i| mapped[(i, i)]);
            let got = classic_variances(f, &p, &v);
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.to_bits(), w.to_bits(), "{got:?} against {want:?}");
            }
        }
    }

    #[test]
    fn the_velocity_error_maps_back() {
        let v = Vector3::new(1.5, -0.4, 0.2);
        let x = Vector15::from_fn(|i, _| (i as f64 - 7.0) * 0.01);
        let xi = t_matrix(&v) * x;
        // δv = δV + [v̂×]ψ: the first-order feedback the filter applies exactly.
        let dv = xi.fixed_rows::<3>(VEL) + v.cross(&xi.fixed_rows::<3>(ATT));
        assert!((dv - x.fixed_rows::<3>(VEL)).abs().max() < 1e-16);
        assert_eq!(
            Formulation::from_name(Formulation::Invariant.name()),
            Some(Formulation::Invariant)
        );
        assert_eq!(Formulation::from_name("psi"), None);
    }
}
