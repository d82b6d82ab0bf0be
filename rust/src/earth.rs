//! WGS-84 Earth model: radii of curvature, normal gravity, Earth and transport rates,
//! and conversions between geodetic coordinates and local NED offsets.
//!
//! Positions are `[lat, lon, h]`: geodetic latitude and longitude in radians, height
//! above the ellipsoid in metres (positive up). Vectors in the navigation frame are
//! NED (north, east, down).

use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};

/// Semi-major axis \[m\].
pub const A: f64 = 6_378_137.0;
/// Flattening.
pub const F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared.
pub const E2: f64 = F * (2.0 - F);
/// Semi-minor axis \[m\].
pub const B: f64 = A * (1.0 - F);
/// Earth rotation rate \[rad/s\].
pub const OMEGA_IE: f64 = 7.292_115e-5;
/// Earth gravitational constant GM \[m³/s²\].
pub const GM: f64 = 3.986_004_418e14;
/// Normal gravity at the equator \[m/s²\].
pub const GAMMA_EQUATOR: f64 = 9.780_325_335_9;
/// Normal gravity at the poles \[m/s²\].
pub const GAMMA_POLE: f64 = 9.832_184_937_8;

/// The terms of one geodetic latitude that every local quantity derives from, computed
/// once: a step that needs the radii, gravity, Earth rate and transport rate pays for one
/// `sin_cos` (and a `tan` for the transport rate) instead of five transcendental calls.
#[derive(Clone, Copy, Debug)]
pub struct Latitude {
    /// The latitude itself \[rad\].
    pub lat: f64,
    pub sin: f64,
    pub cos: f64,
    /// Meridian (north-south) radius of curvature \[m\].
    pub r_n: f64,
    /// Prime-vertical (east-west) radius of curvature \[m\].
    pub r_e: f64,
}

impl Latitude {
    /// The terms at geodetic latitude `lat` \[rad\].
    #[inline]
    pub fn new(lat: f64) -> Self {
        let (sin, cos) = lat.sin_cos();
        Self::from_sin_cos(lat, sin, cos)
    }

    #[inline]
    fn from_sin_cos(lat: f64, sin: f64, cos: f64) -> Self {
        let (r_n, r_e) = radii_from_sin(sin);
        Self {
            lat,
            sin,
            cos,
            r_n,
            r_e,
        }
    }

    /// WGS-84 normal gravity magnitude \[m/s²\] at height `h` \[m\]: Somigliana's formula
    /// with the second-order height correction (NIMA TR8350.2, 4-3). It includes the
    /// centrifugal part, so at rest the accelerometer reads `-gravity`.
    #[inline]
    pub fn gravity(&self, h: f64) -> f64 {
        let s2 = self.sin * self.sin;
        let k = (1.0 - F) * GAMMA_POLE / GAMMA_EQUATOR - 1.0;
        let gamma0 = GAMMA_EQUATOR * (1.0 + k * s2) / (1.0 - E2 * s2).sqrt();
        let m = OMEGA_IE * OMEGA_IE * A * A * B / GM;
        gamma0 * (1.0 - 2.0 * h / A * (1.0 + F + m - 2.0 * F * s2) + 3.0 * h * h / (A * A))
    }

    /// Earth rotation rate expressed in NED \[rad/s\].
    #[inline]
    pub fn earth_rate_ned(&self) -> Vector3<f64> {
        Vector3::new(OMEGA_IE * self.cos, 0.0, -OMEGA_IE * self.sin)
    }

    /// Transport rate (rotation of NED relative to the Earth) \[rad/s\] for NED velocity
    /// `v` \[m/s\] at height `h` \[m\].
    #[inline]
    pub fn transport_rate_ned(&self, h: f64, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            v[1] / (self.r_e + h),
            -v[0] / (self.r_n + h),
            -v[1] * (self.sin / self.cos) / (self.r_e + h),
        )
    }

    /// The terms at a latitude `lat` \[rad\] near this one. Within [`NEAR_LATITUDE`] the
    /// sine and cosine come from this one's by their Taylor series to second order in
    /// δ = lat − self.lat, whose first omitted term (|δ|³/6 < 2e-19) is far below the
    /// rounding of `sin_cos` itself; farther away it is [`Latitude::new`]. The
    /// mechanization's mid-step latitude moves by ~1e-9 rad per step, so this saves it
    /// a `sin_cos` per step.
    #[inline]
    pub fn near(&self, lat: f64) -> Self {
        let d = lat - self.lat;
        if d.is_nan() || d.abs() > NEAR_LATITUDE {
            return Self::new(lat);
        }
        let half_d2 = 0.5 * d * d;
        let sin = self.sin + self.cos * d - self.sin * half_d2;
        let cos = self.cos - self.sin * d - self.cos * half_d2;
        Self::from_sin_cos(lat, sin, cos)
    }
}

