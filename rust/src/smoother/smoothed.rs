//! The smoothed solution at every epoch ([`Smoothed`]): the forward solution corrected
//! by the backward pass, as a [`Sink`].

use super::forward::Forward;
use super::sink::{changed_sigma, Sink};
use crate::ekf::calibration::{correct_dvl, DvlErrors, N_CALIBRATED, N_DVL, SCALE};
use crate::ekf::DvlMounting;
use crate::ekf::{correct, FilterConfig, Matrix15, Vector15};
use crate::mechanization::NavState;
use nalgebra::{SMatrix, SVector, Vector3};

/// The smoothed solution at every epoch of the forward pass.
#[derive(Clone, Debug, Default)]
pub struct Smoothed {
    pub nav: Vec<NavState>,
    /// `[b_a, b_g]` per epoch.
    pub bias: Vec<[f64; 6]>,
    /// 1σ of the 15 error states in the classic coordinates, per epoch.
    pub sigma: Vec<[f64; 15]>,
    /// With the DVL error states: `[k̂, roll, pitch, yaw, b̂]` per epoch, as
    /// [`crate::recorded::FilterOutput::calibration`], and the 1σ of `[δk, δμ, δb]`
    /// (empty without).
    pub calibration: Vec<DvlErrors>,
    pub calibration_sigma: Vec<DvlErrors>,
    /// The smoothed covariance at each node's epoch (in the order of the nodes), in
    /// the filter's own error coordinates about the forward solution's velocity (the
    /// 15 navigation and bias states).
    pub node_covariance: Vec<(usize, Matrix15)>,
    /// Whether `node_covariance` is kept (not for a thinned pass).
    keeps_nodes: bool,
}

impl Smoothed {
    /// The forward solution, to be corrected, with room for σ.
    pub(super) fn start(forward: &Forward<'_>, nodes: usize) -> Self {
        let n = forward.nav.len();
        let calibrated = !forward.calibration.is_empty();
        Self {
            nav: forward.nav.to_vec(),
            bias: forward.bias.to_vec(),
            sigma: vec![[f64::NAN; 15]; n],
            calibration: forward.calibration.to_vec(),
            calibration_sigma: vec![[f64::NAN; N_DVL]; if calibrated { n } else { 0 }],
            node_covariance: Vec::with_capacity(nodes),
            keeps_nodes: true,
        }
    }

    /// [`Smoothed::start`] at the kept rows of a thinned pass (`forward` holds them),
    /// without the smoothed covariance at the nodes.
    pub(super) fn rows(forward: &Forward<'_>) -> Self {
        Self {
            keeps_nodes: false,
            ..Self::start(forward, 0)
        }
    }
}

impl Sink for Smoothed {
    /// Remove the smoothed error `ds` from the forward solution at epoch `i` (the
    /// filter's feedback: [`correct`], and the calibration's).
    fn apply<const N: usize>(&mut self, i: usize, ds: &SVector<f64, N>, cfg: &FilterConfig) {
        let b = self.bias[i];
        let (mut ab, mut gb) = (
            Vector3::new(b[0], b[1], b[2]),
            Vector3::new(b[3], b[4], b[5]),
        );
        let nav: Vector15 = ds.fixed_rows::<15>(0).into_owned();
        correct(&mut self.nav[i], &mut ab, &mut gb, &nav, &cfg.coordinates());
        self.bias[i] = [ab[0], ab[1], ab[2], gb[0], gb[1], gb[2]];
        if N == N_CALIBRATED {
            let c = self.calibration[i];
            let mut mounting = DvlMounting::from_angles(c[0], [c[1], c[2], c[3]]);
            let mut bias = Vector3::new(c[4], c[5], c[6]);
            let dc = std::array::from_fn(|k| ds[SCALE + k]);
            correct_dvl(&mut mounting, &mut bias, &dc);
            let a = mounting.angles();
            self.calibration[i] = [mounting.scale, a[0], a[1], a[2], bias[0], bias[1], bias[2]];
        }
    }

    /// σ at epoch `i`: the forward σ there (`forward.sigma`) changed by `change`.
    fn set_change<const N: usize>(
        &mut self,
        i: usize,
        change: &SVector<f64, N>,
        forward: &Forward<'_>,
    ) {
        let sigma = forward.sigma.get(i).copied().unwrap_or([f64::NAN; 15]);
        self.sigma[i] = std::array::from_fn(|j| changed_sigma(sigma[j], change[j]));
        if let (true, Some(out)) = (N == N_CALIBRATED, self.calibration_sigma.get_mut(i)) {
            let sigma = forward.calibration_sigma.get(i).copied();
            let sigma = sigma.unwrap_or([f64::NAN; N_DVL]);
            *out = std::array::from_fn(|k| changed_sigma(sigma[k], change[SCALE + k]));
        }
    }

    /// Keep the smoothed covariance at a node's epoch (its 15-state block).
    fn keep_node<const N: usize>(&mut self, epoch: usize, ps: &SMatrix<f64, N, N>) {
        if self.keeps_nodes {
            let p = ps.fixed_view::<15, 15>(0, 0).into_owned();
            self.node_covariance.push((epoch, p));
        }
    }
}
