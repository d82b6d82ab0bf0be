"""The differentiable filter (pronet.learn.torchfilter) equals the core: on a recorded
Snapir section and on a simulated recording, for a non-constant q schedule, both
formulations, at every sample and at the default covariance step; resumable in chunks;
windows started from the core's state; its gradient in q against finite differences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import pronet
from pronet.filter import FilterResult
from pronet.learn import torchfilter as tf
from pronet.learn.torchfilter.windows import per_sample_q, windows
from pronet.recorded.alignment import align, estimate_alignment, load_snapir_sections
from pronet.recorded.passes import section_recorded
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q
from pronet.run import Recorded

from recorded.test_real import SNAPIR
from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

FORMULATIONS = ["invariant", "classic"]
STEPS = [0.0, 0.1]  # every sample, and the default covariance step


def _schedule(rec: Recorded, period: float = 23.0) -> tuple[np.ndarray, np.ndarray]:
    """A non-constant q schedule: the data's white-noise q scaled by 1, 4, 0.25, 2, …
    every ``period`` seconds."""
    q0 = np.array(white_noise_q(rec.imu))
    times = np.arange(rec.t0, rec.imu_time[-1], period)
    factors = np.array([1.0, 4.0, 0.25, 2.0, 0.5])[np.arange(len(times)) % 5]
    return times, factors[:, None] * q0


def _core(rec: Recorded, q_time, q, prior) -> FilterResult:
    return pronet.run_filter(
        rec.imu, rec.imu_time, rec.dvl, rec.dvl_time, t0=rec.t0, lla0=rec.lla0,
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
    np.testing.assert_allclose(got["sigma"], core.sigma[epochs], rtol=rtol, atol=0.0)
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


@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("step", STEPS)
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
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("step", STEPS)
def test_equals_the_core_on_a_snapir_section(snapir_section, formulation, step) -> None:
    """A whole 400 s section of the real AUV data, as ``pronet real`` filters it."""
    section = snapir_section
    arm = section.alignment.filter_lever_arm
    dt = imu_step(section.imu_time)
    cfg = real_filter_config(arm, None, False, formulation, dt, None, step)
    rec = section_recorded(section, cfg)
    q_time, q = _schedule(rec, period=37.0)
    core = _core(rec, q_time, q, q[0])
    out = _torch(rec, q_time, q, q[0])
    assert_equal_to_core(out, core, slice(1, None), 0, travel=1000.0)
