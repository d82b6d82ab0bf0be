//! The coordinates of the velocity error, and the maps between them.
//!
//! Three formulations of the same 15-state error share the attitude and bias errors:
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
//! - [`Formulation::Se23`]: the full right-invariant error of SE₂(3) to first order,
//!   `δV` and the position error `δP = δp − [p̂×]ψ`, with `p̂` the estimate's NED
//!   displacement from an anchor (the run's first position): `δP ≈ p̂ − Ĉ Cᵀ p`, the
//!   error left when the estimated track is turned about the anchor by the attitude
//!   error, which a large heading error leaves linear. The position's heading term
//!   `[v̂×]ψ` leaves the dynamics (`F_Pψ = [p̂×][ω_in×] − [ω_en×][p̂×]`,
//!   `F_P,bg = −[p̂×]Ĉ`) and enters the position measurements (`H_ψ = H_p [p̂×]`).
//!
//! The covariance lives in the formulation's coordinates; `x_f = T x_classic` with
//! `T = I` except the blocks (velocity rows, attitude columns) `−[v̂×]` and, in SE₂(3),
//! (position rows, attitude columns) `−[p̂×]`, taken at a [`Point`]. Users read the
//! classic coordinates: the prior is given in them and [`Point::to_classic`] maps every
//! covariance the filter reports. Every formula is in `docs/reference/filter.md`.

use super::state::{Gain, Matrix15, ATT, POS, VEL};
use crate::attitude::skew;
use crate::earth::NedScale;
use crate::mechanization::NavState;
use nalgebra::{Matrix3, Vector3};

/// Which error coordinates the filter's state and covariance are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Formulation {
    /// `δv = v̂ − v`: the first filter's coordinates, kept to reproduce its results.
    Classic,
    /// `δV = δv − [v̂×]ψ`: consistent in heading whether or not heading is observable
    /// (the default).
    #[default]
    Invariant,
    /// `δV` and `δP = δp − [p̂×]ψ` about an anchor: the position consistent too when
    /// the heading error grows large (a MEMS IMU without fixes).
    Se23,
}

impl Formulation {
    /// The name used in configs, TOML and the command line.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Classic => "classic",
            Formulation::Invariant => "invariant",
            Formulation::Se23 => "se23",
        }
    }

    /// Parse [`Formulation::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "classic" => Some(Formulation::Classic),
            "invariant" => Some(Formulation::Invariant),
            "se23" => Some(Formulation::Se23),
            _ => None,
        }
    }

    /// Whether the velocity error is `δV = δv − [v̂×]ψ` (every formulation but the
    /// classic one).
    pub fn velocity_invariant(self) -> bool {
        self != Formulation::Classic
    }

    /// Whether the position error is `δP = δp − [p̂×]ψ` about an anchor.
    pub fn position_invariant(self) -> bool {
        self == Formulation::Se23
    }
}

/// A formulation with the anchor its position error is taken about (geodetic
/// `[lat rad, lon rad, h m]`; read only by [`Formulation::Se23`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coordinates {
    pub formulation: Formulation,
    pub anchor: Vector3<f64>,
}

impl Coordinates {
    /// The point at which the map of the navigation solution `nav` is taken.
    #[inline]
    pub fn at(&self, nav: &NavState) -> Point {
        Point {
            formulation: self.formulation,
            vel: nav.vel,
            disp: if self.formulation.position_invariant() {
                self.displacement(&nav.lla)
            } else {
                Vector3::zeros()
            },
        }
    }

    /// The NED displacement \[m\] of the geodetic position `lla` from the anchor:
    /// `[(φ−φ₀)(R_N₀+h₀), (λ−λ₀)(R_E₀+h₀)cos φ₀, −(h−h₀)]`, the radii at the anchor (a
    /// linear map, inverted exactly by [`Coordinates::position`]).
    #[inline]
    pub fn displacement(&self, lla: &Vector3<f64>) -> Vector3<f64> {
        NedScale::at(&self.anchor).error(lla, &self.anchor)
    }

    /// The geodetic position at the NED displacement `disp` \[m\] from the anchor.
    pub fn position(&self, disp: &Vector3<f64>) -> Vector3<f64> {
        NedScale::at(&self.anchor).offset(&self.anchor, disp)
    }
}

/// Where the map between a formulation's coordinates and the classic ones is taken:
/// the velocity estimate \[m/s, NED\] and, in SE₂(3), the position estimate's
/// displacement from the anchor \[m, NED\] (zero in the other formulations).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub formulation: Formulation,
    pub vel: Vector3<f64>,
    pub disp: Vector3<f64>,
}

