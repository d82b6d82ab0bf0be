"""The NumPy reference's own measurement models (depth, fix, heading, NED velocity, in
every formulation, SE₂(3)'s far from its anchor) against the derivatives of their
predictions, and SE₂(3)'s position rows of F against one strapdown step: the reference
checked by itself, without the core."""

from __future__ import annotations

import math

import numpy as np
import pytest

import numpy_reference_se23
from numpy_reference_ekf import (
    dcm_from_euler,
    depth_h_row,
    depth_prediction,
    error_dynamics,
    exp_so3,
    fix_innovation,
    fix_prediction,
    heading_h_row,
    heading_innovation,
    heading_prediction,
    nav_velocity_h,
    nav_velocity_prediction,
    position_h_row,
    radii,
    strapdown_step,
)
from numpy_reference_se23 import anchor_metres, displacement, position, position_h_psi, to_se23

LLA = np.array([math.radians(32.5), math.radians(34.8), -12.0])
VEL = np.array([1.3, -0.4, 0.2])
C_TRUE = dcm_from_euler(0.05, -0.08, 2.3)
RATE = np.array([0.02, -0.03, 0.1])  # the true body rate [rad/s]
ARM = np.array([0.7, -0.3, 1.2])
#: Perturbation scales per block: δp [m] (it enters linearly but for the radii), and
#: δv, ψ, δb_a, δb_g.
SCALES = np.repeat([1e-2, 1e-5, 1e-5, 1e-5, 1e-5], 3)


#: SE₂(3)'s anchor in the measurement tests: the truth 3.9 km from it.
ANCHOR = position(np.array([-3000.0, 2500.0, 30.0]), LLA)


def _estimate(dx: np.ndarray, formulation: str):
    """``(lla, v, C, ω)`` of the estimate whose error from the truth above is ``dx``
    (15; δV in place of δv but in the classic formulation, δP in place of δp in
    SE₂(3)): ``Ĉ = Exp(−ψ) C``, ``v̂ = v + δv`` or ``v̂ = Ĉ Cᵀ v + δV``
    (docs/reference/filter.md's exact ``δV``), ``p̂ = Ĉ Cᵀ p + δP`` about ``ANCHOR`` (its exact
    ``δP``), ``ω̂ = ω − δb_g``."""
    rn, re = radii(LLA[0])
    lla = LLA + np.array(
        [dx[0] / (rn + LLA[2]), dx[1] / ((re + LLA[2]) * math.cos(LLA[0])), -dx[2]]
    )
    c = exp_so3(-dx[6:9]) @ C_TRUE
    if formulation == "se23":
        lla = position(c @ C_TRUE.T @ displacement(LLA, ANCHOR) + dx[0:3], ANCHOR)
    v = (VEL if formulation == "classic" else c @ C_TRUE.T @ VEL) + dx[3:6]
    return lla, v, c, RATE - dx[12:15]


def _model(name: str, formulation: str):
    """``(h, H)`` of a measurement at an estimate ``(lla, v, C, ω)``: ``h(x̂) − h(x) ≈
    H δx``. The fix is read through the filter's innovation, ``−ν``, against the fix
    of the true antenna (in SE₂(3) in the anchor's metres, its position error's). In
    SE₂(3) the position rows gain ``[p̂×]`` on ψ."""
    z_fix = fix_prediction(LLA, C_TRUE, ARM)
    invariant = formulation != "classic"

    def metres(s, i: int) -> float:  # in SE₂(3) the reading is in δP's metres
        return anchor_metres(s[0], ANCHOR, i) if formulation == "se23" else 1.0

    def position_rows(s, rows, axes):
        if formulation == "se23":
            for row, i in zip(rows, axes, strict=True):
                row[6:9] += position_h_psi(displacement(s[0], ANCHOR), i)
        return rows

    models = {
        "depth": (
            lambda s: np.array([depth_prediction(s[0], s[2], ARM)]),
            lambda s: position_rows(s, depth_h_row(s[2], ARM)[None], [2]),
        ),
        "fix": (
            lambda s: (
                -np.array(
                    [metres(s, i) * fix_innovation(z_fix, s[0], s[2], ARM, i) for i in range(3)]
                )
            ),
            lambda s: position_rows(
                s,
                np.array(
                    [
                        np.r_[
                            position_h_row(i, s[2], ARM)[:6],
                            metres(s, i) * position_h_row(i, s[2], ARM)[6:],
                        ]
                        for i in range(3)
                    ]
                ),
                [0, 1, 2],
            ),  # fmt: skip
        ),
        "heading": (
            lambda s: np.array([heading_prediction(s[2])]),
            lambda s: heading_h_row(s[2])[None],
        ),
        "nav velocity": (
            lambda s: nav_velocity_prediction(s[1], s[2], s[3], ARM),
            lambda s: nav_velocity_h(s[1], s[2], s[3], ARM, invariant),
        ),
    }
    return models[name]


