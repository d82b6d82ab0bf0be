//! `Strategy`: a process-noise strategy.

use super::call::to_py_err;
use super::convert::{arg_window, fixed};
use crate::noise::StrategySpec;
use pyo3::prelude::*;

/// Process-noise strategy: constant Q^c, Mehra innovation-adaptive (window ξ),
/// robust adaptive (covariance matching of a scale on q), the oracle (the simulated
/// IMU's true variance), or external (q set by the caller through an :class:`Ensemble`).
#[pyclass(name = "Strategy", module = "pronet._core", frozen)]
#[derive(Clone)]
pub struct PyStrategy {
    pub(super) inner: StrategySpec,
}

impl PyStrategy {
    fn checked(spec: StrategySpec) -> PyResult<Self> {
        spec.validate().map_err(to_py_err)?;
        Ok(Self { inner: spec })
    }
}

#[pymethods]
impl PyStrategy {
    /// Constant Q^c from 6 per-sample IMU variances q [(m/s²)², (rad/s)²].
    #[staticmethod]
    fn constant(q: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::checked(StrategySpec::Constant { q: fixed(q, "q")? })
    }
    /// Mehra's innovation-adaptive Q over the last ``window`` DVL innovations
    /// (``window`` >= 1); constant ``prior_q`` until that many exist.
    #[staticmethod]
    #[pyo3(signature = (window, prior_q))]
    fn mehra(
        #[pyo3(from_py_with = arg_window)] window: usize,
        prior_q: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        Self::checked(StrategySpec::Mehra {
            window,
            prior_q: fixed(prior_q, "prior_q")?,
        })
    }
    /// q = λ·prior_q with the scale λ estimated by matching the DVL innovations'
    /// NIS over an exponentially forgetting window of ``window`` updates (>= 1);
    /// structure and full rank kept, λ in [1e-3, 1e3]. See ``docs/reference/filter.md``.
    #[staticmethod]
    #[pyo3(signature = (window, prior_q))]
    fn adaptive(
        #[pyo3(from_py_with = arg_window)] window: usize,
        prior_q: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        Self::checked(StrategySpec::Adaptive {
            window,
            prior_q: fixed(prior_q, "prior_q")?,
        })
    }
    /// The simulated IMU's true variance at every IMU step (the ceiling; simulation only).
    #[staticmethod]
    fn oracle() -> Self {
        Self {
            inner: StrategySpec::Oracle,
        }
    }
    /// q set from outside (the hybrid loop, an :class:`Ensemble`); ``prior_q`` until then.
    #[staticmethod]
    fn external(prior_q: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::checked(StrategySpec::External {
            prior_q: fixed(prior_q, "prior_q")?,
        })
    }
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner {
            StrategySpec::Constant { .. } => "constant",
            StrategySpec::Mehra { .. } => "mehra",
            StrategySpec::External { .. } => "external",
            StrategySpec::Oracle => "oracle",
            StrategySpec::Adaptive { .. } => "adaptive",
        }
    }
    #[getter]
    fn label(&self) -> String {
        self.inner.label()
    }
    /// q of a constant strategy, the prior q of the others; empty for the oracle.
    #[getter]
    fn q(&self) -> Vec<f64> {
        match &self.inner {
            StrategySpec::Constant { q } => q.to_vec(),
            StrategySpec::Mehra { prior_q, .. }
            | StrategySpec::Adaptive { prior_q, .. }
            | StrategySpec::External { prior_q } => prior_q.to_vec(),
            StrategySpec::Oracle => Vec::new(),
        }
    }
    #[getter]
    fn window(&self) -> Option<usize> {
        match self.inner {
            StrategySpec::Mehra { window, .. } | StrategySpec::Adaptive { window, .. } => {
                Some(window)
            }
            _ => None,
        }
    }
    fn __repr__(&self) -> String {
        format!("Strategy({:?})", self.inner)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyStrategy>()
}