/// How far \[rad\] [`Latitude::near`] uses its series (about 6 m of latitude).
pub const NEAR_LATITUDE: f64 = 1e-6;

/// Meridian (north-south) and prime-vertical (east-west) radii of curvature \[m\]
/// at geodetic latitude `lat` \[rad\]: `(R_N, R_E)`.
#[inline]
pub fn radii(lat: f64) -> (f64, f64) {
    radii_from_sin(lat.sin())
}

#[inline]
fn radii_from_sin(sin: f64) -> (f64, f64) {
    let d = 1.0 - E2 * sin * sin;
    let sqrt_d = d.sqrt();
    (A * (1.0 - E2) / (d * sqrt_d), A / sqrt_d)
}

/// WGS-84 normal gravity magnitude \[m/s²\] at latitude `lat` \[rad\] and height `h` \[m\]
/// (see [`Latitude::gravity`]).
#[inline]
pub fn gravity(lat: f64, h: f64) -> f64 {
    Latitude::new(lat).gravity(h)
}

/// Heights \[m\] within which [`checked_gravity`] answers: the Somigliana series with its
/// second-order height term is a near-surface model.
pub const MAX_GRAVITY_HEIGHT: f64 = 100_000.0;

/// Largest |latitude| \[°\] a navigation state may start at. Nearer a pole the NED frame
/// turns singular: the east axis and the transport rate's `tan(lat)` blow up.
pub const MAX_LATITUDE_DEG: f64 = 89.0;

/// `Err` naming `arg` unless `value` is finite.
fn finite_scalar(arg: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error::invalid(arg, format!("must be finite, got {value}")))
    }
}

/// The latitude rule of every navigation entry point: `|lat| <= 89°` (`lat` in rad), else
/// an error naming `arg` (the argument holding the position, e.g. `lla0`).
pub fn check_latitude(arg: &str, lat: f64) -> Result<()> {
    if lat.abs() > MAX_LATITUDE_DEG.to_radians() {
        return Err(Error::invalid(
            arg,
            "latitude must be within ±89° (given in radians; NED is singular at the poles)",
        ));
    }
    Ok(())
}

/// The longitudes \[°\] a position may be given in, `[−180°, 360°]`: both the ±180° and
/// the 0–360° conventions. Longitude is periodic (a fix's innovation is wrapped into
/// (−π, π]), so any value within is a place; one beyond is a unit or column slip.
pub const LONGITUDE_RANGE_DEG: (f64, f64) = (-180.0, 360.0);

/// The longitude rule of the position fixes (their rows in `run_filter`, and the
/// recordings' fix tables, which apply it in the file's unit): `lon` \[rad\] within
/// [`LONGITUDE_RANGE_DEG`], else an error naming `arg`. An initial position's
/// longitude (`lla0`) is not held to it.
pub fn check_longitude(arg: &str, lon: f64) -> Result<()> {
    let (lo, hi) = LONGITUDE_RANGE_DEG;
    if !(lo.to_radians()..=hi.to_radians()).contains(&lon) {
        // a huge value in full would be hundreds of digits
        let lon = if lon.abs() < 1e6 {
            format!("{lon}")
        } else {
            format!("{lon:e}")
        };
        return Err(Error::invalid(
            arg,
            format!(
                "longitude {lon} rad must be within [−π, 2π] ({lo}° … {hi}°: the ±180° and \
                 0–360° conventions)"
            ),
        ));
    }
    Ok(())
}

