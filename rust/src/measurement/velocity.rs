//! A velocity reading: a DVL's body-frame velocity at its lever arm (with the DVL
//! calibration states where the filter has them), or a velocity in NED.
//!
//! Body (a DVL): `h = Ĉᵀ v̂ + ω̂ × r`, `H = [0, Ĉᵀ, −Ĉᵀ[v̂×], 0, [r×]]` in the classic
//! formulation and `H_ψ = 0` in the invariant one (it reads `δV ≈ Ĉ δv_b`); with the
//! calibration states `ẑ = (1 + k̂) M̂ h` and their columns
//! ([`crate::ekf::calibration`]). NED: `h = v̂ + Ĉ (ω̂ × r)`,
//! `H = [0, I, [(Ĉ (ω̂×r))×], 0, Ĉ [r×]]`, plus `[v̂×]` on ψ in the invariant formulation
//! (`δv = δV + [v̂×]ψ`). Every formula is in `docs/reference/filter.md`.

use crate::attitude::skew;
use crate::ekf::{Aiding, Ekf, Linearized, Measurement, Rows3, VectorRows};
use crate::ekf::{ATT, GYRO_BIAS, VEL};
use nalgebra::{Matrix3, Vector3};

/// One velocity reading \[m/s\] in `frame`, each axis of variance `variance`
/// \[(m/s)²\], from a sensor at `lever_arm` \[m, body FRD\] from the IMU; a NIS above
/// `gate` (χ², 3 dof) rejects it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Velocity {
    pub z: Vector3<f64>,
    pub variance: [f64; 3],
    pub lever_arm: Vector3<f64>,
    pub frame: Aiding,
    pub gate: Option<f64>,
}

impl Velocity {
    /// The predicted reading (before the DVL calibration states) and its Jacobian
    /// over the 15 states, in the filter's formulation.
    pub fn model(&self, ekf: &Ekf) -> (Vector3<f64>, Rows3) {
        let mut h = Rows3::zeros();
        let nav = &ekf.nav;
        let invariant = ekf.config().formulation.velocity_invariant();
        let r = self.lever_arm;
        match self.frame {
            Aiding::Body => {
                let ct = nav.dcm.transpose();
                h.fixed_view_mut::<3, 3>(0, VEL).copy_from(&ct);
                if !invariant {
                    h.fixed_view_mut::<3, 3>(0, ATT)
                        .copy_from(&(-ct * skew(&nav.vel)));
                }
                h.fixed_view_mut::<3, 3>(0, GYRO_BIAS).copy_from(&skew(&r));
                (ct * nav.vel + ekf.last_gyro().cross(&r), h)
            }
            Aiding::Nav => {
                h.fixed_view_mut::<3, 3>(0, VEL)
                    .copy_from(&Matrix3::identity());
                if invariant {
                    h.fixed_view_mut::<3, 3>(0, ATT).copy_from(&skew(&nav.vel));
                }
                if r == Vector3::zeros() {
                    return (nav.vel, h);
                }
                let arm = nav.dcm * ekf.last_gyro().cross(&r);
                let mut att = h.fixed_view_mut::<3, 3>(0, ATT);
                att += skew(&arm);
                h.fixed_view_mut::<3, 3>(0, GYRO_BIAS)
                    .copy_from(&(nav.dcm * skew(&r)));
                (nav.vel + arm, h)
            }
        }
    }
}

impl Measurement for Velocity {
    fn name(&self) -> &'static str {
        "DVL"
    }

    fn linearize(&self, _: usize, ekf: &Ekf) -> Linearized {
        let r = Matrix3::from_diagonal(&Vector3::from_column_slice(&self.variance));
        let (predicted, h) = self.model(ekf);
        let (innovation, rows) = match (&ekf.calibration, self.frame) {
            (Some(calibration), Aiding::Body) => {
                let (predicted, h) = calibration.measurement(&predicted, &h);
                (self.z - predicted, VectorRows::Calibrated(h))
            }
            _ => (self.z - predicted, VectorRows::Nav(h)),
        };
        Linearized::Vector {
            innovation,
            rows,
            r,
            gate: self.gate,
        }
    }
}
