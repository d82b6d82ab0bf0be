//! The second-order heading term of the position error (opt-in,
//! [`super::FilterConfig::heading_second_order`]; `docs/reference/heading.md`).
//!
//! A heading error `δψ` turns the track the filter dead-reckons: to first order across
//! it (the EKF's `[v̂×]`-terms), to second order along it, `+½ δψ² v̂_h dt` per step
//! (the true velocity is `R(−δψ) v̂`). The linear filter has no variance along the
//! track for that part, and on a long mission without fixes, where heading errors reach
//! tens of degrees, the position error lies off its thin horizontal ellipse
//! (`docs/results/consistency.md`, "A long MEMS mission without fixes": along that axis
//! the error is this term, run by run).
//!
//! The term's size is known to the filter through its own heading variance:
//! `m = ∫ σ_ψ² v̂_h dt`. A heading error that is one Gaussian draw `δψ = σ_ψ z` over the
//! run (as a bias-driven one nearly is) makes the term `½ z² m`, whose second moment
//! about zero is `¾ m mᵀ` (`E z⁴ = 3`), uncorrelated with the linear errors (a Gaussian's
//! third moments vanish): a consider parameter of a Schmidt–Kalman filter, `x_lin + s u`
//! with `E s² = κ`. The filter carries it as a 15-vector `u` beside P, the term's
//! direction in the error state: `u` goes through the transitions (`u ← Φ u`) and the
//! updates (`u ← (I − K H) u`) as an error does, gains `δ = σ_ψ² Σ v̂_h dt` in its
//! position rows at each covariance step (or sample), and P holds `P_lin + κ u uᵀ`
//! (`κ` = [`KAPPA`]): at each gain `P += κ ((u + δ)(u + δ)ᵀ − u uᵀ)`. The gains, the
//! NIS, σ and every covariance read out then include the term.

use super::state::{Matrix15, Vector15, ATT, POS};
use nalgebra::{SMatrix, Vector2, Vector3};

/// The term's second moment per `m mᵀ`: `¾`, that of `½ z² m` for `z ~ N(0, 1)`.
pub const KAPPA: f64 = 0.75;

/// The term's state: its direction `u` in the error state, and the horizontal
/// displacement \[m, north and east\] since it last grew.
#[derive(Clone, Debug, PartialEq)]
pub struct SecondOrder {
    pub(super) u: Vector15,
    distance: Vector2<f64>,
}

impl Default for SecondOrder {
    fn default() -> Self {
        Self {
            u: Vector15::zeros(),
            distance: Vector2::zeros(),
        }
    }
}

impl SecondOrder {
    /// The term's direction in the error state (the filter's coordinates) \[m\]: its
    /// covariance is `KAPPA u uᵀ`.
    pub fn direction(&self) -> &Vector15 {
        &self.u
    }

    /// The heading variance of the linear part of P, `P[ψ_D, ψ_D] − κ u_ψ²` \[rad²\]
    /// (after a horizontal fix `u` has a heading component: the term's own share is not
    /// heading uncertainty that grows it).
    pub(super) fn linear_heading_variance(&self, p: &Matrix15) -> f64 {
        p[(ATT + 2, ATT + 2)] - KAPPA * self.u[ATT + 2] * self.u[ATT + 2]
    }

    /// Add the horizontal distance run over one IMU sample at the NED velocity `vel`
    /// \[m/s\] for `dt` \[s\].
    pub(super) fn run(&mut self, vel: &Vector3<f64>, dt: f64) {
        self.distance += Vector2::new(vel[0], vel[1]) * dt;
    }

    /// `u ← Φ u` over one IMU sample, `Φ = I + F dt`, with `f_u` the navigation rows of
    /// `F u`.
    pub(super) fn step(&mut self, f_u: &[f64; 9], dt: f64) {
        for (u, f) in self.u.iter_mut().zip(f_u) {
            *u += f * dt;
        }
    }

    /// `u ← Φ u` with `apply` the transition of a covariance step (`X ← Φ X`).
    pub(super) fn transition(&mut self, apply: impl FnOnce(&mut SMatrix<f64, 15, 1>)) {
        apply(&mut self.u);
    }

    /// The term's growth over the distance run since the last: `δ = σ_ψ² d` in the
    /// position rows (`heading_variance` \[rad²\] at the start of that stretch), `P +=
    /// κ ((u + δ)(u + δ)ᵀ − u uᵀ)`, `u += δ`, the distance reset.
    pub(super) fn grow(&mut self, p: &mut Matrix15, heading_variance: f64) {
        let delta = self.distance * heading_variance.max(0.0);
        self.distance = Vector2::zeros();
        if delta == Vector2::zeros() {
            return;
        }
        let mut after = self.u;
        after[POS] += delta[0];
        after[POS + 1] += delta[1];
        // Only the rows and columns δ moves change: elsewhere `after` is `u` and the
        // change is exactly zero (56 elements instead of 225, the same numbers).
        let u = &self.u;
        for i in POS..POS + 2 {
            for j in 0..15 {
                let change = KAPPA * (after[i] * after[j] - u[i] * u[j]);
                p[(i, j)] += change;
                if !(POS..POS + 2).contains(&j) {
                    p[(j, i)] += change;
                }
            }
        }
        self.u = after;
    }

