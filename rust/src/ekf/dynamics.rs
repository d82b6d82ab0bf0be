//! The error dynamics of the 15-state filter: the nonzero blocks of F, the block-sparse
//! propagation `P ← Φ P Φᵀ` with `Φ = I + F Δt`, and the IMU white-noise term of Q_d,
//! in either [`Formulation`]. Every formula is in `docs/reference/filter.md`.

use super::formulation::{Formulation, Point};
use super::state::{Matrix15, ACC_BIAS, ATT, GYRO_BIAS, NAV, POS, VEL};
use super::transition::Transition;
use crate::attitude::skew;
use crate::mechanization::{FrameRates, NavState};
use multiversion::multiversion;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// The nonzero blocks of the error dynamics F (see `docs/reference/filter.md`). The classic
/// formulation has no `pos_att`, `pos_gbias` and `vel_gbias` blocks and a skew
/// `vel_att`; the invariant one has `pos_att` (skew), `vel_gbias` and a full `vel_att`;
/// SE₂(3) has all four, `pos_att` full.
#[derive(Clone, Debug)]
pub(crate) struct ErrorDynamics {
    pos_pos: Matrix3<f64>,
    pos_att: Matrix3<f64>,
    pos_gbias: Matrix3<f64>,
    vel_pos: Vector3<f64>,
    vel_vel: Matrix3<f64>,
    vel_att: Matrix3<f64>,
    vel_abias: Matrix3<f64>,
    vel_gbias: Matrix3<f64>,
    att_att: Matrix3<f64>,
    att_gbias: Matrix3<f64>,
    formulation: Formulation,
}

/// [`Formulation`] as a const generic parameter (the loops are monomorphized per
/// formulation).
const CLASSIC: u8 = 0;
const INVARIANT: u8 = 1;
const SE23: u8 = 2;

impl ErrorDynamics {
    pub(crate) fn new(
        nav: &NavState,
        rates: &FrameRates,
        f_body: &Vector3<f64>,
        at: &Point,
    ) -> Self {
        Self::with_force(nav, rates, &(nav.dcm * f_body), at)
    }

    /// [`Self::new`] with the specific force given in NED, `Ĉ f̂` (a covariance step's
    /// mean over its interval). `at` gives the formulation and, in SE₂(3), the position
    /// estimate's displacement from the anchor.
    pub(crate) fn with_force(
        nav: &NavState,
        rates: &FrameRates,
        f_ned: &Vector3<f64>,
        at: &Point,
    ) -> Self {
        let formulation = at.formulation;
        let radius = (rates.latitude.r_n * rates.latitude.r_e).sqrt() + nav.lla[2];
        let schuler = rates.gravity[2] / radius;
        let c = nav.dcm;
        let v = skew(&nav.vel);
        let vel_pos = Vector3::new(-schuler, -schuler, 2.0 * schuler);
        let (mut pos_att, mut vel_att, vel_gbias) = if formulation.velocity_invariant() {
            (v, -skew(&rates.gravity) - v * skew(&rates.earth), -v * c)
        } else {
            (Matrix3::zeros(), skew(f_ned), Matrix3::zeros())
        };
        let mut pos_gbias = Matrix3::zeros();
        if formulation.position_invariant() {
            // δp = δP + [p̂×]ψ in the classic rows, and −[p̂×]ψ̇
            // (docs/reference/filter.md).
            let d = skew(&at.disp);
            pos_att = d * skew(&rates.nav_rate()) - skew(&rates.transport) * d;
            pos_gbias = -d * c;
            vel_att += Matrix3::from_diagonal(&vel_pos) * d;
        }
        Self {
            pos_pos: -skew(&rates.transport),
            pos_att,
            pos_gbias,
            vel_pos,
            vel_vel: -skew(&(2.0 * rates.earth + rates.transport)),
            vel_att,
            vel_abias: -c,
            vel_gbias,
            att_att: -skew(&rates.nav_rate()),
            att_gbias: c,
            formulation,
        }
    }

    /// Rows 0..9 of `F x` for a 15-vector `x` (the bias rows of F are zero): about 60
    /// multiply-adds instead of 225.
    pub(crate) fn apply(&self, x: &[f64]) -> [f64; 9] {
        match self.formulation {
            Formulation::Classic => self.apply_in::<CLASSIC>(x),
            Formulation::Invariant => self.apply_in::<INVARIANT>(x),
            Formulation::Se23 => self.apply_in::<SE23>(x),
        }
    }

