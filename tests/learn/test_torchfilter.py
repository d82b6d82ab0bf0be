"""The differentiable filter (pronet.learn.torchfilter) equals the core: on a recorded
Snapir section and on a simulated recording, for a non-constant q schedule, both
formulations, at every sample and at the default covariance step; resumable in chunks;
windows started from the core's state; its gradient in q against finite differences."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from recorded.test_real import SNAPIR

import pronet
from pronet.filter import FilterResult
from pronet.learn import torchfilter as tf
from pronet.learn.torchfilter.windows import per_sample_q, windows
from pronet.recorded.alignment import align, dcm_from_euler, estimate_alignment
from pronet.recorded.passes import section_recorded
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q
from pronet.run import Recorded

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

FORMULATIONS = ["invariant", "classic"]


@pytest.fixture(autouse=True)
def one_thread():
    """One torch thread: a batch of one or two sequences runs fastest so, and a thread
    pool on a busy machine costs milliseconds per small product."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _schedule(rec: Recorded, period: float = 23.0) -> tuple[np.ndarray, np.ndarray]:
    """A non-constant q schedule: the data's white-noise q scaled by 1, 4, 0.25, 2, …
    every ``period`` seconds."""
    q0 = np.array(white_noise_q(rec.imu))
    times = np.arange(rec.t0, rec.imu_time[-1], period)
    factors = np.array([1.0, 4.0, 0.25, 2.0, 0.5])[np.arange(len(times)) % 5]
    return times, factors[:, None] * q0


def _core(rec: Recorded, q_time, q, prior) -> FilterResult:
    return pronet.run_filter(
        rec.imu, rec.imu_time, rec.streams(aided=False), t0=rec.t0, lla0=rec.lla0,
        vel0=rec.vel0, rpy0=rec.rpy0, config=rec.config,
        strategy=pronet.Strategy.external(prior), q_time=q_time, q=q,
    )  # fmt: skip


def _torch(rec: Recorded, q_time, q, prior) -> tf.Outputs:
    batch = tf.sensor_batch(rec.imu, rec.imu_time, rec.dvl, rec.dvl_time, rec.t0, rec.config)
    p0 = np.diag(np.asarray(rec.config.p0_sigma) ** 2)
    state = tf.start_state(
        rec.lla0[None], rec.vel0[None], rec.rpy0[None], p0[None], [rec.t0], batch.setup
    )
    in_force = per_sample_q(q_time, q, rec.imu_time, rec.t0, prior)
    _, out = tf.advance(state, batch, 0, batch.length, torch.as_tensor(in_force)[None])
    return out


def assert_equal_to_core(
    out: tf.Outputs, core: FilterResult, epochs: slice, b: int, travel: float
) -> None:
    """Relative 1e-9, with absolute floors of 1e-9 of each quantity's scale (the style
    of test_numpy_reference_ekf.py); ``travel`` [m] the distance covered."""
    rtol = 1e-9
    got = {k: getattr(out, k)[b].detach().numpy() for k in ("vel", "rpy", "bias", "sigma", "lla")}
    np.testing.assert_allclose(got["vel"], core.vel[epochs], rtol=rtol, atol=1e-9 * 1.0)
    np.testing.assert_allclose(got["rpy"], core.rpy[epochs], rtol=rtol, atol=1e-9 * 1e-2)
    np.testing.assert_allclose(got["bias"], core.bias[epochs], rtol=rtol, atol=1e-9 * 1e-3)
    settled = out.settled[b].numpy()  # σ after a window's last close awaits the next
    assert settled[: len(settled) - 10].all()
    np.testing.assert_allclose(
        got["sigma"][settled], core.sigma[epochs][settled], rtol=rtol, atol=0.0
    )
    np.testing.assert_allclose(
        got["lla"][:, :2], core.lla[epochs, :2], rtol=0, atol=1e-9 * travel / 6.4e6
    )
    np.testing.assert_allclose(got["lla"][:, 2], core.lla[epochs, 2], rtol=rtol, atol=1e-9)
    # the DVL updates inside these epochs, in order
    mask = out.dvl_mask[b].numpy()
    first, last = epochs.start, epochs.stop if epochs.stop is not None else len(core.time)
    rows = (core.dvl_epoch >= first) & (core.dvl_epoch < last)
    assert mask.sum() == rows.sum() > 0
    np.testing.assert_array_equal(np.nonzero(mask)[0] + first, core.dvl_epoch[rows])
    nu = out.innovation[b].detach().numpy()[mask]
    np.testing.assert_allclose(nu, core.innovation[rows], rtol=rtol, atol=1e-9 * 0.1)
    np.testing.assert_allclose(out.nis[b].detach().numpy()[mask], core.nis[rows], rtol=rtol)