/// [`gravity`] for outside callers: finite `lat` \[rad\] and `h` \[m\] with
/// `|h| <= MAX_GRAVITY_HEIGHT`, else an error naming the argument.
pub fn checked_gravity(lat: f64, h: f64) -> Result<f64> {
    let h = finite_scalar("h", h)?;
    if h.abs() > MAX_GRAVITY_HEIGHT {
        return Err(Error::invalid(
            "h",
            format!(
                "normal gravity holds within ±{MAX_GRAVITY_HEIGHT} m of the ellipsoid, got {h}"
            ),
        ));
    }
    Ok(gravity(finite_scalar("lat", lat)?, h))
}

/// [`radii`] for outside callers: a finite `lat` \[rad\], else an error naming it.
pub fn checked_radii(lat: f64) -> Result<(f64, f64)> {
    Ok(radii(finite_scalar("lat", lat)?))
}

/// Normal gravity vector in NED \[m/s²\]: `[0, 0, gravity(lat, h)]`.
#[inline]
pub fn gravity_ned(lat: f64, h: f64) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, gravity(lat, h))
}

/// Earth rotation rate expressed in NED \[rad/s\].
#[inline]
pub fn earth_rate_ned(lat: f64) -> Vector3<f64> {
    Latitude::new(lat).earth_rate_ned()
}

/// Transport rate (rotation of NED relative to the Earth) \[rad/s\] for NED velocity
/// `v` \[m/s\] at latitude `lat` \[rad\] and height `h` \[m\].
#[inline]
pub fn transport_rate_ned(lat: f64, h: f64, v: &Vector3<f64>) -> Vector3<f64> {
    Latitude::new(lat).transport_rate_ned(h, v)
}

/// Geodetic `[lat, lon, h]` to Earth-centred Earth-fixed coordinates \[m\].
pub fn lla_to_ecef(lla: &Vector3<f64>) -> Vector3<f64> {
    let (lat, lon, h) = (lla[0], lla[1], lla[2]);
    let (_, r_e) = radii(lat);
    Vector3::new(
        (r_e + h) * lat.cos() * lon.cos(),
        (r_e + h) * lat.cos() * lon.sin(),
        (r_e * (1.0 - E2) + h) * lat.sin(),
    )
}

/// ECEF \[m\] to geodetic `[lat, lon, h]` (iterative; converges to machine precision
/// within a few iterations anywhere outside the Earth's centre).
pub fn ecef_to_lla(r: &Vector3<f64>) -> Vector3<f64> {
    let p = (r[0] * r[0] + r[1] * r[1]).sqrt();
    let lon = r[1].atan2(r[0]);
    let mut lat = r[2].atan2(p * (1.0 - E2));
    let mut h = 0.0;
    for _ in 0..8 {
        let (_, r_e) = radii(lat);
        let cos_lat = lat.cos();
        // Near the poles use the z-component for the height: p / cos(lat) is ill-conditioned.
        h = if cos_lat.abs() > 1e-3 {
            p / cos_lat - r_e
        } else {
            r[2] / lat.sin() - r_e * (1.0 - E2)
        };
        lat = r[2].atan2(p * (1.0 - E2 * r_e / (r_e + h)));
    }
    Vector3::new(lat, lon, h)
}

/// Rotation from ECEF to the local NED frame at `(lat, lon)`.
pub fn dcm_ecef_to_ned(lat: f64, lon: f64) -> Matrix3<f64> {
    let (sl, cl) = lat.sin_cos();
    let (so, co) = lon.sin_cos();
    Matrix3::new(
        -sl * co,
        -sl * so,
        cl,
        -so,
        co,
        0.0,
        -cl * co,
        -cl * so,
        -sl,
    )
}

/// Offset \[m, NED\] of the point `lla` from the reference point `origin`, both geodetic.
/// Exact (through ECEF), valid for any distance.
pub fn lla_to_ned(origin: &Vector3<f64>, lla: &Vector3<f64>) -> Vector3<f64> {
    let d = lla_to_ecef(lla) - lla_to_ecef(origin);
    dcm_ecef_to_ned(origin[0], origin[1]) * d
}

/// Geodetic position of the point at offset `ned` \[m\] from `origin`. Inverse of
/// [`lla_to_ned`].
pub fn ned_to_lla(origin: &Vector3<f64>, ned: &Vector3<f64>) -> Vector3<f64> {
    let d = dcm_ecef_to_ned(origin[0], origin[1]).transpose() * ned;
    ecef_to_lla(&(lla_to_ecef(origin) + d))
}

