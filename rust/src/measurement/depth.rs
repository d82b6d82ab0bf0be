//! A depth reading: a pressure sensor at a lever arm from the IMU.
//!
//! `ẑ = −ĥ + (Ĉ r)_D` \[m, positive down\] (a sensor 1 m below a level IMU reads 1 m
//! deeper); `H = e_D` on the position error and row D of `[(Ĉ r)×]` on ψ
//! (`Ĉ − C = −[ψ×] C`), the same in the classic and invariant formulations; SE₂(3)
//! adds row D of `[p̂×]` on ψ (`δp = δP + [p̂×]ψ`). `docs/reference/aiding.md`, "Lever arms
//! and heading".

use crate::attitude::skew;
use crate::ekf::{Ekf, Linearized, Measurement, Row15, ScalarRow, ATT, POS};
use crate::error::{Error, Result};
use nalgebra::Vector3;

/// One depth reading `z` \[m, positive down\] of 1σ `sigma` \[m\] from a sensor at
/// `lever_arm` \[m, body FRD\] from the IMU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Depth {
    pub z: f64,
    pub sigma: f64,
    pub lever_arm: Vector3<f64>,
}

impl Measurement for Depth {
    fn name(&self) -> &'static str {
        "depth"
    }

    fn linearize(&self, _: usize, ekf: &Ekf) -> Linearized {
        let z = self.z + ekf.nav.lla[2]; // z − ẑ with ẑ = −ĥ at the IMU
        position_component(ekf, &self.lever_arm, 2, z, self.sigma * self.sigma, 1.0)
    }
}

/// The scalar update of a position component `axis` (0 north, 1 east, 2 down) read at
/// `lever_arm` from the IMU, its innovation at the IMU `at_imu` and its variance `r`
/// (metres at the estimate), taken in metres `scale` times those (SE₂(3)'s anchor's;
/// 1 otherwise): the unit row on δp at the IMU in the classic and invariant
/// formulations; otherwise [`offset_row`], and in SE₂(3) (`δp = δP + [p̂×]ψ`, both in
/// the anchor's metres) row `axis` of `[p̂×]` added on ψ.
pub(super) fn position_component(
    ekf: &Ekf,
    lever_arm: &Vector3<f64>,
    axis: usize,
    at_imu: f64,
    r: f64,
    scale: f64,
) -> Linearized {
    let se23 = ekf.config().formulation.position_invariant();
    if *lever_arm == Vector3::zeros() && !se23 {
        return Linearized::Scalar {
            innovation: at_imu,
            row: ScalarRow::Unit(POS + axis),
            r,
        };
    }
    let (innovation, mut row) = offset_row(ekf, lever_arm, axis, at_imu);
    if se23 {
        // the reading in the anchor's metres: all but δP's unit scaled, then [p̂×]
        let d = skew(&ekf.point().disp);
        let mut att = row.fixed_columns_mut::<3>(ATT);
        att *= scale;
        att += d.row(axis);
        return Linearized::Scalar {
            innovation: scale * innovation,
            row: ScalarRow::Row(row),
            r: scale * scale * r,
        };
    }
    Linearized::Scalar {
        innovation,
        row: ScalarRow::Row(row),
        r,
    }
}

/// A position component `axis` (0 north, 1 east, 2 down) read at `lever_arm` from
/// the IMU: the innovation at the IMU `at_imu` less the arm's component `(Ĉ r)_axis`,
/// and the row `e_axis` on δp plus row `axis` of `[(Ĉ r)×]` on ψ.
fn offset_row(ekf: &Ekf, lever_arm: &Vector3<f64>, axis: usize, at_imu: f64) -> (f64, Row15) {
    let arm = ekf.nav.dcm * lever_arm;
    let mut row = Row15::zeros();
    row[POS + axis] = 1.0;
    row.fixed_columns_mut::<3>(ATT)
        .copy_from(&skew(&arm).row(axis));
    (at_imu - arm[axis], row)
}

/// The depth sensor's 1σ \[m\]: finite and > 0 (checked wherever one is given, readings
/// or not).
pub fn check_depth_sigma(depth_sigma: f64) -> Result<()> {
    if depth_sigma > 0.0 && depth_sigma.is_finite() {
        return Ok(());
    }
    Err(Error::invalid(
        "depth_sigma",
        format!("must be a finite number of metres > 0, got {}", depth_sigma),
    ))
}
