//! `ConvNet`: the forward pass of a ProNet CNN regressor in the core, built from the
//! torch model's weights (`pronet.models.BaselineNet.native`).

use super::call::{detached, interruptible, invalid};
use super::convert::{arg_precision, arg_threads, describe, real_array, text_arg, window_rows};
use crate::regressors::convnet::{
    ConvBlockWeights, ConvNet, DenseWeights, Precision, Prepare, Scaling,
};
use crate::threads::Workers;
use numpy::{
    IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use std::sync::Arc;

/// The forward pass of a ProNet CNN regressor (``pronet.learn.models.BaselineNet`` or
/// ``DetrendNet``) from its torch weights; build it with
/// :meth:`pronet.learn.models.BaselineNet.native`.
///
/// ``prepare``: ``"centre"`` or ``"detrend"``; ``scaling``: ``"fixed"`` (uses
/// ``input_scale`` and ``q_scale``) or ``"spread"``. ``blocks``: per convolution block
/// ``(weight (c_out, c_in, kernel), bias, norm_weight, norm_bias, stride, eps)``;
/// ``head``: per Linear layer ``(weight (n_out, n_in), bias)``; arrays taken as float32.
/// ``ramp``: the ``(window,)`` ramp a ``"detrend"`` net projects out, as the torch
/// model stores it (None: the exact unit-norm centred ramp). ``threads``: worker
/// threads for ``predict`` (None: all cores). ``precision``: ``"float64"`` (the torch
/// model's function to ~1e-12 relative) or ``"float32"`` (the convolution blocks in
/// float32, ~1.7× as fast, within ~1e-5 relative of float64; the window's
/// preparation and the Linear layers stay float64). Either is deterministic: the same
/// bits whatever the batch, thread count or CPU.
#[pyclass(name = "ConvNet", module = "pronet._core", frozen)]
pub struct PyConvNet {
    inner: Arc<ConvNet>,
    workers: Workers,
}

fn vector(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<f32>> {
    let arr: PyReadonlyArray1<f32> = real_array(obj, "float32")?.ok_or_else(|| {
        invalid(
            arg,
            format!(
                "expected real numbers of shape (n,) (taken as float32), got {}",
                describe(obj)
            ),
        )
    })?;
    Ok(arr.as_array().to_vec())
}

fn block(obj: &Bound<'_, PyAny>, i: usize) -> PyResult<ConvBlockWeights> {
    let arg = format!("blocks[{i}]");
    let parts: (
        Bound<PyAny>,
        Bound<PyAny>,
        Bound<PyAny>,
        Bound<PyAny>,
        usize,
        f32,
    ) = obj.extract().map_err(|_| {
        invalid(
            &arg,
            "expected (weight, bias, norm_weight, norm_bias, stride, eps) with float32 arrays",
        )
    })?;
    let (weight, bias, gamma, beta, stride, eps) = parts;
    let w: PyReadonlyArray3<f32> = real_array(&weight, "float32")?.ok_or_else(|| {
        invalid(
            &arg,
            format!(
                "weight: expected a float32 array (c_out, c_in, kernel), got {}",
                describe(&weight)
            ),
        )
    })?;
    let &[c_out, c_in, kernel] = w.shape() else {
        unreachable!("a 3-d array")
    };
    Ok(ConvBlockWeights {
        weight: w.as_array().iter().copied().collect(),
        bias: vector(&bias, &format!("{arg}.bias"))?,
        c_in,
        c_out,
        kernel,
        stride,
        norm_weight: vector(&gamma, &format!("{arg}.norm_weight"))?,
        norm_bias: vector(&beta, &format!("{arg}.norm_bias"))?,
        norm_eps: eps,
    })
}

fn dense(obj: &Bound<'_, PyAny>, i: usize) -> PyResult<DenseWeights> {
    let arg = format!("head[{i}]");
    let (weight, bias): (Bound<PyAny>, Bound<PyAny>) = obj
        .extract()
        .map_err(|_| invalid(&arg, "expected (weight, bias) with float32 arrays"))?;
    let w: PyReadonlyArray2<f32> = real_array(&weight, "float32")?.ok_or_else(|| {
        invalid(
            &arg,
            format!(
                "weight: expected a float32 array (n_out, n_in), got {}",
                describe(&weight)
            ),
        )
    })?;
    let &[n_out, n_in] = w.shape() else {
        unreachable!("a 2-d array")
    };
    Ok(DenseWeights {
        weight: w.as_array().iter().copied().collect(),
        bias: vector(&bias, &format!("{arg}.bias"))?,
        n_in,
        n_out,
    })
}

#[pymethods]
impl PyConvNet {
    #[new]
    #[pyo3(signature = (*, window, prepare, scaling, blocks, head, input_scale = 0.1, q_scale = 0.01, negative_slope = 0.01, ramp = None, threads = None, precision = "float64".to_string()),
        text_signature = "(*, window, prepare, scaling, blocks, head, input_scale=0.1, q_scale=0.01, negative_slope=0.01, ramp=None, threads=None, precision='float64')"
    )]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        window: usize,
        prepare: &Bound<'_, PyAny>,
        scaling: &Bound<'_, PyAny>,
        blocks: Vec<Bound<'_, PyAny>>,
        head: Vec<Bound<'_, PyAny>>,
        input_scale: f64,
        q_scale: f64,
        negative_slope: f64,
        ramp: Option<Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arg_threads)] threads: Option<usize>,
        #[pyo3(from_py_with = arg_precision)] precision: String,
    ) -> PyResult<Self> {
        let precision = match precision.as_str() {
            "float64" => Precision::F64,
            "float32" => Precision::F32,
            other => {
                return Err(invalid(
                    "precision",
                    format!("'float64' or 'float32', got {other:?}"),
                ))
            }
        };
        let prepare = match text_arg(prepare, "prepare")?.as_str() {
            "centre" => Prepare::Centre,
            "detrend" => Prepare::Detrend,
            other => {
                return Err(invalid(
                    "prepare",
                    format!("'centre' or 'detrend', got {other:?}"),
                ))
            }
        };
        let scaling = match text_arg(scaling, "scaling")?.as_str() {
            "fixed" => Scaling::Fixed {
                input_scale,
                q_scale,
            },
            "spread" => Scaling::Spread,
            other => {
                return Err(invalid(
                    "scaling",
                    format!("'fixed' or 'spread', got {other:?}"),
                ))
            }
        };
        let blocks = blocks
            .iter()
            .enumerate()
            .map(|(i, b)| block(b, i))
            .collect::<PyResult<Vec<_>>>()?;
        let head = head
            .iter()
            .enumerate()
            .map(|(i, d)| dense(d, i))
            .collect::<PyResult<Vec<_>>>()?;
        let ramp = ramp.map(|r| vector(&r, "ramp")).transpose()?;
        let (net, workers) = detached(py, move || {
            let mut net = ConvNet::new(window, prepare, scaling, negative_slope, blocks, head)?;
            if let Some(ramp) = ramp {
                net = net.with_ramp(&ramp)?;
            }
            Ok((net.with_precision(precision), Workers::new(threads)?))
        })?;
        Ok(Self {
            inner: Arc::new(net),
            workers,
        })
    }

    /// q ``(n,)`` [(unit)² per sample] for windows ``(n, window)`` (taken as float32).
    fn predict<'py>(
        &self,
        py: Python<'py>,
        windows: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let samples: Vec<f32> = window_rows(windows, self.inner.window(), "float32")?;
        let net = Arc::clone(&self.inner);
        let workers = self.workers.clone();
        let q = interruptible(py, move |cancel| {
            workers.run(|| net.predict_until(&samples, cancel))
        })?;
        Ok(q.into_pyarray(py))
    }

    #[getter]
    fn window(&self) -> usize {
        self.inner.window()
    }

    /// ``"float64"`` or ``"float32"``: the element type of the convolution blocks.
    #[getter]
    fn precision(&self) -> &'static str {
        match self.inner.precision() {
            Precision::F64 => "float64",
            Precision::F32 => "float32",
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyConvNet>()
}
