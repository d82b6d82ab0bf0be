//! The closes of the covariance step a forward pass keeps for the smoother
//! ([`Ekf::keep_closes`]): the backward pass then reads them instead of rebuilding them
//! (`super::steps`).

use crate::ekf::calibration::Cross;
use crate::ekf::transition::Transition;
use crate::ekf::{Ekf, Matrix15};
use nalgebra::{Matrix4, SMatrix, Vector3};

/// A close of the covariance step as the forward pass made it (see
/// [`Ekf::keep_closes`]): the navigation rows of the step's Φ, the covariance it left
/// (the calibration blocks too) and the forward velocity \[m/s, NED\] there, before any
/// update of its epoch (the one the forward σ at the close is read at). The covariance
/// is symmetric bit for bit (every step writes it so), so its upper triangle alone is
/// kept: 2.0 kB a close instead of 2.9.
#[derive(Clone, Debug)]
pub struct KeptClose {
    pub(in crate::ekf) phi: SMatrix<f64, 9, 15>,
    upper: [f64; UPPER],
    pub(in crate::ekf) vel: Vector3<f64>,
    pub(in crate::ekf) calibration: Option<Box<(Cross, Matrix4<f64>)>>,
}

/// The entries of a 15 × 15 matrix's upper triangle, the diagonal included.
const UPPER: usize = 15 * 16 / 2;

impl KeptClose {
    /// The covariance the close left (15 states).
    pub(in crate::ekf) fn p(&self) -> Matrix15 {
        let mut p = Matrix15::zeros();
        let mut k = 0;
        for j in 0..15 {
            for i in 0..=j {
                p[(i, j)] = self.upper[k];
                p[(j, i)] = self.upper[k];
                k += 1;
            }
        }
        p
    }
}

/// The closes of the covariance step a forward pass kept (see [`Ekf::keep_closes`]),
/// in order, each with the epoch it was made at (the epoch whose step closed it).
#[derive(Clone, Debug, Default)]
pub struct KeptCloses {
    pub(in crate::ekf) epochs: Vec<usize>,
    pub(in crate::ekf) closes: Vec<KeptClose>,
}

impl KeptCloses {
    /// None kept yet, with room for `capacity`.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            epochs: Vec::with_capacity(capacity),
            closes: Vec::with_capacity(capacity),
        }
    }
}

/// Keeping the closes of the covariance step for the smoother.
impl Ekf {
    /// Keep every close of a covariance step from now on (its Φ, the covariance it left
    /// and the velocity there, 2.0 kB; 2.6 kB with the calibration states) for
    /// [`Ekf::take_closes`]: the smoother then reads them instead of rebuilding them.
    pub fn keep_closes(&mut self) {
        self.kept_closes.get_or_insert_with(Vec::new);
    }

    /// Move the closes kept since the last call to `out`, each with `epoch` (none
    /// without [`Ekf::keep_closes`]). The filter's own list stays short (a copy of the
    /// filter, to read its σ brought up to date, copies it).
    pub fn take_closes(&mut self, epoch: usize, out: &mut KeptCloses) {
        if let Some(kept) = self.kept_closes.as_mut() {
            out.epochs.extend(std::iter::repeat_n(epoch, kept.len()));
            out.closes.append(kept);
        }
    }

    /// At a close of the covariance step (its transition `phi`), before any update of
    /// the epoch: keep it if asked.
    pub(in crate::ekf) fn note_close(&mut self, phi: &Transition) {
        let Some(kept) = self.kept_closes.as_mut() else {
            return;
        };
        let p = &self.p;
        debug_assert_eq!(
            *p,
            p.transpose(),
            "a kept covariance must be symmetric bit for bit"
        );
        let mut upper = [0.0; UPPER];
        let mut k = 0;
        for j in 0..15 {
            let column = &p.as_slice()[15 * j..15 * j + j + 1];
            upper[k..k + j + 1].copy_from_slice(column);
            k += j + 1;
        }
        kept.push(KeptClose {
            phi: phi.nav_rows(),
            upper,
            vel: self.nav.vel,
            calibration: self
                .calibration
                .as_ref()
                .map(|c| Box::new((c.cross, c.cov))),
        });
    }
}