MODELS = ["depth", "fix", "heading", "nav velocity"]


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
def test_measurement_h_is_the_derivative_of_the_prediction(name, formulation) -> None:
    """Every column of H against central differences of the prediction (zero columns
    included). The fix's position columns carry terms of order |r|/R (2e-7 here: the
    metres of an arm at the estimate's latitude and height against the truth's), which
    the filter leaves out; everything else agrees to rounding (in SE₂(3), 3.9 km from
    the anchor, to the differences' third-order terms, ψ² |p̂| ~ 5e-8; its fix is read
    in the anchor's metres, those of δP, and its arm's metres at the latitude moved by
    ψ |p̂| differ by |r| |p̂| (1 + tan φ)/R ~ 1.5e-3 m)."""
    h, big_h = _model(name, formulation)
    truth = _estimate(np.zeros(15), formulation)
    steps = np.repeat([1.0, 1e-4, 1e-5, 1e-4, 1e-6], 3)
    jac = np.zeros_like(big_h(truth))
    for k in range(15):
        e = np.zeros(15)
        e[k] = steps[k]
        jac[:, k] = (h(_estimate(e, formulation)) - h(_estimate(-e, formulation))) / (2 * steps[k])
    atol = 1e-9 + (2 * np.linalg.norm(ARM) / 6.36e6 if name == "fix" else 0.0)
    want = big_h(truth)
    if formulation == "se23":
        atol += 1e-7
        if name == "fix":
            arm_metres = np.linalg.norm(ARM) * np.linalg.norm(displacement(LLA, ANCHOR)) / 6.36e6
            atol += 2 * arm_metres
    np.testing.assert_allclose(jac, want, rtol=0, atol=atol)


@pytest.mark.parametrize(
    ("formulation", "name"),
    [(f, n) for f in ("classic", "invariant", "se23") for n in MODELS],
)
def test_measurement_h_predicts_the_change_to_second_order(name, formulation) -> None:
    """``h(x̂) − h(x)`` against ``H δx`` for one estimate off the truth in every state at
    once: with H at the truth, the central difference agrees to 1e-6 relative (its
    remainder is third order); with H at the estimate, as the filter linearizes, the
    remainder is second order: under 10 ε relative at perturbations ε (ψ, δv, δb; δp
    1e-2 m) and 100 times less when they shrink tenfold (but for the fix, whose
    remainder is the rounding of the latitude, 1e-9 m). In SE₂(3) δP shrinks with the
    rest, since it multiplies ψ (``[δP×]ψ``); its fix is read in the anchor's metres,
    those of δP (before, in the estimate's, it was first order off by their ratio)."""
    h, big_h = _model(name, formulation)
    truth = _estimate(np.zeros(15), formulation)
    u = np.random.default_rng(3).normal(size=15)
    dx = u * SCALES
    central = (h(_estimate(dx, formulation)) - h(_estimate(-dx, formulation))) / 2
    linear = big_h(truth) @ dx
    assert np.linalg.norm(central - linear) <= 1e-6 * np.linalg.norm(linear)
    remainders = []
    for eps in (1e-5, 1e-6):
        dx = u * (eps if formulation == "se23" else np.where(SCALES == 1e-2, 1e-2, eps))
        est = _estimate(dx, formulation)
        linear = big_h(est) @ dx
        remainder = np.linalg.norm(h(est) - h(truth) - linear)
        assert remainder <= 10 * eps * np.linalg.norm(linear)
        remainders.append(remainder)
    if name != "fix":
        assert 50 < remainders[0] / remainders[1] < 200


def _log_so3(r: np.ndarray) -> np.ndarray:
    """The rotation vector of ``r`` (inverse of ``exp_so3`` below π)."""
    s = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2
    angle = math.atan2(np.linalg.norm(s), (np.trace(r) - 1) / 2)
    return s * (angle / np.linalg.norm(s)) if angle > 0 else s


def _se23_error(est, truth) -> np.ndarray:
    """``[δP, δV, ψ]`` of an estimate ``(lla, v, C)`` against the truth, exactly:
    ``δP = p̂ − Ĉ Cᵀ p`` about ``ANCHOR``, ``δV = v̂ − Ĉ Cᵀ v``, ``Ĉ = Exp(−ψ) C``."""
    (lla_hat, v_hat, c_hat), (lla, v, c) = est, truth
    r = c_hat @ c.T
    d_p = displacement(lla_hat, ANCHOR) - r @ displacement(lla, ANCHOR)
    return np.concatenate([d_p, v_hat - r @ v, -_log_so3(r)])


