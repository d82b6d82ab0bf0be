//! Clock alignment of recorded data: the cost that pins the ground truth's clock to the
//! IMU's (`pronet.alignment.estimate_gt_clock`).
//!
//! A candidate clock maps the truth's stamps τ to IMU time `t = offset + scale·τ`. Over
//! each pair of consecutive truth rows both sides give an attitude increment: the
//! truth's own Euler-angle step, and the gyro's Euler rates integrated between the two
//! mapped times (`cum`: their running integral at the IMU sample edges, interpolated
//! linearly, as `numpy.interp` does). The cost of a clock is the mean squared
//! difference over the pairs whose both ends map inside the IMU record; fewer than
//! [`MIN_PAIRS`] such pairs cost infinity. The grid search over clocks stays in Python;
//! this evaluates one scale and many offsets in one pass, walking the IMU edges instead
//! of searching them for every point.
//!
//! The scale acts about t = 0 of the times it is given: the caller passes every time
//! counted from the section's start (`pronet.recorded.alignment.since_epoch`), so that
//! a clock does not depend on the stamps' origin (Unix time).

use crate::error::{Error, Result};
use crate::memory::Estimate;
use std::mem::size_of;

/// Fewer valid pairs of truth rows than this: the clock does not overlap the IMU.
pub const MIN_PAIRS: usize = 10;

/// `numpy.interp`'s value at `x` in segment `j` (`xp[j] <= x < xp[j + 1]`), column `c`,
/// with its formula and its fallback where that gives NaN.
#[inline]
fn lerp(xp: &[f64], fp: &[[f64; 3]], j: usize, x: f64, c: usize) -> f64 {
    if x == xp[xp.len() - 1] {
        return fp[fp.len() - 1][c];
    }
    let slope = (fp[j + 1][c] - fp[j][c]) / (xp[j + 1] - xp[j]);
    let mut y = slope * (x - xp[j]) + fp[j][c];
    if y.is_nan() {
        y = slope * (x - xp[j + 1]) + fp[j + 1][c];
        if y.is_nan() && fp[j][c] == fp[j + 1][c] {
            y = fp[j][c];
        }
    }
    y
}

