//! The torch weights of a ProNet CNN ([`ConvBlockWeights`], [`DenseWeights`]), and how
//! they are checked and laid out for its forward pass ([`super::ConvNet`]): each
//! block's kernel as a `(kernel·c_in) × c_pad` matrix for the tiled convolution, in
//! float64 or float32, each Linear layer input-major in float64.

use super::super::aligned::Aligned;
use super::super::element::Real;
use crate::error::{Error, Result};

/// One Conv1d → LayerNorm → LeakyReLU block, in torch's layouts.
#[derive(Clone, Debug)]
pub struct ConvBlockWeights {
    /// `(c_out, c_in, kernel)` row-major (`nn.Conv1d.weight`).
    pub weight: Vec<f32>,
    /// `(c_out,)`.
    pub bias: Vec<f32>,
    pub c_in: usize,
    pub c_out: usize,
    pub kernel: usize,
    pub stride: usize,
    /// LayerNorm's `weight`, `bias` (`(c_out,)` each) and `eps`.
    pub norm_weight: Vec<f32>,
    pub norm_bias: Vec<f32>,
    pub norm_eps: f32,
}

/// One Linear layer, in torch's layout.
#[derive(Clone, Debug)]
pub struct DenseWeights {
    /// `(n_out, n_in)` row-major (`nn.Linear.weight`).
    pub weight: Vec<f32>,
    /// `(n_out,)`.
    pub bias: Vec<f32>,
    pub n_in: usize,
    pub n_out: usize,
}

/// A block laid out for the tiled convolution in `T`.
#[derive(Clone, Debug)]
pub(super) struct Block<T: Real> {
    /// `(kernel·c_in) × c_pad`: row `k·c_in + i`, column o is torch's `weight[o, i, k]`;
    /// columns beyond `c_out` are zero.
    pub(super) w: Aligned<T>,
    pub(super) bias: Aligned<T>,
    pub(super) gamma: Aligned<T>,
    pub(super) beta: Aligned<T>,
    pub(super) eps: T,
    pub(super) c_in: usize,
    pub(super) c_out: usize,
    pub(super) c_pad: usize,
    pub(super) kernel: usize,
    pub(super) stride: usize,
    pub(super) pad: usize,
    pub(super) l_in: usize,
    pub(super) l_out: usize,
}

/// A Linear layer laid out for the forward pass: float64 weights, input-major, so that
/// every output's sum runs in the input's order while the outputs go side by side in
/// vector lanes.
#[derive(Clone, Debug)]
pub(super) struct Dense {
    /// `n_in × n_out`: row i, column o is torch's `weight[o, i]`.
    pub(super) wt: Vec<f64>,
    pub(super) bias: Vec<f64>,
    pub(super) n_out: usize,
}

impl Dense {
    pub(super) fn lay_out(d: &DenseWeights) -> Self {
        let mut wt = vec![0.0; d.n_in * d.n_out];
        for (o, row) in d.weight.chunks_exact(d.n_in).enumerate() {
            for (i, &w) in row.iter().enumerate() {
                wt[i * d.n_out + o] = f64::from(w);
            }
        }
        Self {
            wt,
            bias: d.bias.iter().map(|&b| f64::from(b)).collect(),
            n_out: d.n_out,
        }
    }
}

pub(super) fn sized(arg: &str, what: &str, got: usize, want: usize) -> Result<()> {
    if got == want {
        Ok(())
    } else {
        Err(Error::invalid(
            arg,
            format!("{what} has {got} values, expected {want}"),
        ))
    }
}

impl<T: Real> Block<T> {
    /// Block `b` checked against its input (`c_in` channels, `l_in` steps) and laid out
    /// for the tiled convolution (the float32 weights exactly, in either type); errors
    /// name `arg`.
    pub(super) fn lay_out(
        b: &ConvBlockWeights,
        c_in: usize,
        l_in: usize,
        arg: &str,
    ) -> Result<Self> {
        if b.kernel == 0 || b.stride == 0 {
            return Err(Error::invalid(arg, "kernel and stride must be >= 1"));
        }
        if b.c_in != c_in || b.c_out == 0 {
            return Err(Error::invalid(
                arg,
                format!(
                    "takes {} channels and gives {}; the previous layer gives {c_in}",
                    b.c_in, b.c_out
                ),
            ));
        }
        sized(arg, "weight", b.weight.len(), b.c_out * b.c_in * b.kernel)?;
        sized(arg, "bias", b.bias.len(), b.c_out)?;
        sized(arg, "norm_weight", b.norm_weight.len(), b.c_out)?;
        sized(arg, "norm_bias", b.norm_bias.len(), b.c_out)?;
        if !(b.norm_eps.is_finite() && b.norm_eps >= 0.0) {
            return Err(Error::invalid(arg, "eps must be finite and >= 0"));
        }
        let pad = b.kernel / 2;
        if l_in + 2 * pad < b.kernel {
            return Err(Error::invalid(
                arg,
                format!("kernel {} is longer than its padded input", b.kernel),
            ));
        }
        let c_pad = b.c_out.div_ceil(T::LANES) * T::LANES;
        let real = |v: f32| T::from_f64(f64::from(v));
        let mut w = Aligned::zeros(b.kernel * b.c_in * c_pad);
        for o in 0..b.c_out {
            for ci in 0..b.c_in {
                for k in 0..b.kernel {
                    w[(k * b.c_in + ci) * c_pad + o] =
                        real(b.weight[(o * b.c_in + ci) * b.kernel + k]);
                }
            }
        }
        let mut bias = Aligned::zeros(c_pad);
        for (dst, &v) in bias.iter_mut().zip(&b.bias) {
            *dst = real(v);
        }
        Ok(Self {
            w,
            bias,
            gamma: b.norm_weight.iter().map(|&v| real(v)).collect(),
            beta: b.norm_bias.iter().map(|&v| real(v)).collect(),
            eps: real(b.norm_eps),
            c_in: b.c_in,
            c_out: b.c_out,
            c_pad,
            kernel: b.kernel,
            stride: b.stride,
            pad,
            l_in,
            l_out: (l_in + 2 * pad - b.kernel) / b.stride + 1,
        })
    }
}

/// The Linear layers chain from `c_in` features to one output.
pub(super) fn check_head(head: &[DenseWeights], c_in: usize) -> Result<()> {
    if head.is_empty() {
        return Err(Error::invalid("head", "need at least one Linear layer"));
    }
    let mut c_prev = c_in;
    for (i, d) in head.iter().enumerate() {
        let arg = format!("head[{i}]");
        if d.n_in != c_prev || d.n_out == 0 {
            return Err(Error::invalid(
                &arg,
                format!(
                    "takes {} inputs and gives {}; the previous layer gives {c_prev}",
                    d.n_in, d.n_out
                ),
            ));
        }
        sized(&arg, "weight", d.weight.len(), d.n_out * d.n_in)?;
        sized(&arg, "bias", d.bias.len(), d.n_out)?;
        c_prev = d.n_out;
    }
    if c_prev != 1 {
        return Err(Error::invalid(
            "head",
            format!("the last layer must give 1 output, gives {c_prev}"),
        ));
    }
    Ok(())
}
