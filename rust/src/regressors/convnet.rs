//! The forward pass of the ProNet CNN noise regressors (`pronet.models.BaselineNet` and
//! `DetrendNet`), with weights exported from the torch model: one window of raw IMU
//! samples of one channel in, its per-sample noise variance q out.
//!
//! The network (see `pronet/models.py` for the training side):
//!
//! 1. prepare: remove the window's mean (`Centre`) or its least-squares line
//!    (`Detrend`); then divide by `input_scale` (`Scaling::Fixed`) or by the prepared
//!    window's own RMS s (`Scaling::Spread`, s² floored at the smallest normal f32);
//! 2. blocks of Conv1d (zero padding `kernel / 2`, stride) → LayerNorm over the channels
//!    at each time step → LeakyReLU;
//! 3. the mean over time, then Linear layers with LeakyReLU between them, giving z,
//!    clamped to [-20, 20];
//! 4. q = `q_scale`·exp(z) (`Fixed`) or q = exp(ln s² + z) (`Spread`).
//!
//! [`Precision::F64`] (the default) runs everything in float64 from the float32 weights
//! and samples: the predictions are the torch model's function evaluated in float64 (to
//! ~1e-12 relative), whatever the batch, thread count or CPU. Torch's float32 pass is
//! an approximation of it, ~1e-6 relative for the paper's nets but up to ~1e-2 for the
//! nets trained over nine decades, mostly because it removes a window's mean (~9.8
//! m/s² for an accelerometer) in float32 (within 2e-6 on zero-mean windows, 4e-2 on
//! 9.8 m/s² ones); it also varies with the batch size.
//! [`Precision::F32`] runs the blocks (convolution, LayerNorm, LeakyReLU, pooling) in
//! float32, twice the lanes per vector, but still prepares the window (mean or line,
//! RMS s, scaling) and runs the Linear layers in float64, converting the prepared,
//! scaled window to float32 only for the first convolution: its predictions stay within
//! 1e-5 relative of float64's (measured on the shipped nets: at most 3e-6), with the same
//! determinism (the same bits on every CPU path, batch and thread count). A non-finite
//! sample gives a NaN prediction in either precision.
//!
//! Speed: activations are time-major, so the im2col row of output step t is the
//! contiguous slice of the padded input that starts at `t·stride·c_in`; the convolution
//! is a register-tiled product over those slices, with AVX-512, or AVX2 and FMA, where
//! the CPU has them (the same bits on every path). With AVX-512, a block whose channels
//! fill at most four whole vectors (the shipped nets' 16 and 32) normalises each tile
//! of steps while it is still in registers, instead of in passes over a buffer. The
//! weights and activations start on cache lines (`super::aligned`). Windows are spread
//! over rayon's threads.

use super::aligned::Aligned;
#[cfg(target_arch = "x86_64")]
use super::conv1d::avx512_norm::{self, Activations, Norm};
use super::conv1d::convolve;
use super::conv1d::tiles::lane_sum;
use super::element::Real;
use super::per_window;
use crate::cancel::Cancel;
use crate::error::{Error, Result};

#[path = "convnet_layout.rs"]
mod layout;
use layout::{check_head, sized, Block, Dense};
pub use layout::{ConvBlockWeights, DenseWeights};

/// How a window is prepared before the first convolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Prepare {
    /// Remove the window's mean.
    Centre,
    /// Remove the window's least-squares line.
    Detrend,
}

/// How the prepared window and the output are scaled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scaling {
    /// Divide by `input_scale`; q = `q_scale`·exp(z).
    Fixed { input_scale: f64, q_scale: f64 },
    /// Divide by the window's RMS s; q = s²·exp(z).
    Spread,
}

/// The element type of the convolution blocks (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// float64: the torch model's function, to ~1e-12 relative.
    #[default]
    F64,
    /// float32 blocks (twice as many lanes per vector) between a float64 preparation
    /// and head: within ~1e-5 relative of [`Precision::F64`].
    F32,
}

