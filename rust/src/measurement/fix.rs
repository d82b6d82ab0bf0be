//! A position fix: latitude, longitude and (optionally) height of an antenna or
//! transponder at a lever arm from the IMU.
//!
//! One scalar update per component, north, east and (with a height) down, each
//! linearized at the estimate the previous one left: `ν_N = (φ − φ̂)(R_N + ĥ) − (Ĉr)_N`,
//! `ν_E = (λ − λ̂)(R_E + ĥ) cos φ̂ − (Ĉr)_E` (the longitude difference wrapped into
//! (−π, π]), `ν_D = (ĥ − h) − (Ĉr)_D`; `H = e_i` on δp plus row i of `[(Ĉ r)×]` on ψ
//! (and of `[p̂×]` in SE₂(3)). In SE₂(3) the reading is taken in the anchor's metres,
//! those its position error `δP` is in: innovation, arm and σ scaled by the anchor's
//! metres per metre at the estimate, so that H is exact however far the estimate is
//! from the anchor.
//! No innovation gate applies. `docs/reference/aiding.md`, "Position and depth updates" and
//! "Lever arms and heading".

use super::depth::position_component;
use crate::attitude::wrap_angle;
use crate::earth;
use crate::ekf::{Ekf, Linearized, Measurement};
use nalgebra::Vector3;

/// One fix `lla = [φ (rad), λ (rad), h (m, up)]` (a NaN height: horizontal only) with
/// 1σ `sigma` \[m\] north, east, down, of an antenna at `lever_arm` \[m, body FRD\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    pub lla: [f64; 3],
    pub sigma: [f64; 3],
    pub lever_arm: Vector3<f64>,
}

impl Measurement for Fix {
    fn name(&self) -> &'static str {
        "fix"
    }

    fn components(&self) -> usize {
        if self.lla[2].is_nan() {
            2
        } else {
            3
        }
    }

    fn linearize(&self, axis: usize, ekf: &Ekf) -> Linearized {
        let fix = &self.lla;
        let (r_n, r_e) = earth::radii(ekf.nav.lla[0]);
        let (lat, lon, h) = (ekf.nav.lla[0], ekf.nav.lla[1], ekf.nav.lla[2]);
        let at_imu = match axis {
            0 => (fix[0] - lat) * (r_n + h),
            1 => longitude_difference(fix[1], lon) * (r_e + h) * lat.cos(),
            _ => h - fix[2],
        };
        let r = self.sigma[axis] * self.sigma[axis];
        position_component(
            ekf,
            &self.lever_arm,
            axis,
            at_imu,
            r,
            anchor_metres(ekf, axis),
        )
    }
}

/// Anchor metres per metre at the estimate along `axis` in SE₂(3) (its position error
/// `δP` is in the anchor's metres: the radii, height and latitude of the anchor), 1 in
/// the other formulations and down: `(R_N₀ + h₀)/(R_N + ĥ)` north,
/// `(R_E₀ + h₀) cos φ₀ / ((R_E + ĥ) cos φ̂)` east.
fn anchor_metres(ekf: &Ekf, axis: usize) -> f64 {
    let coordinates = ekf.config().coordinates();
    if !coordinates.formulation.position_invariant() || axis == 2 {
        return 1.0;
    }
    let metres = |lla: &Vector3<f64>| {
        let (r_n, r_e) = earth::radii(lla[0]);
        match axis {
            0 => r_n + lla[2],
            _ => (r_e + lla[2]) * lla[0].cos(),
        }
    };
    metres(&coordinates.anchor) / metres(&ekf.nav.lla)
}

/// `lon − lon_hat` \[rad\] wrapped into (−π, π]: longitude is periodic (a fix across the
/// antimeridian, or given 0–360° against an estimate in ±180°, is metres away, not a
/// turn of the Earth). Within (−π, π] the difference is kept to the bit.
fn longitude_difference(lon: f64, lon_hat: f64) -> f64 {
    let d = lon - lon_hat;
    if d > -std::f64::consts::PI && d <= std::f64::consts::PI {
        d
    } else {
        wrap_angle(d)
    }
}