def test_se23_position_rows_of_f_are_the_derivative_of_the_strapdown() -> None:
    """The position rows of SE₂(3)'s Φ = I + F Δt + (F Δt)²/2 + (F Δt)³/6 (the
    reference's F, 3.9 km from the anchor) against central differences of one
    strapdown step of an estimate off the truth in each state (δP 1 m, δV 1e-3 m/s, ψ
    1e-4 rad, biases; the step's Φ is F's to third order), error taken exactly
    (``_se23_error``): each block within 0.5 % of its size in F Δt, what ``ṗ̂ = v̂``
    leaves out at |p̂|/R (docs/reference/filter.md) with the differences' rounding (0.2 % at
    most here). The position–attitude block is 1.9e-3 in F Δt, 180 times that
    tolerance; with its sign flipped the gap is twice the block. (The velocity rows'
    Schuler terms rest on the rotation of the navigation frame, which this error leaves
    out: they are not checked here.)"""
    f_body, w_body, dt = np.array([0.3, -0.2, -9.7]), np.array([0.02, -0.03, 0.1]), 0.01
    truth = strapdown_step(LLA, VEL, C_TRUE, f_body, w_body, dt)
    steps = np.repeat([1.0, 1e-3, 1e-4, 1e-3, 1e-5], 3)
    numeric = np.zeros((3, 15))
    for k in range(15):
        e = np.zeros(15)
        e[k] = steps[k]
        ends = []
        for dx in (e, -e):
            lla, v, c, _ = _estimate(dx, "se23")
            est = strapdown_step(lla, v, c, f_body - dx[9:12], w_body - dx[12:15], dt)
            ends.append(_se23_error(est, truth)[:3])
        numeric[:, k] = (ends[0] - ends[1]) / (2 * steps[k])

    def phi(sign: float) -> np.ndarray:
        fm, gam = error_dynamics(LLA, VEL, C_TRUE, C_TRUE @ f_body, True)
        saved, numpy_reference_se23.POS_ATT_SIGN = numpy_reference_se23.POS_ATT_SIGN, sign
        try:
            fm, _ = to_se23(fm, gam, LLA, VEL, C_TRUE, displacement(LLA, ANCHOR))
        finally:
            numpy_reference_se23.POS_ATT_SIGN = saved
        fd = fm * dt
        return (np.eye(15) + fd + fd @ fd / 2 + fd @ fd @ fd / 6)[:3], fd[:3]

    want, fd = phi(1.0)
    for cols in (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)):
        gap = np.abs(numeric[:, cols] - want[:, cols]).max()
        assert gap <= 5e-3 * np.abs(fd[:, cols]).max() + 1e-6, (cols, gap)
    assert np.abs(fd[:, 6:9]).max() > 1e-3
    flipped, _ = phi(-1.0)
    assert np.abs(numeric[:, 6:9] - flipped[:, 6:9]).max() > 0.5 * np.abs(fd[:, 6:9]).max()


def test_measurement_models_read_their_signs_and_wrap() -> None:
    """A pressure sensor 1 m below a level IMU reads 1 m deeper; an antenna 2 m above it
    is 2 m higher; a heading across ±π wraps; zero arms leave the plain models."""
    level = dcm_from_euler(0.0, 0.0, 0.4)
    assert depth_prediction(LLA, level, (0.0, 0.0, 1.0)) == pytest.approx(-LLA[2] + 1.0)
    assert fix_prediction(LLA, level, (0.0, 0.0, -2.0))[2] == pytest.approx(LLA[2] + 2.0)
    c = dcm_from_euler(0.0, 0.0, -math.pi + 1e-3)
    assert heading_innovation(math.pi - 1e-3, c) == pytest.approx(-2e-3, abs=1e-12)
    assert heading_innovation(-math.pi + 2e-3, c) == pytest.approx(1e-3, abs=1e-12)
    zero = np.zeros(3)
    assert depth_prediction(LLA, C_TRUE, zero) == -LLA[2]
    np.testing.assert_array_equal(depth_h_row(C_TRUE, zero, 19), np.eye(19)[2])
    np.testing.assert_array_equal(nav_velocity_prediction(VEL, C_TRUE, RATE, zero), VEL)
    assert heading_h_row(C_TRUE, 19)[8] == -1.0 and not heading_h_row(C_TRUE, 19)[15:].any()