/// A ProNet CNN regressor's forward pass; see the module docs.
#[derive(Clone, Debug)]
pub struct ConvNet {
    window: usize,
    prepare: Prepare,
    scaling: Scaling,
    slope: f64,
    precision: Precision,
    /// The blocks laid out in float64 and in float32 (a few thousand weights each).
    blocks: Vec<Block<f64>>,
    blocks32: Vec<Block<f32>>,
    head: Vec<Dense>,
    /// The unit-norm centred time ramp the detrending projects on.
    ramp: Vec<f64>,
}

/// Per-thread buffers of one forward pass whose blocks compute in `T`.
struct Scratch<T: Real> {
    /// Each block's zero-padded, time-major input `(pad + l_in + pad) × c_in`.
    inputs: Vec<Aligned<T>>,
    /// One block's convolution output `l_out × c_pad`.
    conv: Aligned<T>,
    prepared: Vec<f64>,
    /// Each step's LayerNorm mean and 1/σ in one block.
    mean: Vec<T>,
    rstd: Vec<T>,
    /// The last block's output at one time step, and its sum over time.
    last: Vec<T>,
    pooled: Aligned<T>,
    /// The Linear layers' input and output.
    features: Vec<f64>,
    dense: Vec<f64>,
}

impl ConvNet {
    /// The network from torch's weights; checks every shape and that each block leaves
    /// at least one time step.
    pub fn new(
        window: usize,
        prepare: Prepare,
        scaling: Scaling,
        negative_slope: f64,
        blocks: Vec<ConvBlockWeights>,
        head: Vec<DenseWeights>,
    ) -> Result<Self> {
        if window < 3 {
            return Err(Error::invalid(
                "window",
                format!("must be >= 3 samples, got {window}"),
            ));
        }
        if let Scaling::Fixed {
            input_scale,
            q_scale,
        } = scaling
        {
            for (arg, v) in [("input_scale", input_scale), ("q_scale", q_scale)] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(Error::invalid(
                        arg,
                        format!("must be finite and > 0, got {v}"),
                    ));
                }
            }
        }
        if !negative_slope.is_finite() {
            return Err(Error::invalid("negative_slope", "must be finite"));
        }
        if blocks.is_empty() {
            return Err(Error::invalid("blocks", "need at least one block"));
        }
        let (mut c_prev, mut l_prev) = (1, window);
        let (mut laid, mut laid32) = (Vec::new(), Vec::new());
        for (i, b) in blocks.iter().enumerate() {
            let arg = format!("blocks[{i}]");
            let block = Block::lay_out(b, c_prev, l_prev, &arg)?;
            laid32.push(Block::lay_out(b, c_prev, l_prev, &arg)?);
            (c_prev, l_prev) = (block.c_out, block.l_out);
            laid.push(block);
        }
        check_head(&head, c_prev)?;
        let head = head.iter().map(Dense::lay_out).collect();
        let centre = (window as f64 - 1.0) / 2.0;
        let ramp: Vec<f64> = (0..window).map(|i| i as f64 - centre).collect();
        let norm = ramp.iter().map(|t| t * t).sum::<f64>().sqrt();
        Ok(Self {
            window,
            prepare,
            scaling,
            slope: negative_slope,
            precision: Precision::default(),
            blocks: laid,
            blocks32: laid32,
            head,
            ramp: ramp.into_iter().map(|t| t / norm).collect(),
        })
    }

    /// Detrend with `ramp` (`window` values) instead of the exact unit-norm centred time
    /// ramp: the one the torch model stores, computed in float32, so that its
    /// detrending (which leaves ~1e-7 of a line) is reproduced too.
    pub fn with_ramp(mut self, ramp: &[f32]) -> Result<Self> {
        sized("ramp", "ramp", ramp.len(), self.window)?;
        if !ramp.iter().all(|t| t.is_finite()) {
            return Err(Error::invalid("ramp", "must be finite"));
        }
        self.ramp = ramp.iter().map(|&t| f64::from(t)).collect();
        Ok(self)
    }

    /// This net computing its blocks in `precision` (a new net is [`Precision::F64`]).
    pub fn with_precision(mut self, precision: Precision) -> Self {
        self.precision = precision;
        self
    }

    /// Samples per window.
    pub fn window(&self) -> usize {
        self.window
    }

    /// The element type of the blocks.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// q `(n,)` \[(unit)² per sample\] for `n` windows of [`Self::window`] samples each,
    /// `windows` row-major `(n, window)`; windows run in parallel on rayon's threads.
    pub fn predict(&self, windows: &[f32]) -> Result<Vec<f64>> {
        self.predict_until(windows, &Cancel::default())
    }

    /// [`Self::predict`] that stops with [`crate::error::Error::Cancelled`] soon after
    /// `cancel` is set.
    pub fn predict_until(&self, windows: &[f32], cancel: &Cancel) -> Result<Vec<f64>> {
        match self.precision {
            Precision::F64 => self.predict_with(&self.blocks, windows, cancel),
            Precision::F32 => self.predict_with(&self.blocks32, windows, cancel),
        }
    }

    /// [`Self::predict_until`] with these blocks.
    fn predict_with<T: Real>(
        &self,
        blocks: &[Block<T>],
        windows: &[f32],
        cancel: &Cancel,
    ) -> Result<Vec<f64>> {
        per_window(
            windows,
            self.window,
            8,
            cancel,
            || self.scratch(blocks),
            |w, s| self.forward(blocks, w, s),
        )
    }

    fn scratch<T: Real>(&self, blocks: &[Block<T>]) -> Scratch<T> {
        let conv = blocks.iter().map(|b| b.l_out * b.c_pad).max();
        let c_last = blocks.last().map_or(0, |b| b.c_out);
        let steps = blocks.iter().map(|b| b.l_out).max().unwrap_or(0);
        let width = self
            .head
            .iter()
            .map(|d| d.n_out)
            .max()
            .unwrap_or(0)
            .max(c_last);
        Scratch {
            inputs: blocks
                .iter()
                .map(|b| Aligned::zeros((b.l_in + 2 * b.pad) * b.c_in))
                .collect(),
            conv: Aligned::zeros(conv.unwrap_or(0)),
            prepared: vec![0.0; self.window],
            mean: vec![T::ZERO; steps],
            rstd: vec![T::ZERO; steps],
            last: vec![T::ZERO; c_last],
            pooled: Aligned::zeros(c_last),
            features: Vec::with_capacity(width),
            dense: Vec::with_capacity(width),
        }
    }

    /// q of one window (see the module docs) through `blocks`; the whole pass is
    /// compiled for AVX-512 or AVX where the CPU has them, with the same arithmetic in
    /// every lane (no fused multiply-add outside the convolution's explicit ones, the
    /// same order of operations), so every build agrees bit for bit.
    fn forward<T: Real>(&self, blocks: &[Block<T>], x: &[f32], s: &mut Scratch<T>) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F, checked just above.
            return unsafe { self.forward_avx512(blocks, x, s) };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX, checked just above.
            return unsafe { self.forward_avx(blocks, x, s) };
        }
        self.forward_body(blocks, x, s, false)
    }

    /// With AVX-512, blocks whose channels fill whole vectors run convolution,
    /// LayerNorm and LeakyReLU in one pass ([`avx512_norm`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn forward_avx512<T: Real>(&self, blocks: &[Block<T>], x: &[f32], s: &mut Scratch<T>) -> f64 {
        self.forward_body(blocks, x, s, true)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn forward_avx<T: Real>(&self, blocks: &[Block<T>], x: &[f32], s: &mut Scratch<T>) -> f64 {
        self.forward_body(blocks, x, s, false)
    }

    /// The pass; `fused`: the CPU has AVX-512F (see [`Self::forward_avx512`]). The
    /// window is prepared and scaled in float64, then rounded to `T` for the blocks;
    /// their pooled output is the float64 head's input.
    #[inline(always)]
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
    fn forward_body<T: Real>(
        &self,
        blocks: &[Block<T>],
        x: &[f32],
        s: &mut Scratch<T>,
        fused: bool,
    ) -> f64 {
        let (scale, log_s2) = self.prepare_window(x, &mut s.prepared);
        let start = blocks[0].pad; // c_in = 1
        for (dst, p) in s.inputs[0][start..start + self.window]
            .iter_mut()
            .zip(&s.prepared)
        {
            *dst = T::from_f64(p * scale);
        }
        s.pooled.iter_mut().for_each(|v| *v = T::ZERO);
        for (i, b) in blocks.iter().enumerate() {
            #[cfg(target_arch = "x86_64")]
            if fused && avx512_norm::takes::<T>(b.c_out, b.c_pad) {
                // SAFETY: `fused` says the CPU has AVX-512F; `takes` holds.
                unsafe { self.run_block_fused(blocks, i, s) };
                continue;
            }
            self.run_block(blocks, i, s);
        }
        let l = blocks.last().map_or(1, |b| b.l_out) as f64;
        s.features.clear();
        s.features.extend(s.pooled.iter().map(|v| v.to_f64() / l));
        let z = self.head_output(s).clamp(-20.0, 20.0);
        match self.scaling {
            Scaling::Fixed { q_scale, .. } => q_scale * z.exp(),
            Scaling::Spread => (log_s2 + z).exp(),
        }
    }

    /// The window minus its mean (and line) into `prepared`, in float64; the factor
    /// that scales it for the first block and ln s² (0 for `Fixed`).
    #[inline(always)]
    fn prepare_window(&self, x: &[f32], prepared: &mut [f64]) -> (f64, f64) {
        let n = self.window as f64;
        let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        for (p, &v) in prepared.iter_mut().zip(x) {
            *p = f64::from(v) - mean;
        }
        if self.prepare == Prepare::Detrend {
            let slope: f64 = prepared.iter().zip(&self.ramp).map(|(p, t)| p * t).sum();
            for (p, t) in prepared.iter_mut().zip(&self.ramp) {
                *p -= slope * t;
            }
        }
        match self.scaling {
            Scaling::Fixed { input_scale, .. } => (1.0 / input_scale, 0.0),
            Scaling::Spread => {
                let s2 = prepared.iter().map(|p| p * p).sum::<f64>() / n;
                // torch's clamp_min keeps a NaN; f64::max would drop it
                let s2 = if s2.is_nan() {
                    s2
                } else {
                    s2.max(f64::from(f32::MIN_POSITIVE))
                };
                (1.0 / s2.sqrt(), s2.ln())
            }
        }
    }

    /// Block `i`: convolution, LayerNorm, LeakyReLU, into the next block's padded input
    /// or (the last block) summed over time into `s.pooled`.
    #[inline(always)]
    fn run_block<T: Real>(&self, blocks: &[Block<T>], i: usize, s: &mut Scratch<T>) {
        let b = &blocks[i];
        let (done, rest) = s.inputs.split_at_mut(i + 1);
        let conv = &mut s.conv[..b.l_out * b.c_pad];
        let (step, kdim) = (b.stride * b.c_in, b.kernel * b.c_in);
        convolve(&done[i], step, kdim, &b.w, b.c_pad, &b.bias, conv);
        // LayerNorm statistics of every step first, each in its own pass over the steps
        // (means, variances, 1/σ), so that the sums, divisions and square roots of
        // successive steps overlap instead of waiting on one another
        let (mean, rstd) = (&mut s.mean[..b.l_out], &mut s.rstd[..b.l_out]);
        let c = T::from_f64(b.c_out as f64);
        for (row, m) in conv.chunks_exact(b.c_pad).zip(mean.iter_mut()) {
            *m = lane_sum(&row[..b.c_out], |v| v) / c;
        }
        for ((row, &m), r) in conv
            .chunks_exact(b.c_pad)
            .zip(mean.iter())
            .zip(rstd.iter_mut())
        {
            *r = lane_sum(&row[..b.c_out], |v| (v - m) * (v - m)) / c + b.eps;
        }
        for r in rstd.iter_mut() {
            *r = T::ONE / r.sqrt();
        }
        let steps = conv.chunks_exact(b.c_pad).zip(mean.iter().zip(rstd.iter()));
        match rest.first_mut() {
            Some(next) => {
                let off = blocks[i + 1].pad * b.c_out;
                let out = &mut next[off..off + b.l_out * b.c_out];
                for ((row, (&m, &r)), dst) in steps.zip(out.chunks_exact_mut(b.c_out)) {
                    self.norm_act(b, &row[..b.c_out], m, r, dst);
                }
            }
            None => {
                for (row, (&m, &r)) in steps {
                    self.norm_act(b, &row[..b.c_out], m, r, &mut s.last);
                    for (acc, &v) in s.pooled.iter_mut().zip(&s.last) {
                        *acc += v;
                    }
                }
            }
        }
    }

    /// [`Self::run_block`] in one pass ([`avx512_norm::convolve_norm`]).
    ///
    /// # Safety
    /// The CPU must have AVX-512F, and `avx512_norm::takes` must hold for the block.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn run_block_fused<T: Real>(&self, blocks: &[Block<T>], i: usize, s: &mut Scratch<T>) {
        let b = &blocks[i];
        let (done, rest) = s.inputs.split_at_mut(i + 1);
        let norm = Norm {
            gamma: &b.gamma,
            beta: &b.beta,
            eps: b.eps,
            slope: T::from_f64(self.slope),
        };
        let out = match rest.first_mut() {
            Some(next) => {
                let off = blocks[i + 1].pad * b.c_out;
                Activations::Rows(&mut next[off..off + b.l_out * b.c_out])
            }
            None => Activations::Pool(&mut s.pooled),
        };
        let (step, kdim) = (b.stride * b.c_in, b.kernel * b.c_in);
        // SAFETY: the caller's contract (`convolve_norm` asserts the layouts, as
        // `convolve` does in `run_block`).
        unsafe {
            avx512_norm::convolve_norm::<T::V512>(
                &done[i], step, kdim, &b.w, b.c_pad, &b.bias, b.l_out, &norm, out,
            )
        };
    }

    /// LayerNorm over the channels of one time step (its mean and 1/σ given), then
    /// LeakyReLU, into `dst`.
    #[inline(always)]
    fn norm_act<T: Real>(&self, b: &Block<T>, row: &[T], mean: T, rstd: T, dst: &mut [T]) {
        let slope = T::from_f64(self.slope);
        for (((d, &v), &g), &bt) in dst.iter_mut().zip(row).zip(&b.gamma).zip(&b.beta) {
            let y = (v - mean) * rstd * g + bt;
            *d = if y >= T::ZERO { y } else { y * slope };
        }
    }

    /// The Linear layers (LeakyReLU between them) on the pooled features in
    /// `s.features`: z. Each output is its bias plus the products summed in the
    /// inputs' order, as the plain loop over one output adds them.
    #[inline(always)]
    fn head_output<T: Real>(&self, s: &mut Scratch<T>) -> f64 {
        let last = self.head.len() - 1;
        for (i, d) in self.head.iter().enumerate() {
            let acc = &mut s.dense;
            acc.clear();
            acc.resize(d.n_out, 0.0);
            for (&x, row) in s.features.iter().zip(d.wt.chunks_exact(d.n_out)) {
                for (a, &w) in acc.iter_mut().zip(row) {
                    *a += w * x;
                }
            }
            for (a, &b) in acc.iter_mut().zip(&d.bias) {
                let y = b + *a;
                *a = if i == last || y >= 0.0 {
                    y
                } else {
                    y * self.slope
                };
            }
            std::mem::swap(&mut s.features, &mut s.dense);
        }
        s.features[0]
    }
}

#[cfg(test)]
#[path = "convnet_tests.rs"]
mod tests;
