//! A heading reading: the yaw of the body from true north, from a compass, an AHRS or
//! a gyrocompass.
//!
//! `ŷ = atan2(Ĉ₁₀, Ĉ₀₀)` (ZYX, as [`crate::attitude::euler_from_dcm`]), `ν = wrap(y − ŷ)`
//! into (−π, π]; `H = [Ĉ₂₀ Ĉ₀₀ / d, Ĉ₂₀ Ĉ₁₀ / d, −1]` on ψ, `d = Ĉ₀₀² + Ĉ₁₀²`, zero
//! elsewhere, the same in either formulation (ψ means the same in both). From
//! `Ĉ − C = −[ψ×] C`: `ŷ − y = −ψ_z + Ĉ₂₀ (Ĉ₀₀ ψ_x + Ĉ₁₀ ψ_y) / d`, so a level vehicle's
//! heading reads −ψ_z alone. Undefined at a pitch of ±90° (`d = 0`: the update reports
//! a non-finite innovation variance). One scalar update, no gate. `docs/reference/aiding.md`,
//! "Lever arms and heading".

use crate::attitude::wrap_angle;
use crate::ekf::{Ekf, Linearized, Measurement, Row15, ScalarRow, ATT};

/// One heading `y` \[rad, from true north, clockwise seen from above\] of 1σ `sigma`
/// \[rad\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heading {
    pub y: f64,
    pub sigma: f64,
}

impl Measurement for Heading {
    fn name(&self) -> &'static str {
        "heading"
    }

    fn linearize(&self, _: usize, ekf: &Ekf) -> Linearized {
        let c = &ekf.nav.dcm;
        let d = c[(0, 0)] * c[(0, 0)] + c[(1, 0)] * c[(1, 0)];
        let mut row = Row15::zeros();
        row[ATT] = c[(2, 0)] * c[(0, 0)] / d;
        row[ATT + 1] = c[(2, 0)] * c[(1, 0)] / d;
        row[ATT + 2] = -1.0;
        Linearized::Scalar {
            innovation: wrap_angle(self.y - c[(1, 0)].atan2(c[(0, 0)])),
            row: ScalarRow::Row(row),
            r: self.sigma * self.sigma,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::{dcm_from_euler, skew};
    use crate::ekf::tests::moving_state;
    use crate::ekf::{Ekf, FilterConfig, Formulation};
    use nalgebra::{Matrix3, Vector3};

    /// The filter at `moving_state` turned to roll, pitch, yaw `rpy` \[rad\].
    fn at(rpy: [f64; 3], formulation: Formulation) -> Ekf {
        let mut s = moving_state();
        s.dcm = dcm_from_euler(rpy[0], rpy[1], rpy[2]);
        let cfg = FilterConfig {
            formulation,
            ..FilterConfig::default()
        };
        Ekf::new(&cfg, s, Vector3::zeros(), Vector3::zeros()).unwrap()
    }

    /// The predicted heading of the filter whose attitude is `Ĉ = (I − [ψ×]) C`.
    fn yaw_with_error(ekf: &Ekf, psi: &Vector3<f64>) -> f64 {
        let c = (Matrix3::identity() - skew(psi)) * ekf.nav.dcm;
        c[(1, 0)].atan2(c[(0, 0)])
    }

    #[test]
    fn the_row_is_the_derivative_of_the_predicted_heading() {
        let cases = [[0.0, 0.0, 0.3], [0.2, -0.4, 2.9], [-0.5, 0.7, -1.2]];
        for (rpy, formulation) in cases
            .into_iter()
            .flat_map(|r| [(r, Formulation::Classic), (r, Formulation::Invariant)])
        {
            let ekf = at(rpy, formulation);
            let Linearized::Scalar { row, .. } =
                (Heading { y: 0.0, sigma: 0.1 }).linearize(0, &ekf)
            else {
                panic!("a heading is a scalar update");
            };
            let ScalarRow::Row(row) = row else {
                panic!("a heading's row is over ψ")
            };
            let eps = 1e-6;
            for k in 0..3 {
                let mut psi = Vector3::zeros();
                psi[k] = eps;
                let plus = yaw_with_error(&ekf, &psi);
                let minus = yaw_with_error(&ekf, &-psi);
                let numeric = wrap_angle(plus - minus) / (2.0 * eps);
                assert!(
                    (row[ATT + k] - numeric).abs() < 1e-8,
                    "{rpy:?} ψ{k}: {}",
                    row[ATT + k]
                );
            }
            let others: f64 = (0..15)
                .filter(|i| !(ATT..ATT + 3).contains(i))
                .map(|i| row[i].abs())
                .sum();
            assert_eq!(others, 0.0);
        }
    }

    #[test]
    fn the_innovation_is_wrapped_and_level_reads_minus_psi_z() {
        let ekf = at([0.0, 0.0, 3.1], Formulation::Classic);
        let m = Heading {
            y: -3.1,
            sigma: 0.01,
        };
        let Linearized::Scalar { innovation, row, r } = m.linearize(0, &ekf) else {
            panic!("a heading is a scalar update");
        };
        // −3.1 − 3.1 = −6.2 rad is 0.083 rad the other way round.
        assert!((innovation - (2.0 * std::f64::consts::PI - 6.2)).abs() < 1e-12);
        assert!((r - 1e-4).abs() < 1e-18);
        let ScalarRow::Row(row) = row else { panic!() };
        assert_eq!([row[ATT], row[ATT + 1], row[ATT + 2]], [0.0, 0.0, -1.0]);
    }

    #[test]
    fn an_update_pulls_the_yaw_and_its_sigma_in() {
        let mut ekf = at([0.0, 0.0, 0.5], Formulation::Classic);
        let before = ekf.p[(ATT + 2, ATT + 2)];
        let applied = ekf
            .apply(&Heading {
                y: 0.52,
                sigma: 0.01,
            })
            .unwrap();
        assert_eq!(applied.dof, 1);
        let yaw = ekf.nav.dcm[(1, 0)].atan2(ekf.nav.dcm[(0, 0)]);
        // The estimate moves towards the reading by the gain P/(P + σ²).
        let k = before / (before + 1e-4);
        assert!((yaw - (0.5 + 0.02 * k)).abs() < 1e-6, "{yaw}");
        assert!(ekf.p[(ATT + 2, ATT + 2)] < before);
        assert!((applied.nis - 0.02 * 0.02 / (before + 1e-4)).abs() < 1e-9);
    }
}