def _simulated(formulation: str, step: float, seconds: float = 90.0) -> Recorded:
    rec = synthetic_recording(seed=3, duration=seconds).recording
    section = align(rec, estimate_alignment(rec, IMU_LEVER_ARM, DVL_LEVER_ARM))
    arm = section.alignment.filter_lever_arm
    cfg = real_filter_config(arm, None, False, formulation, imu_step(section.imu_time), None, step)
    return section_recorded(section, cfg)


@pytest.mark.parametrize(
    "formulation", ["invariant", pytest.param("classic", marks=pytest.mark.slow)]
)
@pytest.mark.parametrize("step", [pytest.param(0.0, marks=pytest.mark.slow), 0.1])
def test_equals_the_core_on_a_simulated_recording(formulation, step) -> None:
    rec = _simulated(formulation, step)
    q_time, q = _schedule(rec)
    prior = q[0] * 3.0
    core = _core(rec, q_time, q, prior)
    out = _torch(rec, q_time, q, prior)
    assert_equal_to_core(out, core, slice(1, None), 0, travel=200.0)
    # the schedule moved the answer: a constant q gives another σ
    flat = _core(rec, q_time[:1], q[:1], q[0])
    assert np.abs(flat.sigma[-1] - core.sigma[-1]).max() > 1e-3 * core.sigma[-1].min()


def test_equals_the_core_in_ned_aiding_with_a_lever_arm() -> None:
    """NED velocity readings from a sensor away from the IMU (``h = v̂ + Ĉ (ω̂ × r)``,
    its H's attitude and gyro-bias columns, the arm's gyro noise rotated to NED): the
    simulated recording's DVL rotated to NED by the core's own body-aided attitude."""
    body = _simulated("invariant", 0.1, seconds=40.0)
    arm = body.config.lever_arm
    assert np.abs(arm).max() > 0.1
    q_time, q = _schedule(body)
    prior = q[0] * 3.0
    aided = _core(body, q_time, q, prior)
    rows = np.searchsorted(aided.time, body.dvl_time)
    ned = np.einsum("kij,kj->ki", dcm_from_euler(aided.rpy[rows]), body.dvl)
    keys = ("p0_sigma", "accel_bias_psd", "gyro_bias_psd", "dvl_variance", "lever_arm")
    keys += ("imu_dt", "covariance_step", "formulation")
    config = pronet.FilterConfig(aiding="nav", **{k: getattr(body.config, k) for k in keys})
    rec = replace(body, dvl=ned, config=config)
    core = _core(rec, q_time, q, prior)
    assert np.mean(core.nis[core.accepted]) < 20.0  # readings the filter agrees with
    assert_equal_to_core(_torch(rec, q_time, q, prior), core, slice(1, None), 0, travel=100.0)


@pytest.fixture(scope="module")
def snapir_section():
    if not SNAPIR.is_dir():
        pytest.skip(f"the Snapir data is not at {SNAPIR}")
    first = sorted(p for p in Path(SNAPIR).iterdir() if p.is_dir())[0]
    from pronet.recorded.alignment import SNAPIR_DVL_LEVER_ARM, SNAPIR_IMU_LEVER_ARM, load_section

    aligned, _ = load_section(
        first, "snapir", imu_lever_arm=SNAPIR_IMU_LEVER_ARM, dvl_lever_arm=SNAPIR_DVL_LEVER_ARM
    )
    return aligned