    /// `Fᵀ x` for a 15-vector `x` (only its navigation rows 0..9 are read, the bias
    /// rows of F being zero): the smoother's backward products, about 60
    /// multiply-adds instead of 135.
    #[inline]
    pub(crate) fn apply_transposed(&self, x: &[f64]) -> [f64; 15] {
        let v = |at: usize| Vector3::new(x[at], x[at + 1], x[at + 2]);
        let (xp, xv, xa) = (v(POS), v(VEL), v(ATT));
        let pos = self.pos_pos.tr_mul(&xp) + self.vel_pos.component_mul(&xv);
        let vel = xp + self.vel_vel.tr_mul(&xv);
        let mut att = self.vel_att.tr_mul(&xv) + self.att_att.tr_mul(&xa);
        let abias = self.vel_abias.tr_mul(&xv);
        let mut gbias = self.att_gbias.tr_mul(&xa);
        if self.formulation.velocity_invariant() {
            att += self.pos_att.tr_mul(&xp);
            gbias += self.vel_gbias.tr_mul(&xv);
        }
        if self.formulation.position_invariant() {
            gbias += self.pos_gbias.tr_mul(&xp);
        }
        let mut out = [0.0; 15];
        for (at, b) in [
            (POS, pos),
            (VEL, vel),
            (ATT, att),
            (ACC_BIAS, abias),
            (GYRO_BIAS, gbias),
        ] {
            out[at..at + 3].copy_from_slice(b.as_slice());
        }
        out
    }

    /// [`Self::apply`] for one formulation. The skew-symmetric blocks skip their zero
    /// diagonal, which leaves every sum bit-identical (`0·x + y = y` for finite x).
    #[inline(always)]
    fn apply_in<const FORM: u8>(&self, x: &[f64]) -> [f64; 9] {
        #[inline(always)]
        fn mv(a: &Matrix3<f64>, x: &[f64]) -> [f64; 3] {
            let a = a.as_slice(); // column-major
            [
                a[0] * x[0] + a[3] * x[1] + a[6] * x[2],
                a[1] * x[0] + a[4] * x[1] + a[7] * x[2],
                a[2] * x[0] + a[5] * x[1] + a[8] * x[2],
            ]
        }
        #[inline(always)]
        fn skew_mv(a: &Matrix3<f64>, x: &[f64]) -> [f64; 3] {
            let a = a.as_slice();
            [
                a[3] * x[1] + a[6] * x[2],
                a[1] * x[0] + a[7] * x[2],
                a[2] * x[0] + a[5] * x[1],
            ]
        }
        let (xp, xv, xa) = (&x[POS..POS + 3], &x[VEL..VEL + 3], &x[ATT..ATT + 3]);
        let (xba, xbg) = (&x[ACC_BIAS..ACC_BIAS + 3], &x[GYRO_BIAS..GYRO_BIAS + 3]);
        let pp = skew_mv(&self.pos_pos, xp);
        let vv = skew_mv(&self.vel_vel, xv);
        let va = if FORM != CLASSIC {
            mv(&self.vel_att, xa)
        } else {
            skew_mv(&self.vel_att, xa)
        };
        let vb = mv(&self.vel_abias, xba);
        let (aa, ab) = (skew_mv(&self.att_att, xa), mv(&self.att_gbias, xbg));
        let mut o = [0.0; 9];
        for r in 0..3 {
            o[POS + r] = pp[r] + xv[r];
            o[VEL + r] = self.vel_pos[r] * xp[r] + vv[r] + va[r] + vb[r];
            o[ATT + r] = aa[r] + ab[r];
        }
        if FORM == INVARIANT {
            let (pa, vg) = (skew_mv(&self.pos_att, xa), mv(&self.vel_gbias, xbg));
            for r in 0..3 {
                o[POS + r] += pa[r];
                o[VEL + r] += vg[r];
            }
        }
        if FORM == SE23 {
            let (pa, vg) = (mv(&self.pos_att, xa), mv(&self.vel_gbias, xbg));
            let pg = mv(&self.pos_gbias, xbg);
            for r in 0..3 {
                o[POS + r] += pa[r] + pg[r];
                o[VEL + r] += vg[r];
            }
        }
        o
    }

