//! The closes of the covariance step a forward pass keeps for the smoother
//! ([`KeptCloses`]): the backward pass then reads them instead of rebuilding them
//! (`super::steps`).

use crate::ekf::calibration::Cross;
use crate::ekf::calibration::DvlCov;
use crate::ekf::Point;
use crate::ekf::{Ekf, Matrix15, Transition};
use nalgebra::SMatrix;

/// A close of the covariance step as the forward pass made it (see
/// [`KeptCloses::note`]): the navigation rows of the step's Φ, the covariance it left
/// (the calibration blocks too) and the forward velocity \[m/s, NED\] there, before any
/// update of its epoch (the one the forward σ at the close is read at). The covariance
/// is symmetric bit for bit (every step writes it so), so its upper triangle alone is
/// kept: 2.0 kB a close instead of 2.9.
#[derive(Clone, Debug)]
pub struct KeptClose {
    pub(crate) phi: SMatrix<f64, 9, 15>,
    /// The time `phi` spans \[s\].
    pub(crate) dt: f64,
    upper: [f64; UPPER],
    pub(crate) point: Point,
    pub(crate) calibration: Option<Box<(Cross, DvlCov)>>,
}

/// The entries of a 15 × 15 matrix's upper triangle, the diagonal included.
const UPPER: usize = 15 * 16 / 2;

impl KeptClose {
    /// The covariance the close left (15 states).
    pub(crate) fn p(&self) -> Matrix15 {
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

/// The closes of the covariance step a forward pass kept (see [`KeptCloses::note`]),
/// in order, each with the epoch it was made at (the epoch whose step closed it).
#[derive(Clone, Debug, Default)]
pub struct KeptCloses {
    pub(crate) epochs: Vec<usize>,
    pub(crate) closes: Vec<KeptClose>,
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

impl KeptCloses {
    /// At a close of the covariance step at the epoch `epoch` (its transition `phi`),
    /// before any update of the epoch: keep it (its Φ, the covariance it left and the
    /// velocity there, 2.0 kB; 2.6 kB with the calibration states), for the backward
    /// pass to read instead of rebuilding it.
    pub fn note(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        let p = &ekf.p;
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
        self.epochs.push(epoch);
        self.closes.push(KeptClose {
            phi: phi.nav_rows(),
            dt: phi.dt,
            upper,
            point: ekf.point(),
            calibration: ekf.calibration.as_ref().map(|c| Box::new((c.cross, c.cov))),
        });
    }
}