impl Point {
    /// The point of `formulation` at the velocity `vel`, with no position shear (every
    /// formulation but SE₂(3), or SE₂(3) at its anchor).
    pub fn velocity(formulation: Formulation, vel: &Vector3<f64>) -> Self {
        Self {
            formulation,
            vel: *vel,
            disp: Vector3::zeros(),
        }
    }

    /// A covariance in classic coordinates mapped into the formulation's, `T P Tᵀ`.
    pub fn from_classic(&self, p: &mut Matrix15) {
        if self.formulation.velocity_invariant() {
            shear(p, &(-skew(&self.vel)), self.position_shear(-1.0).as_ref());
        }
    }

    /// A covariance in the formulation's coordinates mapped into the classic ones:
    /// `T⁻¹ P T⁻ᵀ` with `T⁻¹ = I + [v̂×]` (and `+ [p̂×]`) in the same blocks.
    pub fn to_classic(&self, p: &mut Matrix15) {
        if self.formulation.velocity_invariant() {
            shear(p, &skew(&self.vel), self.position_shear(1.0).as_ref());
        }
    }

    /// `±[p̂×]` in SE₂(3), None in the other formulations.
    fn position_shear(&self, sign: f64) -> Option<Matrix3<f64>> {
        self.formulation
            .position_invariant()
            .then(|| skew(&self.disp) * sign)
    }

    /// The diagonal of [`Point::to_classic`]'s covariance (the variances in the
    /// classic coordinates) without the rest of it: the velocity (and position) rows
    /// are the only ones the map changes, and their diagonal is computed with its
    /// operations, in its order (the same numbers, bit for bit: tested).
    pub fn classic_variances(&self, p: &Matrix15) -> [f64; 15] {
        let mut d: [f64; 15] = std::array::from_fn(|i| p[(i, i)]);
        if self.formulation.velocity_invariant() {
            sheared_diagonal(p, &skew(&self.vel), VEL, &mut d);
        }
        if let Some(s) = self.position_shear(1.0) {
            sheared_diagonal(p, &s, POS, &mut d);
        }
        d
    }

    /// A Kalman gain in the formulation's coordinates mapped into the classic ones:
    /// `K ← T⁻¹ K`, whose velocity (and position) rows gain `[v̂×]` (`[p̂×]`) times its
    /// attitude rows (so that `−K ν` is the classic error estimate).
    pub fn gain_to_classic(&self, k: &mut Gain) {
        if self.formulation.velocity_invariant() {
            let att = k.fixed_rows::<3>(ATT).into_owned();
            let mut vel = k.fixed_rows_mut::<3>(VEL);
            vel += skew(&self.vel) * att;
            if let Some(s) = self.position_shear(1.0) {
                let mut pos = k.fixed_rows_mut::<3>(POS);
                pos += s * att;
            }
        }
    }
}

/// `P ← T P Tᵀ` for `T = I + E` with `E` the block `s` at (velocity rows, attitude
/// columns) and, where given, `sp` at (position rows, attitude columns): the velocity
/// (position) rows gain `s` (`sp`) times the attitude rows, then the velocity
/// (position) columns gain the attitude columns times `sᵀ` (`spᵀ`). The result is
/// symmetrized.
fn shear(p: &mut Matrix15, s: &Matrix3<f64>, sp: Option<&Matrix3<f64>>) {
    let att_rows = p.fixed_rows::<3>(ATT).into_owned();
    let mut vel_rows = p.fixed_rows_mut::<3>(VEL);
    vel_rows += s * att_rows;
    if let Some(sp) = sp {
        let mut pos_rows = p.fixed_rows_mut::<3>(POS);
        pos_rows += sp * att_rows;
    }
    let att_cols = p.fixed_columns::<3>(ATT).into_owned();
    let mut vel_cols = p.fixed_columns_mut::<3>(VEL);
    vel_cols += att_cols * s.transpose();
    if let Some(sp) = sp {
        let mut pos_cols = p.fixed_columns_mut::<3>(POS);
        pos_cols += att_cols * sp.transpose();
    }
    *p = (*p + p.transpose()) * 0.5;
}