    /// `P ← Φ P Φᵀ` with `Φ = I + F Δt`, using that P is symmetric and that the bias
    /// rows of F are zero: `Φ P Φᵀ = P + Δt (A + Aᵀ) + Δt² F Aᵀ` with `A = F P`, whose
    /// rows 9..15 vanish, so `F Aᵀ` is needed on its 9×9 navigation block only and the
    /// bias-bias block of P is unchanged. The result is written symmetrized.
    ///
    /// Each row of A is a short combination of whole columns of P (row k of a symmetric
    /// P is its column k), so A is built from contiguous 15-vectors that the compiler
    /// vectorizes; an AVX2 copy of the same code is chosen at run time where the CPU
    /// has it. Both copies do the same additions in the same order (no FMA), so the
    /// result does not depend on the CPU.
    pub(crate) fn propagate_covariance(&self, p: &mut Matrix15, dt: f64) {
        propagate_covariance(self, p, dt)
    }

    #[inline(always)]
    fn propagate_covariance_portable(&self, p: &mut Matrix15, dt: f64) {
        match self.formulation {
            Formulation::Classic => self.propagate_in::<CLASSIC>(p, dt),
            Formulation::Invariant => self.propagate_in::<INVARIANT>(p, dt),
            Formulation::Se23 => self.propagate_in::<SE23>(p, dt),
        }
    }

    #[inline(always)]
    fn propagate_in<const FORM: u8>(&self, p: &mut Matrix15, dt: f64) {
        let a = self.times::<FORM>(p);
        // M = Δt A + ½Δt² F Aᵀ on the navigation block, m[j][i] = M[i, j] (column j of
        // F Aᵀ is F times row j of A); the block gains M + Mᵀ, which is exactly
        // symmetric since addition commutes.
        let half_dt2 = 0.5 * (dt * dt);
        let mut m = [[0.0; NAV]; NAV];
        for (j, col) in m.iter_mut().enumerate() {
            let b = self.apply_in::<FORM>(&a[j]);
            for (i, v) in col.iter_mut().enumerate() {
                *v = dt * a[i][j] + half_dt2 * b[i];
            }
        }
        let s = p.as_mut_slice(); // column-major
        for j in 0..NAV {
            let col = &mut s[15 * j..15 * j + 15];
            for i in 0..NAV {
                col[i] += m[j][i] + m[i][j];
            }
            // Rows 9..15 of a navigation column: P[bias, j] + Δt A[j, bias].
            for (v, a) in col[NAV..].iter_mut().zip(&a[j][NAV..]) {
                *v += dt * a;
            }
        }
        // The bias columns' navigation rows mirror them; the bias-bias block is unchanged.
        for j in NAV..15 {
            for i in 0..NAV {
                s[15 * j + i] = s[15 * i + j];
            }
        }
    }

    /// Rows 0..9 of `A = F P` for a symmetric P, each row a 15-array:
    /// `A[i, :] = Σ_k F[i, k] P[:, k]`; `FORM` adds the blocks only the invariant
    /// formulations have (and takes `vel_att`, and in SE₂(3) `pos_att`, as full).
    #[inline(always)]
    fn times<const FORM: u8>(&self, p: &Matrix15) -> [[f64; 15]; 9] {
        #[inline(always)]
        fn col(p: &Matrix15, k: usize) -> &[f64; 15] {
            p.as_slice()[15 * k..15 * k + 15] // column-major
                .try_into()
                .expect("a 15x15 matrix has 15-long columns")
        }
        #[inline(always)]
        fn add(out: &mut [f64; 15], coef: f64, x: &[f64; 15]) {
            for (o, x) in out.iter_mut().zip(x) {
                *o += coef * x;
            }
        }
        // Σ over the three columns of row r of a 3x3 block of F starting at column `at`.
        #[inline(always)]
        fn block(out: &mut [f64; 15], m: &Matrix3<f64>, r: usize, p: &Matrix15, at: usize) {
            for c in 0..3 {
                add(out, m[(r, c)], col(p, at + c));
            }
        }
        // The same for a skew-symmetric block, whose diagonal is zero.
        #[inline(always)]
        fn skew_block(out: &mut [f64; 15], m: &Matrix3<f64>, r: usize, p: &Matrix15, at: usize) {
            let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
            add(out, m[(r, c1)], col(p, at + c1));
            add(out, m[(r, c2)], col(p, at + c2));
        }
        // Each row starts as its first term (so the zeroing is a dead store).
        let mut a = [[0.0; 15]; 9];
        for r in 0..3 {
            let row = &mut a[POS + r];
            *row = *col(p, VEL + r);
            skew_block(row, &self.pos_pos, r, p, POS);
            if FORM == INVARIANT {
                skew_block(row, &self.pos_att, r, p, ATT);
            }
            if FORM == SE23 {
                block(row, &self.pos_att, r, p, ATT);
                block(row, &self.pos_gbias, r, p, GYRO_BIAS);
            }
            let row = &mut a[VEL + r];
            *row = col(p, POS + r).map(|x| self.vel_pos[r] * x);
            skew_block(row, &self.vel_vel, r, p, VEL);
            if FORM != CLASSIC {
                block(row, &self.vel_att, r, p, ATT);
                block(row, &self.vel_gbias, r, p, GYRO_BIAS);
            } else {
                skew_block(row, &self.vel_att, r, p, ATT);
            }
            block(row, &self.vel_abias, r, p, ACC_BIAS);
            let row = &mut a[ATT + r];
            *row = col(p, GYRO_BIAS).map(|x| self.att_gbias[(r, 0)] * x);
            add(row, self.att_gbias[(r, 1)], col(p, GYRO_BIAS + 1));
            add(row, self.att_gbias[(r, 2)], col(p, GYRO_BIAS + 2));
            skew_block(row, &self.att_att, r, p, ATT);
        }
        a
    }
}