/// Small position difference `est - truth` expressed in NED metres with the radii at
/// `truth` (the filter's δp): `[(φ̂−φ)(R_N+h), (λ̂−λ)(R_E+h)cosφ, −(ĥ−h)]`.
#[inline]
pub fn position_error_ned(est: &Vector3<f64>, truth: &Vector3<f64>) -> Vector3<f64> {
    NedScale::at(truth).error(est, truth)
}

/// What [`position_error_ned`] needs of the true position, for a truth read many times
/// (a Monte Carlo's runs share one trajectory): `r_N + h`, `r_E + h` \[m\] and `cos φ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NedScale([f64; 3]);

impl NedScale {
    /// The scale at the geodetic position `truth` `[lat, lon, h]`.
    pub fn at(truth: &Vector3<f64>) -> Self {
        let (r_n, r_e) = radii(truth[0]);
        Self([r_n + truth[2], r_e + truth[2], truth[0].cos()])
    }

    /// [`position_error_ned`] of `est` against `truth`, whose scale this is.
    #[inline]
    pub fn error(&self, est: &Vector3<f64>, truth: &Vector3<f64>) -> Vector3<f64> {
        let [north, east, cos] = self.0;
        Vector3::new(
            (est[0] - truth[0]) * north,
            (est[1] - truth[1]) * east * cos,
            -(est[2] - truth[2]),
        )
    }

    /// The geodetic position whose [`NedScale::error`] against `truth` is `d` \[m,
    /// NED\] (its exact inverse but for rounding).
    #[inline]
    pub fn offset(&self, truth: &Vector3<f64>, d: &Vector3<f64>) -> Vector3<f64> {
        let [north, east, cos] = self.0;
        Vector3::new(
            truth[0] + d[0] / north,
            truth[1] + d[1] / (east * cos),
            truth[2] - d[2],
        )
    }
}

