//! The handcrafted-feature (HCF) ensemble's prediction (`pronet.hcf.HCFEnsemble`): 14
//! statistics of the window feed gradient-boosted trees and a random forest, whose
//! outputs are averaged.
//!
//! Features ([`features`], as `pronet.windowstats.features`), of the raw window and of
//! the window minus its least-squares line: variance (N − 1), standard deviation, range,
//! mean absolute deviation, RMS of first differences, skewness and excess kurtosis (both
//! 0 for a constant window). They are computed on the window divided by the power of two
//! that brings its largest magnitude into [0.5, 1) and scaled back exactly, so no power
//! overflows.
//!
//! With [`Target::LogRatio`] the scale features are divided by the detrended variance
//! d = Σ r² / (N − 2) (or by √d), the detrended variance feature becomes log10 d, and
//! q = d·exp(out); with [`Target::Q`], q = out; where out = ½·(gb_init + gb_rate·Σ gb
//! trees) + ½·mean(rf trees). Split rule, as scikit-learn's: a feature is rounded to
//! float32 and goes left when `feature <= threshold`. A window with a non-finite
//! feature gives NaN.

use super::per_window;
use crate::cancel::Cancel;
use crate::error::{Error, Result};

/// Number of handcrafted features.
pub const N_FEATURES: usize = 14;
/// Feature columns in the window's units (std, range, MAD, RMS of differences).
const LINEAR: [usize; 8] = [1, 2, 3, 4, 8, 9, 10, 11];
/// Feature columns in the window's units squared (the variances).
const SQUARED: [usize; 2] = [0, 7];
/// The detrended variance's column (the level in log-ratio mode).
const LEVEL: usize = 7;

/// What the trees regress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// q itself.
    Q,
    /// ln(q / d), on scale-free features.
    LogRatio,
}

/// Binary regression trees in flat arrays; tree i starts at `roots[i]`; `left`/`right`
/// are absolute node indices, -1 at leaves.
#[derive(Clone, Debug)]
pub struct TreeSet {
    left: Vec<i32>,
    right: Vec<i32>,
    feature: Vec<u32>,
    threshold: Vec<f64>,
    value: Vec<f64>,
    roots: Vec<usize>,
}

impl TreeSet {
    /// Checks that the arrays form trees over [`N_FEATURES`] features whose every walk
    /// ends at a leaf (children come after their parent).
    pub fn new(
        left: Vec<i32>,
        right: Vec<i32>,
        feature: Vec<i32>,
        threshold: Vec<f64>,
        value: Vec<f64>,
        roots: Vec<i32>,
    ) -> Result<Self> {
        let n = value.len();
        if [left.len(), right.len(), feature.len(), threshold.len()] != [n; 4] {
            return Err(Error::invalid("trees", "arrays of unequal length"));
        }
        if roots.is_empty() || roots.iter().any(|&r| r < 0 || r as usize >= n) {
            return Err(Error::invalid("trees", "roots must be node indices"));
        }
        for i in 0..n {
            let (l, r) = (left[i], right[i]);
            let leaf = l == -1 && r == -1;
            let inner = l > i as i32 && r > i as i32 && (l as usize) < n && (r as usize) < n;
            if !(leaf || inner) || feature[i] < 0 || feature[i] as usize >= N_FEATURES {
                return Err(Error::invalid(
                    "trees",
                    format!("node {i} is not a valid node"),
                ));
            }
            if !(value[i].is_finite() && (leaf || !threshold[i].is_nan())) {
                return Err(Error::invalid(
                    "trees",
                    format!("node {i} holds a non-finite value"),
                ));
            }
        }
        Ok(Self {
            left,
            right,
            feature: feature.into_iter().map(|f| f as u32).collect(),
            threshold,
            value,
            roots: roots.into_iter().map(|r| r as usize).collect(),
        })
    }

    fn n_trees(&self) -> usize {
        self.roots.len()
    }

    /// The leaf value of the tree at `root` for features `x32` (already float32-rounded).
    fn walk(&self, root: usize, x32: &[f64; N_FEATURES]) -> f64 {
        let mut node = root;
        while self.left[node] >= 0 {
            node = if x32[self.feature[node] as usize] <= self.threshold[node] {
                self.left[node] as usize
            } else {
                self.right[node] as usize
            };
        }
        self.value[node]
    }