impl ErrorDynamics {
    /// Rows 0..9 of F, dense (its bias rows are zero).
    #[inline(always)]
    pub(crate) fn nav_rows(&self) -> SMatrix<f64, NAV, 15> {
        let mut f = SMatrix::<f64, NAV, 15>::zeros();
        let mut put =
            |r: usize, c: usize, m: &Matrix3<f64>| f.fixed_view_mut::<3, 3>(r, c).copy_from(m);
        put(POS, POS, &self.pos_pos);
        put(POS, VEL, &Matrix3::identity());
        put(POS, ATT, &self.pos_att);
        put(POS, GYRO_BIAS, &self.pos_gbias);
        put(VEL, POS, &Matrix3::from_diagonal(&self.vel_pos));
        put(VEL, VEL, &self.vel_vel);
        put(VEL, ATT, &self.vel_att);
        put(VEL, ACC_BIAS, &self.vel_abias);
        put(VEL, GYRO_BIAS, &self.vel_gbias);
        put(ATT, ATT, &self.att_att);
        put(ATT, GYRO_BIAS, &self.att_gbias);
        f
    }

    /// The transition over a covariance step of `dt` seconds with F held constant:
    /// `Φ = I + F Δt + ½ (F Δt)²`, second order in Δt.
    pub(crate) fn transition(&self, dt: f64) -> Transition {
        transition(self, dt)
    }

    #[inline(always)]
    fn transition_portable(&self, dt: f64) -> Transition {
        Transition::second_order(&(self.nav_rows() * dt)).spanning(dt)
    }
}

// The AVX2 copies of the two kernels above, chosen at run time by `multiversion`
// where the CPU has AVX2 (free functions: it does not take `self`).

#[multiversion(targets("x86_64+avx2"))]
fn propagate_covariance(d: &ErrorDynamics, p: &mut Matrix15, dt: f64) {
    d.propagate_covariance_portable(p, dt)
}

#[multiversion(targets("x86_64+avx2"))]
fn transition(d: &ErrorDynamics, dt: f64) -> Transition {
    d.transition_portable(dt)
}

/// Add the IMU white noise of one step to the velocity and attitude blocks of `p`:
/// `Q_a = C diag(q_a) Cᵀ·white` and `Q_g = C diag(q_g) Cᵀ·white` (`white = Δt_imu·Δt`),
/// each added symmetrized so that `p` stays exactly symmetric. In the invariant
/// formulations the gyro noise also drives `δV = δv − [v×]ψ`: the velocity block gains
/// `[v×] Q_g [v×]ᵀ` and the velocity–attitude block `−[v×] Q_g`; in SE₂(3) it drives
/// `δP = δp − [p̂×]ψ` too (`T Q Tᵀ` with the position shear: [`ImuNoise::new`]).
pub(crate) fn add_imu_noise(
    p: &mut Matrix15,
    nav: &NavState,
    at: &Point,
    q: &[f64; 6],
    white: f64,
) {
    ImuNoise::new(nav, at, q, white).add_to(p);
}

