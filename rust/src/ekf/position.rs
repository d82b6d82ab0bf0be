//! Position aiding: a position fix (GNSS at the surface, a USBL or LBL acoustic fix) and
//! a depth (pressure) reading, as updates of the error-state filter.
//!
//! Both observe the NED position error `δp = [(φ̂−φ)(R_N+h), (λ̂−λ)(R_E+h) cosφ, −(ĥ−h)]`
//! directly: each available component is one scalar update with `H = e_{δp_i}` (the
//! same in either formulation, and with the DVL calibration states on the 19-state
//! covariance), innovation `ν_i = z_i − ẑ_i` in metres north, east and down of the
//! estimate, Joseph form, feedback and reset before the next component. Sequential
//! scalar updates with a diagonal R are the joint update, and the sum of their NIS is
//! its NIS. No innovation gate applies (the DVL's is for its 3 dof). The fix and the
//! depth refer to the IMU's point (no lever arm). `docs/filter.md` ("Position and depth
//! updates") writes the formulas out.

use super::calibration::{Calibration, N_CALIBRATED, SCALE};
use super::{Ekf, Vector15, POS};
use crate::attitude::wrap_angle;
use crate::earth;
use crate::error::{check, Error, Result};
use nalgebra::{SMatrix, SVector};

/// What a position or depth update did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionUpdate {
    /// Sum of the components' normalized innovation squares (χ² with `dof` degrees of
    /// freedom when consistent).
    pub nis: f64,
    /// The components used (3 for a full fix, 2 without its height, 1 for a depth).
    pub dof: usize,
    /// The sum of the error estimates fed back (the first 15 states).
    pub correction: Vector15,
    /// The sum of the DVL calibration states' `[δk̂, δμ̂]` fed back (zero without them).
    pub calibration_correction: [f64; 4],
}

impl Ekf {
    /// A position fix `fix = [φ (rad), λ (rad), h (m, up)]` with 1σ `sigma` \[m\] north,
    /// east, down; a NaN height (and its σ) leaves the vertical out. The longitude
    /// innovation `λ − λ̂` is wrapped into (−π, π] (longitude is periodic).
    pub fn update_fix(&mut self, fix: &[f64; 3], sigma: &[f64; 3]) -> Result<PositionUpdate> {
        let components = if fix[2].is_nan() { 2 } else { 3 };
        let mut out = PositionUpdate {
            nis: 0.0,
            dof: components,
            correction: Vector15::zeros(),
            calibration_correction: [0.0; 4],
        };
        for (axis, sigma) in sigma.iter().enumerate().take(components) {
            let (r_n, r_e) = earth::radii(self.nav.lla[0]);
            let (lat, lon, h) = (self.nav.lla[0], self.nav.lla[1], self.nav.lla[2]);
            let innovation = match axis {
                0 => (fix[0] - lat) * (r_n + h),
                1 => longitude_difference(fix[1], lon) * (r_e + h) * lat.cos(),
                _ => h - fix[2],
            };
            self.scalar_position_update(axis, innovation, sigma * sigma, &mut out)?;
        }
        Ok(out)
    }

    /// A depth reading `depth` \[m, positive down\] with 1σ `sigma` \[m\].
    pub fn update_depth(&mut self, depth: f64, sigma: f64) -> Result<PositionUpdate> {
        let mut out = PositionUpdate {
            nis: 0.0,
            dof: 1,
            correction: Vector15::zeros(),
            calibration_correction: [0.0; 4],
        };
        let innovation = depth + self.nav.lla[2]; // z_D − ẑ_D with ẑ_D = −ĥ
        self.scalar_position_update(2, innovation, sigma * sigma, &mut out)?;
        Ok(out)
    }

