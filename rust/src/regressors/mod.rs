//! The learned noise regressors' predictions, from weights trained in Python: a window of
//! raw IMU samples of one channel in, its per-sample noise variance q out. Training
//! stays in Python (torch, scikit-learn); these are the forward passes the hybrid loop
//! calls hundreds of times per mission.
//!
//! - [`convnet`]: the ProNet CNNs (`BaselineNet`, `DetrendNet`);
//! - [`hcf`]: the handcrafted-feature ensemble (gradient boosting and a random forest).

mod aligned;
mod conv1d;
pub mod convnet;
mod element;
pub mod hcf;

use crate::cancel::Cancel;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// `f(w, scratch)` for each window `w` of `windows` (`(n, window)` row-major), in
/// parallel on rayon's threads, each thread with its own `scratch()`; at least
/// `min_len` windows per task. Stops with [`Error::Cancelled`] soon after `cancel` is
/// set (each window is checked before it is computed).
pub(crate) fn per_window<T: Sync, S>(
    windows: &[T],
    window: usize,
    min_len: usize,
    cancel: &Cancel,
    scratch: impl Fn() -> S + Sync + Send,
    f: impl Fn(&[T], &mut S) -> f64 + Sync + Send,
) -> Result<Vec<f64>> {
    if window == 0 || !windows.len().is_multiple_of(window) {
        return Err(Error::invalid(
            "windows",
            format!(
                "{} samples are not whole windows of {window}",
                windows.len()
            ),
        ));
    }
    let mut q = vec![0.0; windows.len() / window];
    q.par_iter_mut()
        .zip(windows.par_chunks_exact(window))
        .with_min_len(min_len)
        .for_each_init(scratch, |s, (q, w)| {
            if !cancel.is_cancelled() {
                *q = f(w, s);
            }
        });
    cancel.check()?;
    Ok(q)
}