    /// `u ← (I − K H) u` for an update applied with gain `k` and rows `h`.
    pub(super) fn update<const R: usize>(
        &mut self,
        k: &SMatrix<f64, 15, R>,
        h: &SMatrix<f64, R, 15>,
    ) {
        let hu = h * self.u;
        self.u -= k * hu;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_term_grows_with_the_heading_variance_along_the_distance_run() {
        let mut s = SecondOrder::default();
        let mut p = Matrix15::identity();
        s.run(&Vector3::new(1.0, 2.0, 5.0), 0.5);
        s.run(&Vector3::new(1.0, 0.0, 5.0), 0.5);
        s.grow(&mut p, 0.01);
        // d = (1, 1) m (the vertical velocity does not count): u = 0.01 (1, 1).
        assert_eq!(s.u[POS], 0.01);
        assert_eq!(s.u[POS + 1], 0.01);
        assert_eq!(s.u.rows(2, 13).abs().max(), 0.0);
        assert_eq!(p[(0, 0)], 1.0 + KAPPA * 1e-4);
        assert_eq!(p[(0, 1)], KAPPA * 1e-4);
        assert_eq!(p[(2, 2)], 1.0);
        // The next growth adds the cross terms: P − P_lin stays κ u uᵀ.
        s.run(&Vector3::new(0.0, 3.0, 0.0), 1.0);
        s.grow(&mut p, 0.02);
        let expected = Matrix15::identity() + s.u * s.u.transpose() * KAPPA;
        assert!((p - expected).abs().max() < 1e-15, "{}", p - expected);
        // Nothing run, nothing grows; a negative rounding residue counts as none.
        let before = (s.clone(), p);
        s.grow(&mut p, 0.5);
        s.run(&Vector3::new(1.0, 0.0, 0.0), 1.0);
        s.grow(&mut p, -1e-20);
        assert_eq!((s.u, p), (before.0.u, before.1));
    }

    #[test]
    fn the_term_goes_through_an_update_as_an_error_does() {
        let mut s = SecondOrder::default();
        s.u[POS] = 2.0;
        s.u[POS + 1] = -1.0;
        // A north fix with gain 0.25 on north and 0.1 on the north velocity.
        let mut h = SMatrix::<f64, 1, 15>::zeros();
        h[(0, POS)] = 1.0;
        let mut k = SMatrix::<f64, 15, 1>::zeros();
        k[(POS, 0)] = 0.25;
        k[(3, 0)] = 0.1;
        s.update(&k, &h);
        assert_eq!(s.u[POS], 1.5);
        assert_eq!(s.u[POS + 1], -1.0);
        assert_eq!(s.u[3], -0.2);
    }
}

#[cfg(test)]
mod filter_tests {
    use super::{SecondOrder, KAPPA};
    use crate::ekf::tests::{dvl, dvl_at_estimate, moving_state};
    use crate::ekf::{Ekf, FilterConfig, ProcessNoise, Vector15, DEFAULT_P0_SIGMA};
    use crate::measurement::Fix;
    use crate::mechanization::ImuSample;
    use nalgebra::Vector3;

    const Q: [f64; 6] = [1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8];
    const NOISE: ProcessNoise<'static> = ProcessNoise::Continuous {
        imu_variance: &Q,
        bias_psd: &[1e-9; 6],
    };
    /// A turn at 0.02 rad/s, a little forward acceleration.
    const RAW: ImuSample = ImuSample {
        accel: Vector3::new(0.05, 0.0, -9.79),
        gyro: Vector3::new(0.0, 0.0, 0.02),
    };

    /// The default tuning with the heading 0.3 rad (17°) uncertain, so that the term grows.
    fn uncertain_heading() -> FilterConfig {
        let mut p0_sigma = DEFAULT_P0_SIGMA;
        p0_sigma[8] = 0.3;
        FilterConfig {
            p0_sigma,
            ..FilterConfig::default()
        }
    }

    fn started(cfg: &FilterConfig) -> Ekf {
        let zero = Vector3::zeros();
        Ekf::new(cfg, moving_state(), zero, zero).unwrap()
    }

    /// A horizontal fix of 0.5 m at the filter's estimate.
    fn fix_at(ekf: &Ekf) -> Fix {
        Fix {
            lla: [ekf.nav.lla[0], ekf.nav.lla[1], f64::NAN],
            sigma: [0.5; 3],
            lever_arm: Vector3::zeros(),
        }
    }

