"""Errors of a filter run on a recorded section against its ground truth: velocity
SRMSE and SMAE, final and maximum horizontal position error, the final error as a
percentage of the distance travelled, the mean NIS and the heading error against the
filter's heading σ. Taken at the ground-truth rows
inside the run, the estimate linearly interpolated between IMU epochs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import float_array
from pronet.filter import FilterResult
from pronet.recorded.alignment import Section, no_truth

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class SectionMetrics:
    """Errors of one run against the ground truth at its rows after the start.

    Attributes:
        srmse, smae: velocity √(mean Σ δv²) and mean Σ|δv| [m/s].
        final_horizontal, max_horizontal: horizontal position error [m].
        distance: horizontal distance travelled by the truth [m].
        final_percent: ``final_horizontal`` as % of ``distance``.
        mean_nis: mean NIS of the DVL updates (3 when consistent).
        heading_ratio: RMS over the scored rows of the heading error (yaw estimate
            minus truth, wrapped) over the filter's heading 1σ (about 1 when the filter
            is consistent, above 1 overconfident; the truth's own heading error and
            any yaw misalignment between the truth and the IMU count as error).
        n_scored: ground-truth rows scored.
        velocity_3sigma: the share of the scored rows at which the velocity error lies
            within 3 of the filter's 1σ in each NED axis (at least 0.99 when the filter
            is consistent; its truth's own error counts as error).
        velocity_3sigma_truth: the same share with the truth's own velocity error
            counted: within 3 √(σ² + σ_truth²) per NED axis, ``σ_truth`` the section's
            :attr:`~pronet.recorded.alignment.Section.truth_velocity_sigma`
            (:mod:`pronet.recorded.trutherror`); NaN where the section states none.
        missed_updates: DVL rows inside the run skipped as missing readings
            (:mod:`pronet.recorded.missing`); 0 for a run without the DVL.
        dvl_autocorrelation: the whiteness test of the DVL's innovations
            (:func:`pronet.stats.whiteness`: the lag-one autocorrelation of the whitened
            innovations, about 0 ± :attr:`dvl_autocorrelation_band` when white); NaN
            without DVL updates.
        dvl_autocorrelation_band: the half-width of its 95 % band.
    """

    srmse: float
    smae: float
    final_horizontal: float
    max_horizontal: float
    distance: float
    final_percent: float
    mean_nis: float
    heading_ratio: float
    n_scored: int
    missed_updates: int = 0
    velocity_3sigma: float = math.nan
    velocity_3sigma_truth: float = math.nan
    dvl_autocorrelation: float = math.nan
    dvl_autocorrelation_band: float = math.nan


def _horizontal_offsets(lla: F64, ref: F64) -> tuple[F64, F64]:
    """North and east of ``lla`` from ``ref`` [m], row by row (radii at ``ref``)."""
    radii = np.array([_core.earth_radii(float(lat)) for lat in ref[:, 0]])
    north = (lla[:, 0] - ref[:, 0]) * (radii[:, 0] + ref[:, 2])
    east = (lla[:, 1] - ref[:, 1]) * (radii[:, 1] + ref[:, 2]) * np.cos(ref[:, 0])
    return north, east


def estimate_at_truth(section: Section, result: FilterResult) -> tuple[NDArray[np.intp], F64, F64]:
    """``(rows, lla, vel)``: the truth rows inside the run and the estimate there,
    linearly interpolated between IMU epochs."""
    rows = np.flatnonzero(
        (section.truth_time > result.time[0]) & (section.truth_time <= result.time[-1])
    )
    t = section.truth_time[rows]

    def at(values: F64) -> F64:
        return np.stack([np.interp(t, result.time, values[:, j]) for j in range(3)], axis=1)

    return rows, at(result.lla), at(result.vel)


def _heading_ratio(section: Section, result: FilterResult, rows: NDArray[np.intp]) -> float:
    """RMS of the heading error over its 1σ at the truth ``rows`` (see
    :class:`SectionMetrics`); the yaw interpolated unwrapped, the error wrapped."""
    t = section.truth_time[rows]
    yaw = np.interp(t, result.time, np.unwrap(result.rpy[:, 2]))
    sigma = np.interp(t, result.time, result.sigma[:, 8])
    error = np.angle(np.exp(1j * (yaw - section.truth_rpy[rows, 2])))
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.sqrt(np.mean((error / sigma) ** 2)))


def section_metrics(section: Section, result: FilterResult, use_dvl: bool = True) -> SectionMetrics:
    """Errors of ``result`` against the truth of ``section`` (see :class:`SectionMetrics`;
    ``use_dvl``: whether the run had the DVL, for its missed updates); a section
    without a ground truth is refused in one line."""
    if not section.has_truth:
        raise ValueError(no_truth(section.name, "its errors are taken against one"))
    rows, lla, vel = estimate_at_truth(section, result)
    if rows.size == 0:
        raise ValueError(f"section {section.name}: no ground-truth row inside the run")
    dv = vel - section.truth_vel[rows]
    north, east = _horizontal_offsets(lla, section.truth_lla[rows])
    horizontal = np.hypot(north, east)
    truth = section.truth_lla[np.concatenate([[rows[0] - 1], rows])]
    step_n, step_e = _horizontal_offsets(truth[1:], truth[:-1])
    distance = float(np.sum(np.hypot(step_n, step_e)))
    nis = result.nis[np.isfinite(result.nis)]
    sigma = _velocity_sigma(section, result, rows)
    truth = section.truth_velocity_sigma
    dvl = next((r for r in result.health.streams if r.kind == "velocity"), None)
    return SectionMetrics(
        srmse=float(np.sqrt(np.mean(np.sum(dv**2, axis=1)))),
        smae=float(np.mean(np.sum(np.abs(dv), axis=1))),
        final_horizontal=float(horizontal[-1]),
        max_horizontal=float(horizontal.max()),
        distance=distance,
        final_percent=100 * float(horizontal[-1]) / distance if distance > 0 else math.nan,
        mean_nis=float(nis.mean()) if nis.size else math.nan,
        heading_ratio=_heading_ratio(section, result, rows),
        n_scored=int(rows.size),
        missed_updates=missed_updates(section, result) if use_dvl else 0,
        velocity_3sigma=within_3sigma(dv, sigma),
        velocity_3sigma_truth=(math.nan if truth is None else within_3sigma(dv, sigma, truth)),
        dvl_autocorrelation=math.nan if dvl is None else dvl.autocorrelation,
        dvl_autocorrelation_band=math.nan if dvl is None else dvl.autocorrelation_band,
    )


def _velocity_sigma(section: Section, result: FilterResult, rows: NDArray[np.intp]) -> F64:
    """The filter's velocity 1σ per NED axis [m/s] at the truth ``rows``, interpolated."""
    t = section.truth_time[rows]
    return np.stack([np.interp(t, result.time, result.sigma[:, 3 + j]) for j in range(3)], 1)