/// The attitude-increment cost (see the module docs) of the clocks `(offset, scale)`
/// for every `offset` in `offsets`.
///
/// Args: `edges` `(K,)` the IMU sample edges \[s\], increasing; `cum` `(K, 3)` the
/// integrated Euler rates at the edges \[rad\]; `gt_time` `(R,)` the truth's stamps \[s\];
/// `gt_step` `(R - 1, 3)` its Euler-angle steps \[rad\]; `scale` > 0.
pub fn attitude_increment_costs(
    edges: &[f64],
    cum: &[[f64; 3]],
    gt_time: &[f64],
    gt_step: &[[f64; 3]],
    offsets: &[f64],
    scale: f64,
) -> Result<Vec<f64>> {
    if edges.len() < 2 || cum.len() != edges.len() {
        return Err(Error::invalid(
            "cum",
            format!(
                "needs one row per edge (>= 2), got {} for {}",
                cum.len(),
                edges.len()
            ),
        ));
    }
    if !edges.windows(2).all(|e| e[0] < e[1]) {
        return Err(Error::invalid("edges", "must be strictly increasing"));
    }
    if gt_time.is_empty() || gt_step.len() + 1 != gt_time.len() {
        return Err(Error::invalid(
            "gt_step",
            format!(
                "needs len(gt_time) - 1 rows, got {} for {}",
                gt_step.len(),
                gt_time.len()
            ),
        ));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(
            "scale",
            format!("must be finite and > 0, got {scale}"),
        ));
    }
    let (lo, hi) = (edges[0], edges[edges.len() - 1]);
    let n_off = offsets.len();
    // Per offset: its sum, its pair count, the value at the previous truth row, its cost.
    let each = size_of::<f64>() * 3 + size_of::<usize>() + size_of::<Option<[f64; 3]>>();
    let mut memory = Estimate::default();
    memory.add(
        "offsets",
        "clocks",
        (n_off as f64, each as f64),
        "fewer offsets per call (a search in rounds)",
    );
    memory.check("this clock search")?;
    let mut sq = vec![0.0; n_off];
    let mut pairs = vec![0usize; n_off];
    // value at the previous truth row (None: outside) and the segment found for it
    let mut prev: Vec<Option<[f64; 3]>> = vec![None; n_off];
    for (r, &tau) in gt_time.iter().enumerate() {
        // the segment of the previous offset: ascending offsets move t on by a few
        // samples, so a short walk finds the next one; anything else is searched
        let mut j = 0;
        for k in 0..n_off {
            let t = offsets[k] + scale * tau;
            let cur = if t >= lo && t <= hi {
                let near = edges[(j + 8).min(edges.len() - 1)];
                if t < edges[j] || t >= near {
                    j = edges.partition_point(|&e| e <= t).saturating_sub(1);
                } else {
                    while j + 2 < edges.len() && edges[j + 1] <= t {
                        j += 1;
                    }
                }
                j = j.min(edges.len() - 2);
                Some([0, 1, 2].map(|c| lerp(edges, cum, j, t, c)))
            } else {
                None
            };
            if let (Some(a), Some(b), true) = (prev[k], cur, r > 0) {
                let g = gt_step[r - 1];
                sq[k] += (0..3).map(|c| (b[c] - a[c] - g[c]).powi(2)).sum::<f64>();
                pairs[k] += 1;
            }
            prev[k] = cur;
        }
    }
    Ok(sq
        .iter()
        .zip(&pairs)
        .map(|(&s, &n)| {
            if n >= MIN_PAIRS {
                s / n as f64
            } else {
                f64::INFINITY
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    type Scene = (Vec<f64>, Vec<[f64; 3]>, Vec<f64>, Vec<[f64; 3]>);

    /// A gyro turning at 0.1·sin(0.3 t) rad/s in each axis, sampled at 100 Hz, and a
    /// truth stamped at 1 Hz on a clock shifted by `offset` and stretched by `scale`.
    fn scene(offset: f64, scale: f64) -> Scene {
        let edges: Vec<f64> = (0..=6000).map(|i| i as f64 * 0.01).collect();
        let angle = |t: f64| {
            [
                1.0 - (0.3 * t).cos(),
                0.5 * (1.0 - (0.3 * t).cos()),
                -(1.0 - (0.3 * t).cos()),
            ]
        };
        let cum: Vec<[f64; 3]> = edges.iter().map(|&t| angle(t).map(|a| a / 3.0)).collect();
        let gt_time: Vec<f64> = (2..55).map(|i| i as f64).collect();
        let truth: Vec<[f64; 3]> = gt_time
            .iter()
            .map(|&tau| angle(offset + scale * tau).map(|a| a / 3.0))
            .collect();
        let gt_step = truth
            .windows(2)
            .map(|w| [0, 1, 2].map(|c| w[1][c] - w[0][c]))
            .collect();
        (edges, cum, gt_time, gt_step)
    }

    #[test]
    fn the_true_clock_costs_nothing_and_others_cost_more() {
        let (edges, cum, gt_time, gt_step) = scene(0.4, 1.0);
        let offsets: Vec<f64> = (-20..=20).map(|k| 0.4 + k as f64 * 0.02).collect();
        let c = attitude_increment_costs(&edges, &cum, &gt_time, &gt_step, &offsets, 1.0).unwrap();
        let best = c
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert_eq!(best, 20);
        assert!(c[20] < 1e-12, "{}", c[20]);
        assert!(c[0] > 1e-6 && c[40] > 1e-6);
    }

    #[test]
    fn the_walk_equals_a_search_for_every_point() {
        let (edges, cum, gt_time, gt_step) = scene(0.0, 1.0);
        // offsets out of order, far apart and close together
        let offsets = [3.0, -1.0, 0.013, 0.014, 2.5, -1.9];
        let fast =
            attitude_increment_costs(&edges, &cum, &gt_time, &gt_step, &offsets, 0.999).unwrap();
        for (k, &o) in offsets.iter().enumerate() {
            let one =
                attitude_increment_costs(&edges, &cum, &gt_time, &gt_step, &[o], 0.999).unwrap();
            assert_eq!(one[0].to_bits(), fast[k].to_bits(), "offset {o}");
        }
    }

    #[test]
    fn no_overlap_costs_infinity_and_bad_input_is_named() {
        let (edges, cum, gt_time, gt_step) = scene(0.0, 1.0);
        let c = attitude_increment_costs(&edges, &cum, &gt_time, &gt_step, &[100.0], 1.0).unwrap();
        assert_eq!(c[0], f64::INFINITY);
        let err = attitude_increment_costs(&edges, &cum[1..], &gt_time, &gt_step, &[0.0], 1.0);
        assert!(err
            .unwrap_err()
            .to_string()
            .starts_with("cum: needs one row per edge"));
        let err = attitude_increment_costs(&edges, &cum, &gt_time, &gt_step, &[0.0], 0.0);
        assert!(err
            .unwrap_err()
            .to_string()
            .starts_with("scale: must be finite and > 0"));
    }
}