@pytest.mark.slow
@pytest.mark.parametrize(("step", "formulation"), [(0.1, "invariant"), (0.0, "classic")])
def test_equals_the_core_on_a_snapir_section(snapir_section, formulation, step) -> None:
    """A whole 400 s section of the real AUV data, as ``pronet real`` filters it: the
    default (the invariant formulation at the 0.1 s step) and its opposite corner (the
    classic one at every sample). Each formulation meets each step on the simulated
    recording above; the real data adds its own noise, gaps and lever arms, which no
    pair of the four sees differently, at 30 s a pair."""
    section = snapir_section
    arm = section.alignment.filter_lever_arm
    dt = imu_step(section.imu_time)
    cfg = real_filter_config(arm, None, False, formulation, dt, None, step)
    rec = section_recorded(section, cfg)
    q_time, q = _schedule(rec, period=37.0)
    core = _core(rec, q_time, q, q[0])
    out = _torch(rec, q_time, q, q[0])
    assert_equal_to_core(out, core, slice(1, None), 0, travel=1000.0)


@pytest.mark.parametrize(
    "formulation", ["invariant", pytest.param("classic", marks=pytest.mark.slow)]
)
def test_chunks_of_a_second_equal_one_call(formulation) -> None:
    """``advance`` resumes exactly: 1 s chunks (and a ragged last one) give the one
    call's numbers bit for bit, σ interpolated across the chunks' seams included."""
    rec = _simulated(formulation, 0.1, seconds=30.0)
    q_time, q = _schedule(rec, period=7.0)
    batch = tf.sensor_batch(rec.imu, rec.imu_time, rec.dvl, rec.dvl_time, rec.t0, rec.config)
    p0 = np.diag(np.asarray(rec.config.p0_sigma) ** 2)
    start = tf.start_state(
        rec.lla0[None], rec.vel0[None], rec.rpy0[None], p0[None], [rec.t0], batch.setup
    )
    in_force = torch.as_tensor(per_sample_q(q_time, q, rec.imu_time, rec.t0, q[0]))[None]
    whole_state, whole = tf.advance(start, batch, 0, batch.length, in_force)
    state, chunks = start, []
    bounds = [*range(0, batch.length, 100), batch.length]
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        state, out = tf.advance(state, batch, k0, k1, in_force[:, k0:k1])
        chunks.append(out)
    joined = tf.Outputs.cat(chunks)
    # a covariance step runs across some seams: the seam is inside a step
    assert not bool(torch.stack([c.current[0, -1] for c in chunks]).all())
    for name in ("vel", "lla", "dcm", "bias", "sigma", "innovation", "nis"):
        np.testing.assert_array_equal(getattr(joined, name).numpy(), getattr(whole, name).numpy())
    np.testing.assert_array_equal(state.p.numpy(), whole_state.p.numpy())


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_windows_start_from_the_core_and_follow_it(formulation) -> None:
    """Each window of :func:`windows` starts at the core's state (the pass's start or
    right after a DVL update) and, run with the q the core had, equals the core's epochs
    over the window to 1e-9."""
    passes = [_simulated(formulation, 0.1, seconds=70.0)]
    rec = passes[0]
    q_time, q = _schedule(rec, period=11.0)
    cut = windows(passes, [(q_time, q)], q[0], seconds=20.0)
    core = cut.core[0]
    assert core is not None
    assert cut.batch.size == len(cut.first) >= 3 and cut.batch.length == 2000
    assert cut.first[0] == 0 and set(cut.first[1:]) <= set(core.dvl_epoch)
    # the start equals the core's state there
    e = cut.first
    np.testing.assert_array_equal(cut.start.vel.numpy(), core.vel[e])
    np.testing.assert_allclose(cut.start.var_current.numpy(), core.sigma[e] ** 2, rtol=1e-15)
    _, out = tf.advance(cut.start, cut.batch, 0, cut.batch.length, cut.q)
    for b, first in enumerate(cut.first):
        assert_equal_to_core(out, core, slice(first + 1, first + 2001), b, travel=200.0)