def within_3sigma(
    error: ArrayLike, sigma: ArrayLike, truth_sigma: ArrayLike = (0.0, 0.0, 0.0)
) -> float:
    """The share of rows whose velocity error ``error`` ``(rows, 3)`` [m/s, NED] lies
    within 3 √(σ² + σ_truth²) in every axis: ``sigma`` ``(rows, 3)`` the filter's 1σ
    [m/s], ``truth_sigma`` ``(3,)`` the truth's own error 1σ [m/s] (independent of the
    filter's; zero: the filter's σ alone). Raises ValueError on mismatched shapes."""
    e = float_array(error, "error", (None, 3))
    s = float_array(sigma, "sigma", (len(e), 3))
    t = float_array(truth_sigma, "truth_sigma", (3,))
    if not (np.isfinite(t).all() and (t >= 0).all()):
        raise ValueError(f"truth_sigma: must be finite and >= 0, got {t.tolist()}")
    return float(np.mean(np.all(np.abs(e) <= 3 * np.sqrt(s**2 + t**2), axis=1)))


def missed_updates(section: Section, result: FilterResult) -> int:
    """The DVL rows of ``section`` skipped as missing readings whose time lies inside
    the run ``result`` (after its start, up to its last epoch)."""
    t = section.dvl_skipped_time
    return int(np.sum((t > result.time[0]) & (t <= result.time[-1])))