    fn direction(ekf: &Ekf) -> Vector15 {
        ekf.second_order
            .as_deref()
            .map(SecondOrder::direction)
            .unwrap()
            .to_owned()
    }

    /// Side by side with the linear filter on the same readings (a DVL every 0.2 s):
    /// the filter with the term holds `P_lin + κ u uᵀ` (to the gains' small change: `u`
    /// leaks into the velocity rows through Φ, where the DVL sees it), the same
    /// solution, and a horizontal fix shrinks the term; at every sample and under a
    /// covariance step.
    #[test]
    fn the_filter_holds_the_linear_covariance_plus_the_term() {
        for covariance_step in [0.0, 0.1] {
            let linear_cfg = FilterConfig {
                covariance_step,
                ..uncertain_heading()
            };
            let cfg = FilterConfig {
                heading_second_order: true,
                ..linear_cfg.clone()
            };
            let (mut on, mut off) = (started(&cfg), started(&linear_cfg));
            for k in 1..=600 {
                for ekf in [&mut on, &mut off] {
                    ekf.propagate(&RAW, 0.01, NOISE).unwrap();
                }
                if k % 20 == 0 {
                    let z = Vector3::new(1.1, 0.4, 0.05);
                    for ekf in [&mut on, &mut off] {
                        ekf.apply(&dvl(ekf, z)).unwrap();
                    }
                }
            }
            let u = direction(&on);
            let lin = on.p - u * u.transpose() * KAPPA;
            let scale = off.p.abs().max();
            assert!(
                (lin - off.p).abs().max() < 1e-6 * scale,
                "{covariance_step}"
            );
            // 2e-11 rad (0.1 mm) and 3e-11 m/s apart at the end: the leak alone.
            assert!((on.nav.lla - off.nav.lla).abs().max() < 1e-9);
            assert!((on.nav.vel - off.nav.vel).abs().max() < 1e-8);
            assert!(u[0].hypot(u[1]) > 0.1, "{u}");
            let (wide, narrow) = (on.p[(0, 0)] + on.p[(1, 1)], off.p[(0, 0)] + off.p[(1, 1)]);
            assert!(wide > narrow + 0.01, "{wide} {narrow} {u}");
            // A horizontal fix at the estimate: the term shrinks with the position σ.
            let before = u[0].hypot(u[1]);
            on.apply(&fix_at(&on)).unwrap();
            let u = direction(&on);
            assert!(u[0].hypot(u[1]) < 0.7 * before, "{before} {u}");
            let lin = on.p - u * u.transpose() * KAPPA;
            let smallest = lin.symmetric_eigenvalues().min();
            assert!(smallest > -1e-12 * lin.abs().max(), "{smallest}");
        }
    }

    /// A DVL reading the gate rejects leaves the term's direction as it leaves P; one
    /// it accepts moves it (after a fix has put `u` into the velocity rows, where the
    /// DVL sees it).
    #[test]
    fn a_rejected_reading_leaves_the_term_alone() {
        let cfg = FilterConfig {
            innovation_gate: Some(16.27),
            heading_second_order: true,
            ..uncertain_heading()
        };
        let mut ekf = started(&cfg);
        for _ in 0..500 {
            ekf.propagate(&RAW, 0.01, NOISE).unwrap();
        }
        ekf.apply(&fix_at(&ekf)).unwrap();
        let before = direction(&ekf);
        assert!(before.rows(3, 3).abs().max() > 0.0, "{before}");
        let predicted = dvl_at_estimate(&ekf).z;
        let far = dvl(&ekf, predicted + Vector3::new(5.0, 0.0, 0.0));
        assert!(!ekf.apply(&far).unwrap().report.unwrap().accepted);
        assert_eq!(direction(&ekf), before);
        let near = dvl(&ekf, predicted + Vector3::new(0.01, 0.0, 0.0));
        assert!(ekf.apply(&near).unwrap().report.unwrap().accepted);
        assert_ne!(direction(&ekf), before);
    }
}

#[cfg(test)]
mod config_tests {
    use crate::ekf::calibration::CalibrationConfig;
    use crate::ekf::{FilterConfig, Formulation};

    #[test]
    fn the_term_is_refused_where_its_position_error_is_not_the_filters() {
        let with = |cfg: FilterConfig| FilterConfig {
            heading_second_order: true,
            ..cfg
        };
        for cfg in [
            with(FilterConfig {
                formulation: Formulation::Se23,
                ..FilterConfig::default()
            }),
            with(FilterConfig {
                dvl_calibration: Some(CalibrationConfig::default()),
                ..FilterConfig::default()
            }),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.starts_with("heading_second_order"), "{e}");
        }
        for formulation in [Formulation::Classic, Formulation::Invariant] {
            with(FilterConfig {
                formulation,
                ..FilterConfig::default()
            })
            .validate()
            .unwrap();
        }
    }
}
