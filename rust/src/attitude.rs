//! Attitude representations: body-to-navigation DCM `C_b^n`, quaternions, ZYX Euler
//! angles (roll, pitch, yaw in radians), the rotation-vector exponential and logarithm,
//! and re-orthonormalization.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Skew-symmetric cross-product matrix: `skew(a) * b == a × b`.
#[inline]
pub fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a[2], a[1], a[2], 0.0, -a[0], -a[1], a[0], 0.0)
}

/// Rotation-vector exponential (Rodrigues): the DCM of a rotation by `|rv|` radians
/// about `rv`. Uses a Taylor series for small angles (the common case per IMU step:
/// no trigonometry, and exact to rounding for |rv| < 1e-3).
#[inline]
pub fn exp_so3(rv: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = rv.norm_squared();
    let (a, b) = if t2 < 1e-6 {
        // sin t / t and (1 - cos t) / t², truncated after the t⁶ term (error < t⁸/9!),
        // with the constant divisors as reciprocals: a division costs the core several
        // multiplies, and these ones run twice in every strapdown step.
        (
            1.0 - t2 * (1.0 / 6.0) * (1.0 - t2 * (1.0 / 20.0) * (1.0 - t2 * (1.0 / 42.0))),
            0.5 * (1.0 - t2 * (1.0 / 12.0) * (1.0 - t2 * (1.0 / 30.0) * (1.0 - t2 * (1.0 / 56.0)))),
        )
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    // I + a K + b K², written out with K² = v vᵀ − |v|² I (K = skew(v)).
    let (x, y, z) = (rv[0], rv[1], rv[2]);
    let (ax, ay, az) = (a * x, a * y, a * z);
    let (bxy, bxz, byz) = (b * x * y, b * x * z, b * y * z);
    Matrix3::new(
        1.0 - b * (y * y + z * z),
        bxy - az,
        bxz + ay,
        bxy + az,
        1.0 - b * (x * x + z * z),
        byz - ax,
        bxz - ay,
        byz + ax,
        1.0 - b * (x * x + y * y),
    )
}

/// Rotation-vector logarithm of a proper rotation matrix (inverse of [`exp_so3`]).
pub fn log_so3(c: &Matrix3<f64>) -> Vector3<f64> {
    // The skew part of C is sin θ · axis. The angle from atan2(sin, cos) stays accurate
    // for the tiny rotations of one IMU step, where acos of the trace loses half the
    // digits. Past 90° the skew part loses the axis; nalgebra handles angles near π.
    let v = 0.5
        * Vector3::new(
            c[(2, 1)] - c[(1, 2)],
            c[(0, 2)] - c[(2, 0)],
            c[(1, 0)] - c[(0, 1)],
        );
    let cos = 0.5 * (c.trace() - 1.0);
    if cos < 0.0 {
        return Rotation3::from_matrix_unchecked(*c).scaled_axis();
    }
    let sin = v.norm();
    let angle = sin.atan2(cos);
    // θ / sin θ, by its series where sin θ is tiny.
    let scale = if angle < 1e-4 {
        1.0 + angle * angle / 6.0
    } else {
        angle / sin
    };
    v * scale
}

/// DCM `C_b^n = Rz(yaw) · Ry(pitch) · Rx(roll)` from ZYX Euler angles \[rad\].
pub fn dcm_from_euler(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// ZYX Euler angles `[roll, pitch, yaw]` \[rad\] of `C_b^n`; yaw in (−π, π].
pub fn euler_from_dcm(c: &Matrix3<f64>) -> Vector3<f64> {
    let roll = c[(2, 1)].atan2(c[(2, 2)]);
    let pitch = (-c[(2, 0)]).clamp(-1.0, 1.0).asin();
    let yaw = c[(1, 0)].atan2(c[(0, 0)]);
    Vector3::new(roll, pitch, yaw)
}

/// Unit quaternion of a DCM.
pub fn quat_from_dcm(c: &Matrix3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_matrix(c)
}

/// DCM of a unit quaternion.
pub fn dcm_from_quat(q: &UnitQuaternion<f64>) -> Matrix3<f64> {
    q.to_rotation_matrix().into_inner()
}

/// One step of the first-order re-orthonormalization `C ← C − ½ C (CᵀC − I)`.
/// Removes the rounding drift of repeated products; for a nearly orthonormal C the
/// residual error is squared by each step.
#[inline]
pub fn orthonormalize(c: &Matrix3<f64>) -> Matrix3<f64> {
    c * (Matrix3::identity() * 1.5 - c.transpose() * c * 0.5)
}

/// Wrap an angle \[rad\] to (−π, π].
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    let w =
        (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
    if w == -std::f64::consts::PI {
        std::f64::consts::PI
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_abs(m: &Matrix3<f64>) -> f64 {
        m.abs().max()
    }

    #[test]
    fn euler_round_trip() {
        for &(r, p, y) in &[(0.1, -0.2, 2.9), (-1.0, 1.2, -3.0), (0.0, 0.0, 0.0)] {
            let c = dcm_from_euler(r, p, y);
            let e = euler_from_dcm(&c);
            assert!((e - Vector3::new(r, p, y)).abs().max() < 1e-12, "{e:?}");
            assert!(max_abs(&(c.transpose() * c - Matrix3::identity())) < 1e-15);
        }
    }

    #[test]
    fn euler_matches_elementary_rotations() {
        // A yaw of +90° turns the body x axis (forward) to east.
        let c = dcm_from_euler(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let east = c * Vector3::x();
        assert!((east - Vector3::y()).norm() < 1e-15);
        // A pitch up of +90° turns forward to up (negative down).
        let c = dcm_from_euler(0.0, std::f64::consts::FRAC_PI_2, 0.0);
        assert!((c * Vector3::x() + Vector3::z()).norm() < 1e-15);
    }

    #[test]
    fn exp_matches_nalgebra_for_small_and_large_angles() {
        for rv in [
            Vector3::new(1e-9, -2e-9, 3e-9),
            Vector3::new(1e-4, 2e-4, -3e-4),
            Vector3::new(5e-4, -7e-4, 2e-4),
            Vector3::new(0.3, -1.2, 0.7),
        ] {
            let want = Rotation3::from_scaled_axis(rv).into_inner();
            assert!(max_abs(&(exp_so3(&rv) - want)) < 1e-15, "{rv:?}");
            assert!((log_so3(&exp_so3(&rv)) - rv).norm() < 1e-13);
        }
    }

    #[test]
    fn quaternion_round_trip() {
        let c = dcm_from_euler(0.3, -0.4, 1.7);
        let q = quat_from_dcm(&c);
        assert!(max_abs(&(dcm_from_quat(&q) - c)) < 1e-14);
    }

    #[test]
    fn orthonormalize_removes_drift() {
        let c = dcm_from_euler(0.3, -0.4, 1.7) * 1.000_001;
        let o = orthonormalize(&orthonormalize(&c));
        assert!(max_abs(&(o.transpose() * o - Matrix3::identity())) < 1e-15);
        assert!(max_abs(&(o - dcm_from_euler(0.3, -0.4, 1.7))) < 1e-14);
    }

    #[test]
    fn wrap() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
        assert!((wrap_angle(7.0) - (7.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12);
    }
}
