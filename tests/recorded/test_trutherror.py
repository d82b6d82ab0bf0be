"""The ground truth's own velocity error (pronet.recorded.trutherror) and the share within
3σ with it counted (pronet.recorded.metrics): the residual's parts recovered where they
are known, the share computed by hand, the Snapir numbers re-derived from the data."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import pronet
from pronet.recorded import real
from pronet.recorded.alignment import Alignment, Section, align, load_snapir_sections
from pronet.recorded.metrics import section_metrics, within_3sigma
from pronet.recorded.reading import stated_truth_error
from pronet.recorded.trutherror import (
    SNAPIR_TRUTH_VELOCITY_SIGMA,
    pooled,
    residual_parts,
    section_parts,
    truth_velocity_error,
)

from .test_real import SNAPIR
from synthetic_recording import (
    DVL_CLOCK,
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
)


def section(seed: int, duration: float, dvl_sigma: float = 0.01) -> Section:
    """A simulated section aligned with its true clocks and lever arms."""
    rec = synthetic_recording(seed, duration, dvl_sigma=dvl_sigma).recording
    given = Alignment(GT_CLOCK, DVL_CLOCK, IMU_LEVER_ARM, DVL_LEVER_ARM, how="given")
    return align(rec, given)


def test_white_noise_and_a_constant_bias_are_told_apart() -> None:
    """White noise of 0.02 m/s goes to the white part, a bias of (0.01, −0.005, 0) m/s
    to the slow one; a slow sine of amplitude 0.01 m/s to the slow one as its RMS."""
    rng = np.random.default_rng(7)
    noise = 0.02 * rng.standard_normal((4000, 3))
    bias = np.array([0.01, -0.005, 0.0])
    parts = residual_parts(noise + bias)
    assert parts.white == pytest.approx([0.02] * 3, rel=0.05)
    assert parts.slow[:2] == pytest.approx(np.abs(bias[:2]), abs=1e-3)
    assert parts.slow[2] < 1e-3
    assert parts.mean == pytest.approx(bias, abs=1e-3)
    t = np.arange(4000.0)
    sine = 0.01 * np.sin(2 * math.pi * t / 600.0)[:, None] * np.ones(3)
    slow = residual_parts(sine + 0.002 * rng.standard_normal((4000, 3)))
    assert slow.slow == pytest.approx([0.01 / math.sqrt(2)] * 3, rel=0.05)
    assert slow.white == pytest.approx([0.002] * 3, rel=0.05)


def test_alternating_noise_is_not_taken_for_white() -> None:
    """The Snapir DVL's errors alternate from one reading to the next: noise of 1σ
    0.03 m/s from ``e_k = −0.6 e_{k−1} + w_k`` with a bias of (0.01, 0.005, 0) m/s. The
    fast part is its 1σ with its lag-one autocorrelation, the slow part the bias; the
    white-noise formulas (``std(Δr)/√2``, the mean's noise ``σ²/N``) overstate the
    first by √1.6 and take a quarter of the bias away."""
    rng = np.random.default_rng(3)
    phi, sigma, rows = -0.6, 0.03, 20000
    w = rng.standard_normal((rows, 3)) * sigma * math.sqrt(1 - phi**2)
    e = np.zeros((rows, 3))
    e[0] = w[0] / math.sqrt(1 - phi**2)
    for k in range(1, rows):
        e[k] = phi * e[k - 1] + w[k]
    bias = np.array([0.01, 0.005, 0.0])
    parts = residual_parts(e + bias)
    assert parts.white == pytest.approx([sigma] * 3, rel=0.03)
    assert parts.lag_one == pytest.approx([phi] * 3, abs=0.03)
    assert parts.slow[:2] == pytest.approx(bias[:2], abs=1e-3)
    assert parts.slow[2] < 1.5e-3
    white = np.std(np.diff(e + bias, axis=0), axis=0) / math.sqrt(2)
    assert white == pytest.approx([sigma * math.sqrt(1.6)] * 3, rel=0.03)
    kernel = np.ones(30) / 30
    moving = np.convolve(e[:, 0] + bias[0], kernel, mode="valid")
    as_white = math.sqrt(max(np.mean(moving**2) - white[0] ** 2 / 30, 0.0))
    assert as_white < 0.85 * bias[0]  # the white-noise share takes a quarter of the bias


def test_pooled_parts_weigh_sections_by_their_rows() -> None:
    a = residual_parts(np.full((100, 3), 0.01))
    b = residual_parts(np.full((300, 3), 0.03))
    both = pooled([a, b])
    assert both.rows == 400
    assert both.slow == pytest.approx([math.sqrt(0.25 * 0.01**2 + 0.75 * 0.03**2)] * 3)
    assert both.mean == pytest.approx([0.025] * 3)
    with pytest.raises(ValueError, match="no section"):
        pooled([])


def test_a_residual_shorter_than_its_window_is_refused() -> None:
    with pytest.raises(ValueError, match="fewer than the window"):
        residual_parts(np.zeros((20, 3)))
    with pytest.raises(ValueError, match="must be finite"):
        residual_parts(np.full((100, 3), np.nan))


def test_a_truth_without_error_against_a_white_dvl_has_no_slow_part() -> None:
    """A simulated section (exact truth, DVL white noise 0.01 m/s per body axis): the
    white part is the DVL's, the slow part nearly nothing. A DVL bias of 0.03 m/s
    forward shows in the slow part as it turns with the vehicle."""
    sec = section(3, 300.0)
    parts = section_parts(sec)
    assert parts.white == pytest.approx([0.01] * 3, rel=0.2)
    assert np.all(parts.slow < 0.003), parts.slow
    biased = dataclasses.replace(sec, dvl=sec.dvl + np.array([0.03, 0.0, 0.0]))
    seen = section_parts(biased).slow
    assert math.hypot(seen[0], seen[1]) == pytest.approx(0.03, rel=0.1)


def test_the_share_with_the_truths_error_is_computed_by_hand() -> None:
    """Four rows, the filter's σ 0.01 m/s on every axis: without the truth's error rows
    1 and 4 lie within 0.03 m/s (share 0.5); with σ_truth (0.04, 0.02, 0) m/s row 2's
    0.05 m/s north lies within 3√(0.01² + 0.04²) = 0.124 m/s too, row 3's 0.1 m/s east
    still beyond 3√(0.01² + 0.02²) = 0.067 m/s (share 0.75)."""
    error = [[0.02, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, -0.02]]
    sigma = np.full((4, 3), 0.01)
    without = within_3sigma(error, sigma)
    with_truth = within_3sigma(error, sigma, (0.04, 0.02, 0.0))
    assert without == 0.5 and with_truth == 0.75
    assert within_3sigma(error, sigma, (0.0, 0.0, 0.0)) == without
    with pytest.raises(ValueError, match="truth_sigma"):
        within_3sigma(error, sigma, (-0.01, 0.0, 0.0))
    with pytest.raises(ValueError, match="sigma: expected shape"):
        within_3sigma(error, sigma[:3])


def test_a_sections_metrics_report_both_shares() -> None:
    """The filter on a simulated section: without a stated truth error the new share is
    NaN; with one it is at least the old share, equal to it for a zero error, and 1 for
    an error far beyond the velocity errors."""
    sec = section(4, 60.0)
    strategy = pronet.Strategy.constant(real.white_noise_q(sec.imu))
    config = real.real_filter_config(sec.alignment.filter_lever_arm, (0.01**2,) * 3)
    result = real.run_section(sec, strategy, config).result
    plain = section_metrics(sec, result)
    assert math.isnan(plain.velocity_3sigma_truth) and 0 < plain.velocity_3sigma
    for stated, want in (((0.0, 0.0, 0.0), plain.velocity_3sigma), ((1.0, 1.0, 1.0), 1.0)):
        told = section_metrics(dataclasses.replace(sec, truth_velocity_sigma=stated), result)
        assert told.velocity_3sigma == plain.velocity_3sigma
        assert told.velocity_3sigma_truth == want


def test_only_a_snapir_section_states_its_truths_error() -> None:
    sec = section(5, 40.0)
    assert stated_truth_error(sec, "snapir").truth_velocity_sigma == SNAPIR_TRUTH_VELOCITY_SIGMA
    assert stated_truth_error(sec, "generic").truth_velocity_sigma is None
    assert stated_truth_error(sec, "bag").truth_velocity_sigma is None


@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_the_snapir_truths_error_is_re_derived_from_the_data() -> None:
    """The stated numbers are the slow part pooled over sections 1–11, rounded up to
    0.1 mm/s; the white part (the DVL's) is larger on every axis."""
    sections = [a for a, _ in load_snapir_sections(SNAPIR)]
    names = [f"trajectory{i:02d}" for i in range(1, 12)]
    sections = [s for s in sections if s.name in names]
    assert [s.name for s in sections] == names
    parts = truth_velocity_error(sections)
    stated = np.array(SNAPIR_TRUTH_VELOCITY_SIGMA)
    assert np.all((stated >= parts.slow) & (stated - parts.slow < 1e-4)), parts.slow
    assert np.all(parts.white > stated), parts.white