    /// Σ over the trees of their leaf values.
    fn sum(&self, x32: &[f64; N_FEATURES]) -> f64 {
        self.roots.iter().map(|&r| self.walk(r, x32)).sum()
    }
}

/// The HCF ensemble; see the module docs.
#[derive(Clone, Debug)]
pub struct HcfEnsemble {
    window: usize,
    gb: TreeSet,
    gb_init: f64,
    gb_rate: f64,
    rf: TreeSet,
    target: Target,
}

impl HcfEnsemble {
    pub fn new(
        window: usize,
        gb: TreeSet,
        gb_init: f64,
        gb_rate: f64,
        rf: TreeSet,
        target: Target,
    ) -> Result<Self> {
        if window < 3 {
            return Err(Error::invalid(
                "window",
                format!("must be >= 3 samples, got {window}"),
            ));
        }
        if !(gb_init.is_finite() && gb_rate.is_finite()) {
            return Err(Error::invalid("gb_init, gb_rate", "must be finite"));
        }
        Ok(Self {
            window,
            gb,
            gb_init,
            gb_rate,
            rf,
            target,
        })
    }

    /// Samples per window.
    pub fn window(&self) -> usize {
        self.window
    }

    /// q `(n,)` for `n` windows `(n, window)` row-major, in parallel on rayon's threads.
    pub fn predict(&self, windows: &[f64]) -> Result<Vec<f64>> {
        self.predict_until(windows, &Cancel::default())
    }

    /// [`Self::predict`] that stops with [`crate::error::Error::Cancelled`] soon after
    /// `cancel` is set.
    pub fn predict_until(&self, windows: &[f64], cancel: &Cancel) -> Result<Vec<f64>> {
        per_window(
            windows,
            self.window,
            16,
            cancel,
            || vec![0.0; self.window],
            |w, buf| self.predict_one(w, buf),
        )
    }

    fn predict_one(&self, w: &[f64], buf: &mut [f64]) -> f64 {
        let (mut x, e) = features_scaled(w, buf);
        let mut d = 1.0;
        if self.target == Target::LogRatio {
            // buf holds the scaled detrended window
            let n = w.len() as f64;
            d = ldexp(buf.iter().map(|r| r * r).sum::<f64>() / (n - 2.0), 2 * e);
            if d == 0.0 && w.iter().all(|v| v.is_finite()) {
                // A window that is a straight line has no noise: q = d·exp(out) → 0
                // (its scale-free features would be 0/0).
                return 0.0;
            }
            let sd = d.sqrt();
            LINEAR.iter().for_each(|&i| x[i] /= sd);
            SQUARED.iter().for_each(|&i| x[i] /= d);
            x[LEVEL] = d.log10();
        }
        if !x.iter().all(|v| v.is_finite()) {
            return f64::NAN;
        }
        let x32: [f64; N_FEATURES] = std::array::from_fn(|i| f64::from(x[i] as f32));
        let gb = self.gb_init + self.gb_rate * self.gb.sum(&x32);
        let rf = self.rf.sum(&x32) / self.rf.n_trees() as f64;
        let out = 0.5 * gb + 0.5 * rf;
        match self.target {
            Target::Q => out,
            Target::LogRatio => d * out.min(700.0).exp(),
        }
    }
}

/// `x·2^e` (exact unless it overflows or underflows).
fn ldexp(x: f64, e: i32) -> f64 {
    // split the power so that neither factor overflows for |e| up to ~2000
    let half = e / 2;
    x * 2f64.powi(half) * 2f64.powi(e - half)
}

/// The exponent e with `peak / 2^e` in [0.5, 1) (`frexp`); 0 for 0 and non-finite.
fn frexp_exponent(peak: f64) -> i32 {
    if peak == 0.0 || !peak.is_finite() {
        return 0;
    }
    let (mut m, mut e) = (peak, 0i32);
    // normalise subnormals first
    if m < f64::MIN_POSITIVE {
        m *= 2f64.powi(54);
        e -= 54;
    }
    let bits = m.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i32;
    e + exp - 1022
}

/// The 14 features of one window (see the module docs).
pub fn features(w: &[f64]) -> [f64; N_FEATURES] {
    let mut buf = vec![0.0; w.len()];
    features_scaled(w, &mut buf).0
}

