//! The error dynamics of the 15-state filter: the nonzero blocks of F, the block-sparse
//! propagation `P ← Φ P Φᵀ` with `Φ = I + F Δt`, and the IMU white-noise term of Q_d.
//! Every formula is in `docs/filter.md`.

use super::{Matrix15, ACC_BIAS, ATT, GYRO_BIAS, POS, VEL};
use crate::attitude::skew;
use crate::mechanization::{FrameRates, NavState};
use nalgebra::{Matrix3, Vector3};

/// The nonzero blocks of the error dynamics F (see `docs/filter.md`).
pub(super) struct ErrorDynamics {
    pos_pos: Matrix3<f64>,
    vel_pos: Vector3<f64>,
    vel_vel: Matrix3<f64>,
    vel_att: Matrix3<f64>,
    vel_abias: Matrix3<f64>,
    att_att: Matrix3<f64>,
    att_gbias: Matrix3<f64>,
}

impl ErrorDynamics {
    pub(super) fn new(nav: &NavState, rates: &FrameRates, f_body: &Vector3<f64>) -> Self {
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
    pub(super) fn propagate_covariance(&self, p: &mut Matrix15, dt: f64) {
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

/// Add the IMU white noise of one step to the velocity and attitude blocks of `p`:
/// `C diag(q_a) Cᵀ·white` and `C diag(q_g) Cᵀ·white` (`white = Δt_imu·Δt`), each added
/// symmetrized so that `p` stays exactly symmetric.
pub(super) fn add_imu_noise(p: &mut Matrix15, c: &Matrix3<f64>, q: &[f64; 6], white: f64) {
    let qa = c * Matrix3::from_diagonal(&Vector3::new(q[0], q[1], q[2])) * c.transpose();
    let qg = c * Matrix3::from_diagonal(&Vector3::new(q[3], q[4], q[5])) * c.transpose();
    let mut blk = |at: usize, m: Matrix3<f64>| {
        let mut view = p.fixed_view_mut::<3, 3>(at, at);
        view += (m + m.transpose()) * 0.5;
    };
    blk(VEL, qa * white);
    blk(ATT, qg * white);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::tests::moving_state;

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
}