/// The diagonal of rows `at..at + 3` of [`shear`]'s result for one block `s` at (those
/// rows, attitude columns), by its operations: row `at + i` after `rows += s · att_rows`
/// at column c, then `cols += att_cols · sᵀ` at its own column.
fn sheared_diagonal(p: &Matrix15, s: &Matrix3<f64>, at: usize, d: &mut [f64; 15]) {
    for (i, d) in d[at..at + 3].iter_mut().enumerate() {
        let row = |c: usize| {
            p[(at + i, c)]
                + (s[(i, 0)] * p[(ATT, c)]
                    + s[(i, 1)] * p[(ATT + 1, c)]
                    + s[(i, 2)] * p[(ATT + 2, c)])
        };
        *d = row(at + i)
            + (row(ATT) * s[(i, 0)] + row(ATT + 1) * s[(i, 1)] + row(ATT + 2) * s[(i, 2)]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::Vector15;

    fn points() -> [Point; 3] {
        let (vel, disp) = (
            Vector3::new(1.5, -0.4, 0.2),
            Vector3::new(850.0, -1200.0, 35.0),
        );
        [
            Formulation::Classic,
            Formulation::Invariant,
            Formulation::Se23,
        ]
        .map(|formulation| Point {
            formulation,
            vel,
            disp,
        })
    }

    fn t_matrix(at: &Point) -> Matrix15 {
        let mut t = Matrix15::identity();
        if at.formulation.velocity_invariant() {
            t.fixed_view_mut::<3, 3>(VEL, ATT)
                .copy_from(&(-skew(&at.vel)));
        }
        if at.formulation.position_invariant() {
            t.fixed_view_mut::<3, 3>(POS, ATT)
                .copy_from(&(-skew(&at.disp)));
        }
        t
    }

    fn test_p() -> Matrix15 {
        let a = Matrix15::from_fn(|i, j| ((i * 5 + j * 7) % 13) as f64 * 0.1 - 0.6);
        a * a.transpose() + Matrix15::identity()
    }

    #[test]
    fn the_maps_are_t_p_tt_and_its_inverse() {
        let p = test_p();
        for at in points() {
            let t = t_matrix(&at);
            let mut got = p;
            at.from_classic(&mut got);
            let want = t * p * t.transpose();
            assert!(
                (got - want).abs().max() < 1e-13 * want.abs().max(),
                "{at:?}"
            );
            // Rounding at the size of the mapped matrix (|p̂| ~ 1 km squared).
            at.to_classic(&mut got);
            assert!((got - p).abs().max() < 1e-15 * want.abs().max(), "{at:?}");
            let mut k = Gain::from_fn(|i, j| (i + 3 * j) as f64 * 0.01);
            let want = t.try_inverse().unwrap() * k;
            at.gain_to_classic(&mut k);
            assert!((k - want).abs().max() < 1e-12 * want.abs().max(), "{at:?}");
        }
    }

    #[test]
    fn the_classic_variances_are_the_mapped_diagonal() {
        let p = test_p();
        for at in points() {
            let mut mapped = p;
            at.to_classic(&mut mapped);
            let want: [f64; 15] = std::array::from_fn(|i| mapped[(i, i)]);
            let got = at.classic_variances(&p);
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.to_bits(), w.to_bits(), "{got:?} against {want:?}");
            }
        }
    }

    #[test]
    fn the_error_maps_back() {
        let x = Vector15::from_fn(|i, _| (i as f64 - 7.0) * 0.01);
        for at in points().into_iter().skip(1) {
            let xi = t_matrix(&at) * x;
            // δv = δV + [v̂×]ψ and δp = δP + [p̂×]ψ: the first-order feedback.
            let psi = xi.fixed_rows::<3>(ATT);
            let dv = xi.fixed_rows::<3>(VEL) + at.vel.cross(&psi);
            assert!((dv - x.fixed_rows::<3>(VEL)).abs().max() < 1e-16);
            if at.formulation.position_invariant() {
                let dp = xi.fixed_rows::<3>(POS) + at.disp.cross(&psi);
                assert!((dp - x.fixed_rows::<3>(POS)).abs().max() < 1e-12);
            }
            assert_eq!(
                Formulation::from_name(at.formulation.name()),
                Some(at.formulation)
            );
        }
        assert_eq!(Formulation::from_name("psi"), None);
    }

    #[test]
    fn the_anchor_displacement_is_inverted_exactly() {
        let coordinates = Coordinates {
            formulation: Formulation::Se23,
            anchor: Vector3::new(0.55, 0.6, -10.0),
        };
        let lla = Vector3::new(0.5503, 0.5996, -42.0);
        let d = coordinates.displacement(&lla);
        assert!(d.norm() > 1000.0 && d[2] > 0.0, "{d}");
        assert!((coordinates.position(&d) - lla).abs().max() < 1e-12);
    }
}