def _short_window(formulation: str = "invariant"):
    rec = _simulated(formulation, 0.1, seconds=40.0)
    q_time, q = _schedule(rec, period=9.0)
    cut = windows([rec], [(q_time, q)], q[0], seconds=3.0)
    return cut, q[0]


@pytest.mark.slow
def test_the_gradient_in_q_matches_finite_differences() -> None:
    """d(loss)/dq through three seconds (three DVL updates) of two windows, against
    central differences (``torch.autograd.gradcheck``), q = q0·exp(s) per channel and
    window; the loss a velocity error against the DVL-free truth stand-in plus an NLL
    term on σ, as a Kalman-informed loss reads the filter."""
    cut, q0 = _short_window()
    batch, start = cut.batch, cut.start
    batch, start = batch.select(slice(0, 2)), start.select(slice(0, 2))
    q0t = torch.as_tensor(q0)
    target = cut.start.vel[:2, None] + 0.05

    def loss(s: torch.Tensor) -> torch.Tensor:
        _, out = tf.advance(start, batch, 0, batch.length, q0t * torch.exp(s))
        var = out.sigma[..., 3:6] ** 2
        err = out.vel - target
        return ((err**2 / var).sum() + torch.log(var).sum()) / err.numel()

    s = torch.zeros(2, 6, dtype=torch.float64, requires_grad=True)
    (grad,) = torch.autograd.grad(loss(s), s)
    assert grad.abs().max() > 0  # q moves the loss: the check is not vacuous
    assert torch.autograd.gradcheck(loss, (s,), eps=1e-5, atol=1e-8, rtol=1e-4)


@pytest.mark.slow
def test_the_gradient_in_the_start_state_matches_finite_differences() -> None:
    cut, q0 = _short_window("classic")
    batch, start = cut.batch.select(slice(0, 1)), cut.start.select(slice(0, 1))

    def loss(dv: torch.Tensor) -> torch.Tensor:
        s = tf.State(**{**vars(start), "vel": start.vel + dv})
        _, out = tf.advance(s, batch, 0, batch.length, torch.as_tensor(q0)[None])
        return (out.vel**2).sum() + out.sigma[..., 3:6].sum()

    dv = torch.zeros(1, 3, dtype=torch.float64, requires_grad=True)
    # eps 1e-5: at 1e-6 the down-velocity component's central difference is rounding
    # (6.21375e-2 against 6.21382e-2 at 1e-4 and 1e-5, where the gradient agrees to 4e-7)
    assert torch.autograd.gradcheck(loss, (dv,), eps=1e-5, atol=1e-7, rtol=1e-5)


def test_bad_input_names_the_argument() -> None:
    rec = _simulated("invariant", 0.1, seconds=40.0)
    batch = tf.sensor_batch(rec.imu, rec.imu_time, rec.dvl, rec.dvl_time, rec.t0, rec.config)
    p0 = np.diag(np.asarray(rec.config.p0_sigma) ** 2)[None]
    state = tf.start_state(rec.lla0[None], rec.vel0[None], rec.rpy0[None], p0, [0.0], batch.setup)
    with pytest.raises(ValueError, match=r"^q: expected \(1, 6\) or \(1, 10, 6\), got \(6,\)$"):
        tf.advance(state, batch, 0, 10, torch.ones(6))
    with pytest.raises(ValueError, match="^k0, k1: need 0 <= k0 < k1 <= "):
        tf.advance(state, batch, 5, 5, torch.ones(1, 6))
    calibrated = pronet.FilterConfig(dvl_calibration=True)
    with pytest.raises(ValueError, match="^config: the differentiable filter has no DVL"):
        tf.Setup.from_config(calibrated)