/// The blocks that [`add_imu_noise`] adds, built once so that a covariance step can add
/// them on either side of Φ without building them twice.
pub(crate) struct ImuNoise {
    /// Added to the velocity block (symmetrized).
    vel: Matrix3<f64>,
    /// Added to the attitude block (symmetrized).
    att: Matrix3<f64>,
    /// `−[v×] Q_g`, added to the velocity–attitude block (invariant formulations only).
    cross: Option<Matrix3<f64>>,
    /// SE₂(3) only, with `D = [p̂×]`: `D Q_g Dᵀ` added to the position block
    /// (symmetrized), `−D Q_g` to the position–attitude block and `D Q_g [v×]ᵀ` to the
    /// position–velocity block.
    position: Option<[Matrix3<f64>; 3]>,
}

impl ImuNoise {
    pub(crate) fn new(nav: &NavState, at: &Point, q: &[f64; 6], white: f64) -> Self {
        let c = &nav.dcm;
        let qa = c * Matrix3::from_diagonal(&Vector3::new(q[0], q[1], q[2])) * c.transpose();
        let qg = c * Matrix3::from_diagonal(&Vector3::new(q[3], q[4], q[5])) * c.transpose();
        let (qa, qg) = (qa * white, qg * white);
        if at.formulation.velocity_invariant() {
            let v = skew(&nav.vel);
            let vq = v * qg; // once: −[v×]Q_g is its negation, exactly
            let position = at.formulation.position_invariant().then(|| {
                let d = skew(&at.disp);
                let dq = d * qg;
                [dq * d.transpose(), -dq, dq * v.transpose()]
            });
            Self {
                vel: qa + vq * v.transpose(),
                att: qg,
                cross: Some(-vq),
                position,
            }
        } else {
            Self {
                vel: qa,
                att: qg,
                cross: None,
                position: None,
            }
        }
    }