    /// One scalar update of `δp[axis]` (0 north, 1 east, 2 down) with innovation `ν`
    /// \[m\] and variance `r` \[m²\], fed back; its NIS and correction added to `out`.
    fn scalar_position_update(
        &mut self,
        axis: usize,
        innovation: f64,
        r: f64,
        out: &mut PositionUpdate,
    ) -> Result<()> {
        self.bring_up_to_date();
        self.note_prior();
        let state = POS + axis;
        let (nis, dx) = match self.calibration.as_mut() {
            None => {
                let m = self.sensitivity.as_mut().map(|(m, _)| m);
                let (nis, dx) = scalar_update(&mut self.p, m, state, innovation, r)?;
                (nis, (dx, None))
            }
            Some(calibration) => {
                let mut p = calibration.assemble(&self.p);
                let sensitivity = self.sensitivity.as_mut().map(|(m, _)| m);
                let mut m = match (&sensitivity, self.sensitivity_calibration.as_ref()) {
                    (Some(m15), Some(c)) => Some(c.assemble(m15)),
                    _ => None,
                };
                let (nis, d) = scalar_update(&mut p, m.as_mut(), state, innovation, r)?;
                calibration.split(&p, &mut self.p);
                if let (Some(full), Some(m15), Some(c)) = (
                    m.as_ref(),
                    sensitivity,
                    self.sensitivity_calibration.as_mut(),
                ) {
                    c.split(full, m15);
                }
                let d: SVector<f64, N_CALIBRATED> = d;
                let nav: Vector15 = d.fixed_rows::<15>(0).into_owned();
                (
                    nis,
                    (
                        nav,
                        Some([d[SCALE], d[SCALE + 1], d[SCALE + 2], d[SCALE + 3]]),
                    ),
                )
            }
        };
        let (dx, cal) = dx;
        self.feedback(&dx);
        if let (Some(c), Some(cal)) = (self.calibration.as_mut(), cal) {
            c.feedback(&cal);
        }
        if !self.is_finite() || !self.calibration.as_ref().is_none_or(Calibration::is_finite) {
            return Err(Error::Numerical(
                "the position update produced a non-finite state".into(),
            ));
        }
        out.nis += nis;
        out.correction += dx;
        if let Some(cal) = cal {
            for (sum, v) in out.calibration_correction.iter_mut().zip(cal) {
                *sum += v;
            }
        }
        Ok(())
    }
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

/// The scalar update of state `i` of an `N`-state covariance `p` (and of the
/// sensitivity `m`, if tracked) with `H = e_i`, innovation `ν` and variance `r`:
/// `S = P_ii + r`, `K = P e_i / S`, Joseph form, symmetrized; its NIS `ν²/S` and the
/// error estimate `−K ν`.
fn scalar_update<const N: usize>(
    p: &mut SMatrix<f64, N, N>,
    m: Option<&mut SMatrix<f64, N, N>>,
    i: usize,
    innovation: f64,
    r: f64,
) -> Result<(f64, SVector<f64, N>)> {
    let s = p[(i, i)] + r;
    if !(s > 0.0 && s.is_finite() && innovation.is_finite()) {
        return Err(Error::Numerical(format!(
            "the position update has an innovation variance of {s} and an innovation of \
             {innovation}"
        )));
    }
    let gain: SVector<f64, N> = p.column(i) / s;
    let mut h = SMatrix::<f64, 1, N>::zeros();
    h[(0, i)] = 1.0;
    let ikh = SMatrix::<f64, N, N>::identity() - gain * h;
    *p = ikh * *p * ikh.transpose() + gain * r * gain.transpose();
    *p = (*p + p.transpose()) * 0.5;
    if let Some(m) = m {
        *m = ikh * *m * ikh.transpose();
        *m = (*m + m.transpose()) * 0.5;
    }
    Ok((innovation * innovation / s, -(gain * innovation)))
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

/// The depth readings and position fixes of a pass: lengths, times, values and σ, each
/// error naming its argument.
pub(super) fn check_aiding(
    depth: &[f64],
    depth_time: &[f64],
    depth_sigma: f64,
    fix: &[[f64; 3]],
    fix_time: &[f64],
    fix_sigma: &[[f64; 3]],
) -> Result<()> {
    let same = |name: &str, n: usize, time: &str, m: usize| {
        if n == m {
            return Ok(());
        }
        Err(Error::invalid(
            time,
            format!("has {m} rows but {name} has {n}"),
        ))
    };
    same("depth", depth.len(), "depth_time", depth_time.len())?;
    same("fix", fix.len(), "fix_time", fix_time.len())?;
    same("fix", fix.len(), "fix_sigma", fix_sigma.len())?;
    check::increasing("depth_time", depth_time)?;
    check::increasing("fix_time", fix_time)?;
    check::finite("depth", depth)?;
    if !depth.is_empty() {
        check_depth_sigma(depth_sigma)?;
    }
    for (i, (fix, sigma)) in fix.iter().zip(fix_sigma).enumerate() {
        let vertical = !fix[2].is_nan();
        if !fix[0].is_finite() || !fix[1].is_finite() || fix[2].is_infinite() {
            return Err(Error::invalid(
                "fix",
                format!(
                    "row {i} must hold a finite latitude and longitude [rad] and a finite \
                     or NaN height [m], got {fix:?}"
                ),
            ));
        }
        let row = |e: Error| match e {
            Error::InvalidArgument { arg, reason } => {
                Error::invalid(arg, format!("row {i}: {reason}"))
            }
            other => other,
        };
        earth::check_latitude("fix", fix[0]).map_err(row)?;
        earth::check_longitude("fix", fix[1]).map_err(row)?;
        let wanted = if vertical { 3 } else { 2 };
        if !sigma[..wanted].iter().all(|s| *s > 0.0 && s.is_finite()) {
            let axes = if vertical {
                "north, east, down"
            } else {
                "north, east"
            };
            return Err(Error::invalid(
                "fix_sigma",
                format!("row {i} must hold {wanted} finite 1σ > 0 [m] ({axes}), got {sigma:?}"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::tests::moving_state;
    use crate::ekf::FilterConfig;
    use nalgebra::Vector3;

    fn filter() -> Ekf {
        let cfg = FilterConfig::default();
        Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap()
    }

    /// A fix 10 m north and 5 m east of the estimate, with a P0 of 1 m and a σ of 1 m,
    /// moves the estimate half way (north and east alike), halves those variances, and
    /// its NIS is the two normalized squares (100 + 25) / 2.
    #[test]
    fn a_fix_pulls_the_estimate_by_the_kalman_share() {
        let mut ekf = filter();
        let start = ekf.nav.lla;
        let (r_n, r_e) = earth::radii(start[0]);
        let p0 = ekf.p;
        let fix = [
            start[0] + 10.0 / (r_n + start[2]),
            start[1] + 5.0 / ((r_e + start[2]) * start[0].cos()),
            f64::NAN,
        ];
        let sigma = p0[(0, 0)].sqrt();
        let out = ekf.update_fix(&fix, &[sigma, sigma, f64::NAN]).unwrap();
        assert_eq!(out.dof, 2);
        assert!(
            (out.nis - 125.0 / (2.0 * p0[(0, 0)])).abs() < 1e-6 * out.nis,
            "{out:?}"
        );
        let moved = earth::position_error_ned(&ekf.nav.lla, &start);
        assert!(
            (moved[0] - 5.0).abs() < 1e-6 && (moved[1] - 2.5).abs() < 1e-6,
            "{moved}"
        );
        assert!(moved[2].abs() < 1e-9);
        assert!((ekf.p[(0, 0)] - p0[(0, 0)] / 2.0).abs() < 1e-12);
        assert!((ekf.p[(1, 1)] - p0[(1, 1)] / 2.0).abs() < 1e-12);
        assert_eq!(ekf.p[(2, 2)], p0[(2, 2)]);
        assert!((out.correction[0] + 5.0).abs() < 1e-6);
    }

    /// Longitude is periodic: a fix 3 m east of the antimeridian, 5 m east of an
    /// estimate 2 m west of it, moves the estimate 2.5 m east (the Kalman share) with the
    /// same NIS whether its longitude is given beyond +π, near −π (±180°) or a turn
    /// higher (without the wrap: an innovation of 40 000 km).
    #[test]
    fn a_fix_across_the_antimeridian_pulls_the_estimate_by_the_same_share() {
        use std::f64::consts::PI;
        let mut ekf = filter();
        let (_, r_e) = earth::radii(ekf.nav.lla[0]);
        let per_metre = 1.0 / ((r_e + ekf.nav.lla[2]) * ekf.nav.lla[0].cos());
        ekf.nav.lla[1] = PI - 2.0 * per_metre;
        let start = ekf.nav.lla;
        let east = start[1] + 5.0 * per_metre; // beyond +π: the unwrapped fix
        let sigma = ekf.p[(0, 0)].sqrt();
        let mut reference = None;
        // the same place three ways: beyond +π, in ±180° (near −π), one turn higher
        for lon in [east, east - 2.0 * PI, east + 2.0 * PI] {
            let mut e = ekf.clone();
            let out = e
                .update_fix(&[start[0], lon, f64::NAN], &[sigma, sigma, f64::NAN])
                .unwrap();
            let moved = wrap_angle(e.nav.lla[1] - start[1]) / per_metre;
            assert!((moved - 2.5).abs() < 1e-6, "lon {lon}: moved {moved} m");
            let nis = *reference.get_or_insert(out.nis);
            assert!((out.nis - nis).abs() < 1e-9 * nis, "lon {lon}: {out:?}");
        }
        assert!((reference.unwrap() - 25.0 / (2.0 * ekf.p[(1, 1)])).abs() < 1e-6);
    }

    /// The fix rows' latitude (±89°) and longitude ([−π, 2π]) rules, each error naming
    /// `fix` and its row.
    #[test]
    fn fix_rows_beyond_the_latitude_or_longitude_range_are_named() {
        let sigma = [[1.0; 3]; 3];
        let time = [1.0, 2.0, 3.0];
        let check = |fix: &[[f64; 3]]| check_aiding(&[], &[], 0.1, fix, &time, &sigma);
        let good = [0.5, 0.6, f64::NAN];
        for lon in [-std::f64::consts::PI, 2.0 * std::f64::consts::PI, 6.0] {
            assert!(check(&[good, [0.5, lon, 1.0], good]).is_ok(), "{lon}");
        }
        let err = check(&[good, good, [0.5, 7.0, f64::NAN]])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("fix: row 2: longitude 7 rad must be within"),
            "{err}"
        );
        let err = check(&[good, [0.5, -3.2, f64::NAN], good])
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("fix: row 1: longitude -3.2 rad"), "{err}");
        let err = check(&[good, [1.56, 0.6, f64::NAN], good])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("fix: row 1: latitude must be within ±89°"),
            "{err}"
        );
    }

    /// A depth 2 m deeper than the estimate moves it down (lower height) by the
    /// Kalman share; a zero σ on a zero prior is refused, not divided by.
    #[test]
    fn a_depth_pulls_the_height_and_a_degenerate_one_is_refused() {
        let mut ekf = filter();
        let h0 = ekf.nav.lla[2];
        let share = ekf.p[(2, 2)] / (ekf.p[(2, 2)] + 0.25);
        let out = ekf.update_depth(-h0 + 2.0, 0.5).unwrap();
        assert_eq!(out.dof, 1);
        assert!((ekf.nav.lla[2] - (h0 - 2.0 * share)).abs() < 1e-9);
        let mut ekf = filter();
        ekf.p[(2, 2)] = 0.0;
        let err = ekf.update_depth(1.0, 0.0).unwrap_err();
        assert!(err.to_string().contains("innovation variance"), "{err}");
    }
}
