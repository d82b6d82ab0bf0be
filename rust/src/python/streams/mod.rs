//! `Dvl`, `Depth`, `Fix`: the aiding sensors' streams a filter pass takes, one file per
//! type, each checked when it is made ([`Stream::validate`]) and resolved against the
//! pass's `FilterConfig` when the pass runs ([`StreamRef::stream`]).

mod args;
mod depth;
mod dvl;
mod fix;

use self::depth::PyDepth;
use self::dvl::PyDvl;
use self::fix::PyFix;
use super::call::invalid;
use super::convert::describe;
use crate::ekf::FilterConfig;
use crate::recorded::Stream;
use pyo3::prelude::*;

/// One of a pass's streams, borrowed from its Python object (frozen, so readable
/// without the GIL).
#[derive(Clone, Copy)]
pub(super) enum StreamRef<'a> {
    Dvl(&'a PyDvl),
    Depth(&'a PyDepth),
    Fix(&'a PyFix),
}

impl<'a> StreamRef<'a> {
    /// The core's stream, named `streams[i]` for errors, resolved against `cfg`.
    pub(super) fn stream(self, i: usize, cfg: &FilterConfig) -> Stream<'a> {
        let name = format!("streams[{i}]");
        match self {
            StreamRef::Dvl(d) => d.stream(name, cfg),
            StreamRef::Depth(d) => d.stream(name),
            StreamRef::Fix(f) => f.stream(name),
        }
    }
}

/// The items of `streams` (a sequence of `Dvl`, `Depth` and `Fix`), type-checked.
pub(super) fn stream_items<'py>(streams: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let refuse = || {
        invalid(
            "streams",
            format!(
                "expected a sequence (a list or tuple) of Dvl, Depth and Fix streams, got {}",
                describe(streams)
            ),
        )
    };
    if streams.is_instance_of::<pyo3::types::PyString>()
        || streams.is_instance_of::<PyDvl>()
        || streams.is_instance_of::<PyDepth>()
        || streams.is_instance_of::<PyFix>()
    {
        return Err(refuse());
    }
    let items: Vec<Bound<'py, PyAny>> = streams
        .try_iter()
        .map_err(|_| refuse())?
        .collect::<PyResult<_>>()?;
    for (i, item) in items.iter().enumerate() {
        if !(item.is_instance_of::<PyDvl>()
            || item.is_instance_of::<PyDepth>()
            || item.is_instance_of::<PyFix>())
        {
            return Err(invalid(
                &format!("streams[{i}]"),
                format!("expected a Dvl, Depth or Fix, got {}", describe(item)),
            ));
        }
    }
    Ok(items)
}

/// The stream an item of [`stream_items`] is.
pub(super) fn stream_ref<'a>(item: &'a Bound<'_, PyAny>) -> StreamRef<'a> {
    if let Ok(d) = item.cast::<PyDvl>() {
        StreamRef::Dvl(d.get())
    } else if let Ok(d) = item.cast::<PyDepth>() {
        StreamRef::Depth(d.get())
    } else if let Ok(f) = item.cast::<PyFix>() {
        StreamRef::Fix(f.get())
    } else {
        unreachable!("stream_items checked the type")
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDvl>()?;
    m.add_class::<PyDepth>()?;
    m.add_class::<PyFix>()
}