    pub(crate) fn add_to(&self, p: &mut Matrix15) {
        fn blk(p: &mut Matrix15, at: usize, m: &Matrix3<f64>) {
            let mut view = p.fixed_view_mut::<3, 3>(at, at);
            view += (m + m.transpose()) * 0.5;
        }
        blk(p, VEL, &self.vel);
        blk(p, ATT, &self.att);
        if let Some(cross) = &self.cross {
            let mut view = p.fixed_view_mut::<3, 3>(VEL, ATT);
            view += cross;
            let mut view = p.fixed_view_mut::<3, 3>(ATT, VEL);
            view += cross.transpose();
        }
        if let Some([pos, pos_att, pos_vel]) = &self.position {
            blk(p, POS, pos);
            for (at, m) in [(ATT, pos_att), (VEL, pos_vel)] {
                let mut view = p.fixed_view_mut::<3, 3>(POS, at);
                view += m;
                let mut view = p.fixed_view_mut::<3, 3>(at, POS);
                view += m.transpose();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::tests::moving_state;

    fn dense_f(d: &ErrorDynamics) -> Matrix15 {
        let mut f = Matrix15::zeros();
        f.fixed_view_mut::<NAV, 15>(0, 0).copy_from(&d.nav_rows());
        f
    }

    fn test_p() -> Matrix15 {
        let a = Matrix15::from_fn(|i, j| {
            ((i * 7 + j * 3) % 11) as f64 * 0.1 + if i == j { 2.0 } else { 0.0 }
        });
        a * a.transpose()
    }

    #[test]
    fn interval_transition_is_second_order_and_propagates_blockwise() {
        for formulation in [
            Formulation::Classic,
            Formulation::Invariant,
            Formulation::Se23,
        ] {
            let nav = moving_state();
            let rates = FrameRates::at(&nav);
            let at = point(formulation, &nav);
            let d = ErrorDynamics::new(&nav, &rates, &Vector3::new(0.1, 0.2, -9.8), &at);
            let f = dense_f(&d);
            let dt = 0.3;
            let want_phi = Matrix15::identity() + f * dt + f * f * (0.5 * dt * dt);
            let t = d.transition(dt);
            let phi = t.dense();
            assert!((phi - want_phi).abs().max() < 1e-12, "{formulation:?}");
            // Φ (P + ½Q) Φᵀ + ½Q against the dense product (the noise as a step adds it).
            let p = test_p();
            let q = Matrix15::from_diagonal(&crate::ekf::Vector15::from_fn(|i, _| {
                1e-3 * (i + 1) as f64
            }));
            let want = phi * (p + q * 0.5) * phi.transpose() + q * 0.5;
            let mut got = p + q * 0.5;
            t.propagate(&mut got);
            got += q * 0.5;
            assert!((got - want).abs().max() < 1e-12 * want.abs().max());
            assert_eq!(got, got.transpose());
            let mut x = SMatrix::<f64, 15, 4>::from_fn(|i, j| (i + 2 * j) as f64 * 0.1);
            let want = phi * x;
            t.apply(&mut x);
            assert!((x - want).abs().max() < 1e-12);
        }
    }

    #[test]
    fn block_sparse_propagation_equals_dense_phi_p_phi_t() {
        for formulation in [
            Formulation::Classic,
            Formulation::Invariant,
            Formulation::Se23,
        ] {
            sparse_equals_dense(formulation);
        }
    }

    /// The point of `formulation` at `nav`, SE₂(3)'s displacement a few km.
    fn point(formulation: Formulation, nav: &NavState) -> Point {
        Point {
            formulation,
            vel: nav.vel,
            disp: Vector3::new(2500.0, -1800.0, 40.0),
        }
    }

    /// SE₂(3)'s F is the invariant F in the coordinates `δP = δp − [p̂×]ψ`:
    /// `T F Tⁱ⁻¹ + Ṫ T⁻¹` with `T = I − [p̂×]` at (position, attitude) and `ṗ̂ = v̂`; and
    /// its IMU noise is `T Q Tᵀ`.
    #[test]
    fn se23_dynamics_are_the_invariant_ones_in_its_coordinates() {
        let nav = moving_state();
        let rates = FrameRates::at(&nav);
        let se23 = point(Formulation::Se23, &nav);
        let inv = Point::velocity(Formulation::Invariant, &nav.vel);
        let f_b = Vector3::new(0.1, 0.2, -9.8);
        let f_se23 = dense_f(&ErrorDynamics::new(&nav, &rates, &f_b, &se23));
        let f_inv = dense_f(&ErrorDynamics::new(&nav, &rates, &f_b, &inv));
        let shear = |m: Matrix3<f64>| {
            let mut t = Matrix15::identity();
            t.fixed_view_mut::<3, 3>(POS, ATT).copy_from(&m);
            t
        };
        let (t, t_inv) = (shear(-skew(&se23.disp)), shear(skew(&se23.disp)));
        let mut t_dot = Matrix15::zeros();
        t_dot
            .fixed_view_mut::<3, 3>(POS, ATT)
            .copy_from(&(-skew(&nav.vel)));
        let want = t * f_inv * t_inv + t_dot * t_inv;
        assert!((f_se23 - want).abs().max() < 1e-12, "{f_se23} vs {want}");
        let q = [1e-3, 2e-3, 3e-3, 1e-5, 2e-5, 3e-5];
        let (mut got, mut classic) = (Matrix15::zeros(), Matrix15::zeros());
        add_imu_noise(&mut got, &nav, &se23, &q, 0.01);
        add_imu_noise(
            &mut classic,
            &nav,
            &Point::velocity(Formulation::Classic, &nav.vel),
            &q,
            0.01,
        );
        let mut want = classic;
        se23.from_classic(&mut want);
        assert!((got - want).abs().max() < 1e-12 * want.abs().max());
    }

    fn sparse_equals_dense(formulation: Formulation) {
        let nav = moving_state();
        let rates = FrameRates::at(&nav);
        let at = point(formulation, &nav);
        let d = ErrorDynamics::new(&nav, &rates, &Vector3::new(0.1, 0.2, -9.8), &at);
        let f = dense_f(&d);
        // F x from the dense F equals the sparse product.
        let x: [f64; 15] = std::array::from_fn(|i| (i as f64 - 6.0) * 0.3);
        let fx = f * crate::ekf::Vector15::from_column_slice(&x);
        let sparse = d.apply(&x);
        assert!(
            (0..9).all(|i| (fx[i] - sparse[i]).abs() < 1e-12),
            "{formulation:?}"
        );
        let ftx = f.transpose() * crate::ekf::Vector15::from_column_slice(&x);
        let sparse = d.apply_transposed(&x);
        assert!(
            (0..15).all(|i| (ftx[i] - sparse[i]).abs() < 1e-12),
            "{formulation:?}"
        );
        let p = test_p();
        let dt = 0.01;
        let phi = Matrix15::identity() + f * dt;
        let want = phi * p * phi.transpose();
        let mut got = p;
        d.propagate_covariance(&mut got, dt);
        assert!((got - want).abs().max() < 1e-12 * want.abs().max());
        assert_eq!(got, got.transpose());
        // The AVX2 copy and the portable one give the same bits (no FMA, same order).
        let mut portable = p;
        d.propagate_covariance_portable(&mut portable, dt);
        assert_eq!(portable, got);
    }
}
