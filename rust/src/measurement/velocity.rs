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
use crate::ekf::{Aiding, Ekf, Linearized, Measurement, Rows3, VectorNoise, VectorRows};
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

    /// The noise the gyro's white noise `n` puts on the lever arm's `ω̂ × r`: the
    /// prediction's error `−n × r = [r×] n` has the covariance `[r×] Σ_ω [r×]ᵀ` in the
    /// body frame (`Ĉ [r×] Σ_ω [r×]ᵀ Ĉᵀ` in NED), `Σ_ω` of [`Ekf::gyro_noise`]; and
    /// its `∂/∂λ` where the sensitivity is carried. None without a lever arm.
    fn arm_noise(&self, ekf: &Ekf) -> Option<(Matrix3<f64>, Option<Matrix3<f64>>)> {
        if self.lever_arm == Vector3::zeros() {
            return None;
        }
        let arm = match self.frame {
            Aiding::Body => skew(&self.lever_arm),
            Aiding::Nav => ekf.nav.dcm * skew(&self.lever_arm),
        };
        let through = |sigma: Matrix3<f64>| arm * sigma * arm.transpose();
        let (sigma, per_scale) = ekf.gyro_noise();
        Some((through(sigma), per_scale.map(through)))
    }
}

impl Measurement for Velocity {
    fn name(&self) -> &'static str {
        "DVL"
    }

    fn linearize(&self, _: usize, ekf: &Ekf) -> Linearized {
        let mut noise = VectorNoise {
            r: Matrix3::from_diagonal(&Vector3::from_column_slice(&self.variance)),
            per_scale: None,
        };
        let (predicted, h) = self.model(ekf);
        let arm = self.arm_noise(ekf);
        let (innovation, rows) = match (&ekf.calibration, self.frame) {
            (Some(calibration), Aiding::Body) => {
                let (predicted, h) = calibration.measurement(&predicted, &h);
                if let Some((sigma, per_scale)) = arm {
                    noise.r += calibration.body_noise_as_read(&sigma);
                    noise.per_scale = per_scale.map(|d| calibration.body_noise_as_read(&d));
                }
                (self.z - predicted, VectorRows::Calibrated(h))
            }
            _ => {
                if let Some((sigma, per_scale)) = arm {
                    noise.r += sigma;
                    noise.per_scale = per_scale;
                }
                (self.z - predicted, VectorRows::Nav(h))
            }
        };
        Linearized::Vector {
            innovation,
            rows,
            r: noise,
            gate: self.gate,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::ekf::ProcessNoise;
    use nalgebra::Vector3;

    /// The sensitivity M the filter carries for the adaptive strategy is the derivative
    /// of P with respect to the scale λ on q: central differences of P over a run with
    /// updates (innovations kept at zero, so that the state, and with it Φ, is the same
    /// for every λ) agree with M, before and after updates; with a DVL lever arm (whose
    /// `ω̂ × r` reads the gyro's noise, so R depends on λ too) in the body frame, in NED
    /// and with the DVL calibration states, the reported `∂S/∂λ` agrees with the
    /// difference of S.
    #[test]
    fn carried_sensitivity_is_the_derivative_of_p_in_the_scale() {
        use crate::ekf::calibration::CalibrationConfig;
        use crate::ekf::{Aiding, FilterConfig};
        let arm = Vector3::new(0.3, -0.2, 1.1);
        sensitivity_matches_differences(FilterConfig::default());
        for aiding in [Aiding::Body, Aiding::Nav] {
            sensitivity_matches_differences(FilterConfig {
                lever_arm: arm,
                aiding,
                ..FilterConfig::default()
            });
        }
        sensitivity_matches_differences(FilterConfig {
            lever_arm: arm,
            dvl_calibration: Some(CalibrationConfig::default()),
            ..FilterConfig::default()
        });
    }

    fn sensitivity_matches_differences(cfg: crate::ekf::FilterConfig) {
        use crate::ekf::Ekf;
        use crate::mechanization::ImuSample;
        let q = [1e-4, 2e-4, 1e-4, 1e-6, 3e-6, 1e-6];
        let bias = [1e-3; 6];
        let run = |lambda: f64, track: bool| {
            let nav = crate::ekf::tests::moving_state();
            let mut ekf = Ekf::new(&cfg, nav, Vector3::zeros(), Vector3::zeros()).unwrap();
            if track {
                ekf.track_sensitivity(q);
            }
            let scaled = q.map(|v| v * lambda);
            let sample = ImuSample::from_array(&[0.05, -0.02, -9.79, 0.01, 0.002, 0.03]);
            let mut last = None;
            for k in 1..=250 {
                let noise = ProcessNoise::Continuous {
                    imu_variance: &scaled,
                    bias_psd: &bias,
                };
                ekf.propagate(&sample, 0.01, noise).unwrap();
                if k % 100 == 0 {
                    let dvl = crate::ekf::tests::dvl_at_estimate(&ekf); // zero innovation
                    last = ekf.apply(&dvl).unwrap().report;
                }
            }
            (ekf, last.unwrap())
        };
        let (tracked, report) = run(1.3, true);
        let eps = 1e-3;
        let (up, up_report) = run(1.3 + eps, false);
        let (down, down_report) = run(1.3 - eps, false);
        let fd = (up.p - down.p) / (2.0 * eps);
        let m = tracked.sensitivity_matrix().unwrap();
        let scale = fd.abs().max();
        assert!(scale > 0.0);
        assert!(
            (m - fd).abs().max() < 1e-6 * scale,
            "{}",
            (m - fd).abs().max() / scale
        );
        // The last update's ∂S/∂λ against the difference of its S (P before it and R).
        let ds = (up_report.s - down_report.s) / (2.0 * eps);
        let reported = report.sensitivity.expect("a tracking filter reports ∂S/∂λ");
        assert!(
            (reported - ds).abs().max() < 1e-6 * ds.abs().max(),
            "{reported} against {ds}"
        );
        assert!(
            run(1.0, false).1.sensitivity.is_none(),
            "an untracked one does not"
        );
    }
}