/// The features, the power-of-two exponent e of the window's scaling, and in `buf` the
/// scaled window minus its least-squares line.
fn features_scaled(w: &[f64], buf: &mut [f64]) -> ([f64; N_FEATURES], i32) {
    let peak = w.iter().fold(0.0f64, |m, v| {
        if v.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(v.abs())
        }
    });
    let e = frexp_exponent(peak);
    let scale = ldexp(1.0, -e);
    for (b, v) in buf.iter_mut().zip(w) {
        *b = v * scale;
    }
    let raw = stats(buf, e);
    detrend(buf);
    let detrended = stats(buf, e);
    let mut x = [0.0; N_FEATURES];
    x[..7].copy_from_slice(&raw);
    x[7..].copy_from_slice(&detrended);
    (x, e)
}

/// Subtract the least-squares line over the sample index, in place.
fn detrend(w: &mut [f64]) {
    let n = w.len() as f64;
    let centre = (n - 1.0) / 2.0;
    let mean = w.iter().sum::<f64>() / n;
    let tt: f64 = (0..w.len()).map(|i| (i as f64 - centre).powi(2)).sum();
    let mut slope = 0.0;
    for (i, v) in w.iter_mut().enumerate() {
        *v -= mean;
        slope += *v * (i as f64 - centre);
    }
    slope /= tt;
    for (i, v) in w.iter_mut().enumerate() {
        *v -= slope * (i as f64 - centre);
    }
}

