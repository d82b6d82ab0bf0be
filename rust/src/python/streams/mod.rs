//! `Dvl`, `Depth`, `Fix`, `Heading`: the aiding sensors' streams a filter pass takes, one file per
//! type, each checked when it is made ([`Stream::validate`]) and resolved against the
//! pass's `FilterConfig` when the pass runs ([`StreamRef::stream`]).

mod args;
mod depth;
mod dvl;
mod fix;
mod heading;

use self::depth::PyDepth;
use self::dvl::PyDvl;
use self::fix::PyFix;
use self::heading::PyHeading;
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
    Heading(&'a PyHeading),
}

impl<'a> StreamRef<'a> {
    /// The core's stream, named `streams[i]` for errors, resolved against `cfg`.
    pub(super) fn stream(self, i: usize, cfg: &FilterConfig) -> Stream<'a> {
        let name = format!("streams[{i}]");
        match self {
            StreamRef::Dvl(d) => d.stream(name, cfg),
            StreamRef::Depth(d) => d.stream(name),
            StreamRef::Fix(f) => f.stream(name),
            StreamRef::Heading(h) => h.stream(name),
        }
    }
}

/// The items of `streams`, a sequence (each item's type is [`stream_ref`]'s to check).
pub(super) fn stream_items<'py>(streams: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let refuse = || {
        invalid(
            "streams",
            format!(
                "expected a sequence (a list or tuple) of Dvl, Depth, Fix and Heading \
                 streams, got {}",
                describe(streams)
            ),
        )
    };
    if streams.is_instance_of::<pyo3::types::PyString>() || as_stream(streams).is_some() {
        return Err(refuse());
    }
    let items: Vec<Bound<'py, PyAny>> = streams
        .try_iter()
        .map_err(|_| refuse())?
        .collect::<PyResult<_>>()?;
    Ok(items)
}

/// The stream `item` is, or None for any other object.
fn as_stream<'a>(item: &'a Bound<'_, PyAny>) -> Option<StreamRef<'a>> {
    if let Ok(d) = item.cast::<PyDvl>() {
        Some(StreamRef::Dvl(d.get()))
    } else if let Ok(d) = item.cast::<PyDepth>() {
        Some(StreamRef::Depth(d.get()))
    } else if let Ok(f) = item.cast::<PyFix>() {
        Some(StreamRef::Fix(f.get()))
    } else if let Ok(h) = item.cast::<PyHeading>() {
        Some(StreamRef::Heading(h.get()))
    } else {
        None
    }
}

/// The stream item `i` of [`stream_items`] is, or an error naming `streams[i]`.
pub(super) fn stream_ref<'a>(i: usize, item: &'a Bound<'_, PyAny>) -> PyResult<StreamRef<'a>> {
    as_stream(item).ok_or_else(|| {
        invalid(
            &format!("streams[{i}]"),
            format!(
                "expected a Dvl, Depth, Fix or Heading, got {}",
                describe(item)
            ),
        )
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDvl>()?;
    m.add_class::<PyDepth>()?;
    m.add_class::<PyFix>()?;
    m.add_class::<PyHeading>()
}
