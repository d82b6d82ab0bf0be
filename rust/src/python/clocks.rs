//! `attitude_increment_costs`: the clock-alignment cost of recorded data (the grid search
//! around it is `pronet.alignment`).

use super::call::detached;
use super::convert::{as_rows, as_values, column, readonly_column, readonly_rows, real_arg, rows};
use crate::clocks;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

/// The clock-alignment cost of ``pronet.recorded.alignment.estimate_gt_clock`` for the clocks
/// ``(offset, scale)``, one per offset: the mean squared difference between the
/// truth's Euler-angle steps ``gt_step (R - 1, 3)`` [rad] and the integrated gyro Euler
/// rates ``cum (K, 3)`` [rad] at the IMU ``edges (K,)`` [s], interpolated linearly at
/// ``offset + scale·gt_time``, over the pairs of rows mapped inside the edges; inf
/// with fewer than 10 such pairs. More offsets than this process can still take are a
/// ``ValueError`` naming ``offsets`` (docs/results/performance.md, "Memory").
#[pyfunction]
#[pyo3(signature = (edges, cum, gt_time, gt_step, offsets, scale))]
fn attitude_increment_costs<'py>(
    py: Python<'py>,
    edges: &Bound<'py, PyAny>,
    cum: &Bound<'py, PyAny>,
    gt_time: &Bound<'py, PyAny>,
    gt_step: &Bound<'py, PyAny>,
    offsets: &Bound<'py, PyAny>,
    scale: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    // Read in place: a clock search calls this ~90 times per section with the same
    // 40,000 edges, which copying took a fifth of the search's time.
    let edges = readonly_column(edges, "edges")?;
    let cum = readonly_rows::<3>(cum, "cum")?;
    let gt_time = column(gt_time, "gt_time")?;
    let gt_step = rows::<3>(gt_step, "gt_step")?;
    let offsets = column(offsets, "offsets")?;
    let scale = real_arg(scale, "scale")?;
    let (edges, cum) = (as_values(&edges), as_rows::<3>(&cum));
    let (edges, cum) = (&*edges, &*cum);
    let costs = detached(py, move || {
        clocks::attitude_increment_costs(edges, cum, &gt_time, &gt_step, &offsets, scale)
    })?;
    Ok(costs.into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(attitude_increment_costs, m)?)
}