/// Variance, std, range, MAD, RMS of differences (scaled back by 2^e), skewness and
/// excess kurtosis of `w` (already scaled by 2^-e).
fn stats(w: &[f64], e: i32) -> [f64; 7] {
    let n = w.len() as f64;
    let mean = w.iter().sum::<f64>() / n;
    let (mut m2, mut m3, mut m4, mut mad) = (0.0, 0.0, 0.0, 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in w {
        let c = v - mean;
        let c2 = c * c;
        m2 += c2;
        m3 += c2 * c;
        m4 += c2 * c2;
        mad += c.abs();
        lo = if v.is_nan() || lo.is_nan() {
            f64::NAN
        } else {
            lo.min(v)
        };
        hi = if v.is_nan() || hi.is_nan() {
            f64::NAN
        } else {
            hi.max(v)
        };
    }
    let (m2, m3, m4) = (m2 / n, m3 / n, m4 / n);
    let diff2 = w
        .windows(2)
        .map(|p| (p[1] - p[0]) * (p[1] - p[0]))
        .sum::<f64>()
        / (n - 1.0);
    let var = m2 * n / (n - 1.0);
    let (skew, kurt) = if m2 > 0.0 {
        (m3 / m2.powf(1.5), m4 / (m2 * m2) - 3.0)
    } else {
        (0.0, 0.0)
    };
    [
        ldexp(var, 2 * e),
        ldexp(var.sqrt(), e),
        ldexp(hi - lo, e),
        ldexp(mad / n, e),
        ldexp(diff2.sqrt(), e),
        skew,
        kurt,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stump on feature `f` at `threshold`: left leaf `a`, right leaf `b`.
    fn stump(f: i32, threshold: f64, a: f64, b: f64) -> TreeSet {
        TreeSet::new(
            vec![1, -1, -1],
            vec![2, -1, -1],
            vec![f, 0, 0],
            vec![threshold, -2.0, -2.0],
            vec![0.0, a, b],
            vec![0],
        )
        .unwrap()
    }

    fn ramp_noise(n: usize, amp: f64, slope: f64) -> Vec<f64> {
        // a deterministic, irregular sequence
        (0..n)
            .map(|i| amp * ((i * 7919 % 211) as f64 / 105.0 - 1.0) + slope * i as f64 + 9.81)
            .collect()
    }

    #[test]
    fn the_features_are_the_textbook_statistics() {
        let w = ramp_noise(200, 0.1, 0.0);
        let x = features(&w);
        let n = w.len() as f64;
        let mean = w.iter().sum::<f64>() / n;
        let var = w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!((x[0] / var - 1.0).abs() < 1e-12);
        assert!((x[1] / var.sqrt() - 1.0).abs() < 1e-12);
        let range =
            w.iter().cloned().fold(f64::MIN, f64::max) - w.iter().cloned().fold(f64::MAX, f64::min);
        assert!((x[2] / range - 1.0).abs() < 1e-12);
        // a line changes the raw statistics, not the detrended ones
        let tilted = ramp_noise(200, 0.1, 0.01);
        let y = features(&tilted);
        for i in 7..14 {
            assert!(
                (x[i] - y[i]).abs() <= 1e-9 * x[i].abs().max(1e-9),
                "{i}: {} {}",
                x[i],
                y[i]
            );
        }
        assert!(y[0] > 2.0 * x[0]);
        // a constant window has no shape: skewness and kurtosis 0
        let flat = features(&[3.0; 50]);
        assert_eq!((flat[5], flat[6], flat[12], flat[13]), (0.0, 0.0, 0.0, 0.0));
    }

    #[test]
    fn the_power_of_two_scaling_is_exact_and_keeps_huge_windows_finite() {
        let w = ramp_noise(100, 0.3, 0.002);
        let big: Vec<f64> = w.iter().map(|v| v * 2f64.powi(300)).collect();
        let (x, xb) = (features(&w), features(&big));
        for i in 0..N_FEATURES {
            let k = [2, 1, 1, 1, 1, 0, 0][i % 7] * 300;
            assert_eq!(ldexp(x[i], k), xb[i], "feature {i}");
        }
        assert_eq!(frexp_exponent(0.75), 0);
        assert_eq!(frexp_exponent(1.0), 1);
        assert_eq!(frexp_exponent(3e-310), -1028);
    }

    #[test]
    fn trees_split_on_float32_features_and_the_ensemble_averages() {
        let w = ramp_noise(200, 0.1, 0.0);
        let v = features(&w)[0];
        let v32 = f64::from(v as f32);
        // at exactly the float32 value the sample goes left
        let gb = stump(0, v32, 1.0, 2.0);
        let rf = stump(0, v32 - 1e-12, 10.0, 20.0);
        let m = HcfEnsemble::new(200, gb, 0.5, 0.1, rf, Target::Q).unwrap();
        let q = m.predict(&w).unwrap()[0];
        assert_eq!(q, 0.5 * (0.5 + 0.1 * 1.0) + 0.5 * 20.0);
        // log-ratio: q = d·exp(out), d the detrended variance
        let m = HcfEnsemble::new(
            200,
            stump(0, 0.0, 0.0, 0.0),
            0.2,
            1.0,
            stump(0, 0.0, 0.4, 0.4),
            Target::LogRatio,
        )
        .unwrap();
        let mut buf = w.clone();
        detrend(&mut buf);
        let d = buf.iter().map(|r| r * r).sum::<f64>() / 198.0;
        let q = m.predict(&w).unwrap()[0];
        assert!((q / (d * 0.3f64.exp()) - 1.0).abs() < 1e-12, "{q}");
        // non-finite windows give NaN, a constant window (d = 0) q = 0
        let mut bad = w.clone();
        bad[9] = f64::NAN;
        assert!(m.predict(&bad).unwrap()[0].is_nan());
        let cancel = Cancel::default();
        cancel.cancel();
        assert!(
            m.predict_until(&[1.0; 200], &cancel).is_err(),
            "a set flag stops it"
        );
        assert_eq!(m.predict(&[1.0; 200]).unwrap()[0], 0.0);
        let line: Vec<f64> = (0..200).map(|k| 0.5 - 0.25 * k as f64).collect();
        assert_eq!(m.predict(&line).unwrap()[0], 0.0);
    }

    #[test]
    fn malformed_trees_are_refused() {
        let ok = || {
            (
                vec![1, -1, -1],
                vec![2, -1, -1],
                vec![0, 0, 0],
                vec![0.5, -2.0, -2.0],
                vec![0.0, 1.0, 2.0],
                vec![0],
            )
        };
        let (l, r, f, t, v, roots) = ok();
        assert!(TreeSet::new(l, r, f, t, v, roots).is_ok());
        let (mut l, r, f, t, v, roots) = ok();
        l[0] = 0; // a cycle
        assert!(TreeSet::new(l, r, f, t, v, roots)
            .unwrap_err()
            .to_string()
            .contains("node 0"));
        let (l, r, mut f, t, v, roots) = ok();
        f[0] = 14;
        assert!(TreeSet::new(l, r, f, t, v, roots).is_err());
        let (l, r, f, t, v, _) = ok();
        assert!(TreeSet::new(l, r, f, t, v, vec![3]).is_err());
    }
}