/// Geodetic increment `[Δlat, Δlon, Δh]` for a small NED displacement `d` \[m\] at `lla`.
#[inline]
pub fn ned_delta_to_lla_delta(lla: &Vector3<f64>, d: &Vector3<f64>) -> Vector3<f64> {
    let (r_n, r_e) = radii(lla[0]);
    Vector3::new(
        d[0] / (r_n + lla[2]),
        d[1] / ((r_e + lla[2]) * lla[0].cos()),
        -d[2],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The texts `tests/test_core_rules.py` expects from Python: the same error from
    /// either side.
    #[test]
    fn latitude_and_gravity_height_rules_name_their_argument() {
        assert!(check_latitude("lla0", 89f64.to_radians()).is_ok());
        assert_eq!(
            check_latitude("lla0", 1.56).unwrap_err().to_string(),
            "lla0: latitude must be within ±89° (given in radians; NED is singular at the poles)"
        );
        assert!(check_longitude("fix", -std::f64::consts::PI).is_ok());
        assert!(check_longitude("fix", 2.0 * std::f64::consts::PI).is_ok());
        assert_eq!(
            check_longitude("fix", 1e300).unwrap_err().to_string(),
            "fix: longitude 1e300 rad must be within [−π, 2π] (-180° … 360°: the ±180° and \
             0–360° conventions)"
        );
        for bad in [7.0, -3.2, f64::NAN] {
            let err = check_longitude("fix", bad).unwrap_err().to_string();
            assert!(err.starts_with("fix: longitude "), "{err}");
        }
        assert_eq!(
            checked_gravity(0.5, 100_001.0).unwrap_err().to_string(),
            "h: normal gravity holds within ±100000 m of the ellipsoid, got 100001"
        );
        assert_eq!(
            checked_gravity(0.5, -100_000.0).unwrap(),
            gravity(0.5, -1e5)
        );
        assert_eq!(
            checked_gravity(f64::NAN, 0.0).unwrap_err().to_string(),
            "lat: must be finite, got NaN"
        );
        assert_eq!(
            checked_radii(f64::INFINITY).unwrap_err().to_string(),
            "lat: must be finite, got inf"
        );
    }

    #[test]
    fn latitude_near_agrees_with_the_direct_evaluation() {
        for lat_deg in [-88.9, -45.0, -1e-9, 0.0, 12.5, 32.1, 60.0, 88.9] {
            let at = Latitude::new(f64::to_radians(lat_deg));
            for d in [0.0, 1e-12, -3e-9, 4e-8, -5e-7, 1e-6, -1e-6, 2e-6, -0.3] {
                let (near, direct) = (at.near(at.lat + d), Latitude::new(at.lat + d));
                assert_eq!(near.lat, direct.lat);
                for (x, y) in [
                    (near.sin, direct.sin),
                    (near.cos, direct.cos),
                    (near.r_n, direct.r_n),
                    (near.r_e, direct.r_e),
                ] {
                    // Within a couple of ulps of the libm values (absolute near zero).
                    assert!(
                        (x - y).abs() <= 4.0 * f64::EPSILON * y.abs().max(1.0),
                        "{lat_deg}° + {d}: {x} vs {y}"
                    );
                }
            }
        }
    }

    #[test]
    fn gravity_matches_wgs84_at_equator_and_pole() {
        assert!((gravity(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-6);
        assert!((gravity(std::f64::consts::FRAC_PI_2, 0.0) - 9.832_184_937_8).abs() < 1e-6);
    }

    #[test]
    fn gravity_decreases_with_height_by_the_free_air_gradient() {
        // Free-air gradient is about 3.086e-6 (m/s²)/m.
        let lat = 32f64.to_radians();
        let grad = (gravity(lat, 100.0) - gravity(lat, 0.0)) / 100.0;
        assert!((grad + 3.086e-6).abs() < 0.01e-6, "gradient {grad}");
    }

    #[test]
    fn radii_at_equator_and_pole() {
        let (rn, re) = radii(0.0);
        assert!((re - A).abs() < 1e-6);
        assert!((rn - A * (1.0 - E2)).abs() < 1e-6);
        let (rn, re) = radii(std::f64::consts::FRAC_PI_2);
        assert!((rn - re).abs() < 1e-6, "radii equal at the pole");
        assert!((rn - A * A / B).abs() < 1e-6);
    }

    #[test]
    fn earth_rate_has_the_earth_rotation_magnitude() {
        let w = earth_rate_ned(32f64.to_radians());
        assert!((w.norm() - OMEGA_IE).abs() < 1e-18);
        assert!(
            w[2] < 0.0,
            "points up (negative down) in the northern hemisphere"
        );
    }

    #[test]
    fn transport_rate_of_eastward_motion() {
        let lat = 0.3;
        let v = Vector3::new(0.0, 10.0, 0.0);
        let w = transport_rate_ned(lat, 0.0, &v);
        let (_, re) = radii(lat);
        assert!((w[0] - 10.0 / re).abs() < 1e-18);
        assert_eq!(w[1], 0.0);
        assert!((w[2] + 10.0 * lat.tan() / re).abs() < 1e-18);
    }

    #[test]
    fn ecef_round_trip() {
        for &(lat, lon, h) in &[
            (0.0, 0.0, 0.0),
            (0.558, 0.593, -5.0),
            (-1.2, -2.9, 8000.0),
            (1.5, 1.0, 100.0),
        ] {
            let lla = Vector3::new(lat, lon, h);
            let back = ecef_to_lla(&lla_to_ecef(&lla));
            assert!((back - lla).abs().max() < 1e-8, "{lla:?} -> {back:?}");
        }
    }

    #[test]
    fn ned_offsets_round_trip_and_match_small_difference_formula() {
        let origin = Vector3::new(32f64.to_radians(), 34f64.to_radians(), -5.0);
        let ned = Vector3::new(120.0, -45.0, 3.0);
        let p = ned_to_lla(&origin, &ned);
        assert!((lla_to_ned(&origin, &p) - ned).norm() < 1e-6);
        // For a short baseline the curvilinear small-difference formula agrees to mm.
        let approx = position_error_ned(&p, &origin);
        assert!((approx - ned).norm() < 5e-3, "{approx:?}");
        // Same for the increment: angles to 1e-9 rad; the height differs by the Earth's
        // curvature over the baseline, d²/2R ≈ 1.3 mm.
        let diff = origin + ned_delta_to_lla_delta(&origin, &ned) - p;
        assert!(diff[0].abs() < 1e-9 && diff[1].abs() < 1e-9, "{diff:?}");
        assert!(diff[2].abs() < 2e-3, "{diff:?}");
    }
}
