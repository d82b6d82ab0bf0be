"""The Rust filter with the DVL's correlated velocity error (``dvl_bias_sigma``, states
19..21) agrees with the dense NumPy reference (``numpy_reference_dvl.py``) to 1e-8
relative, with and without the calibration states, and a reference with the model
slightly wrong does not."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet

import numpy_reference_dvl
from numpy_reference_ekf import dcm_from_euler, run_reference_filter
from test_numpy_reference_ekf import P0, Q, _inputs

SIGMA_B, TAU = np.array([0.04, 0.05, 0.03]), 15.0  # [m/s, DVL axes], [s]
CALIBRATION = (0.01, (0.02, 0.02, 0.03), 1e-8, 1e-9)
ARM = np.array([0.5, -0.2, 1.0])
RTOL = 1e-8
#: Per quantity, the scale below which the tolerance is absolute: the comparison is
#: ``|rust − ref| ≤ RTOL (scale + |ref|)`` (``assert_allclose`` with ``atol = RTOL
#: scale``), the floors of the calibration test; latitude and longitude are absolute.
SCALES = {
    "vel": 1.0,  # ~1 m/s
    "rpy": 1e-2,  # ~0.01 rad
    "bias": 1e-3,
    "sigma": 0.0,
    "height": 1.0,
    "innovation": 0.1,
    "nis": 0.0,
    "calibration": 1e-2,  # scale ~0.005, angles ~0.01 rad, b̂ ~0.03 m/s
    "calibration_sigma": 0.0,
}


def _readings(calibrate: bool, seed: int = 11):
    """The inputs of the calibration test with the DVL's readings carrying a correlated
    error (the process itself, sampled exactly at the readings' times) and, when
    ``calibrate``, a 0.5 % scale error and a mounting of (0.1°, −0.2°, 0.5°)."""
    imu, imu_time, dvl_body, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, ARM, "body")
    dvl = dvl_body
    if calibrate:
        m_true = dcm_from_euler(*np.radians([0.1, -0.2, 0.5])).T  # body -> DVL
        dvl = (1.005 * (m_true @ dvl_body.T)).T
    rng = np.random.default_rng(seed)
    b = np.empty_like(dvl)
    b[0] = SIGMA_B * rng.normal(size=3)
    for k in range(1, len(b)):
        e = math.exp(-(dvl_time[k] - dvl_time[k - 1]) / TAU)
        b[k] = e * b[k - 1] + SIGMA_B * math.sqrt(1 - e * e) * rng.normal(size=3)
    return imu, imu_time, dvl + b, dvl_time, lla0, vel0, rpy0


def _rust(inputs, calibrate, formulation, covariance_step):
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = inputs
    extra = {}
    if calibrate:
        s, m, sp, mp = CALIBRATION
        extra = dict(dvl_calibration=True, dvl_scale_sigma=s, dvl_misalignment_sigma=m,
                     dvl_scale_psd=sp, dvl_misalignment_psd=mp)  # fmt: skip
    cfg = pronet.FilterConfig(
        p0_sigma=P0, accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3,
        lever_arm=ARM, dvl_bias_sigma=SIGMA_B, dvl_bias_time_constant=TAU,
        formulation=formulation, covariance_step=covariance_step, **extra,
    )  # fmt: skip
    return pronet.run_filter(
        imu, imu_time, [pronet.Dvl(dvl_time, dvl)], t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
        config=cfg, strategy=pronet.Strategy.constant(Q), warn=False,
    )  # fmt: skip


def _reference(inputs, calibrate, formulation, covariance_step, tau=TAU):
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = inputs
    return run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, accel_bias_psd=1e-6,
        gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3, p0_sigma=P0, imu_dt=0.01, lever_arm=ARM,
        calibration=CALIBRATION if calibrate else None, dvl_bias=(SIGMA_B, tau),
        formulation=formulation, covariance_step=covariance_step,
    )  # fmt: skip


def _ratio(a, b, scale: float) -> float:
    """The largest ``|a − b| / (scale + |b|)``: at most RTOL where ``assert_allclose(a,
    b, rtol=RTOL, atol=RTOL * scale)`` passes (0/0 is 0)."""
    d, den = np.abs(np.asarray(a) - b), scale + np.abs(b)
    ratio = np.divide(d, den, out=np.where(d > 0, np.inf, 0.0), where=den > 0)
    return float(ratio.max())


def _differences(rust, ref) -> dict[str, float]:
    """Per quantity, the largest difference relative to the tolerance's scale."""
    out = {
        key: _ratio(getattr(rust, key), ref[key], SCALES[key])
        for key in ("vel", "rpy", "bias", "sigma", "innovation", "nis")
    }
    out["height"] = _ratio(rust.lla[:, 2], ref["lla"][:, 2], SCALES["height"])
    # Latitude/longitude: 1e-8 relative of the distance travelled (60 m) in radians.
    out["lat_lon"] = float(np.abs(rust.lla[:, :2] - ref["lla"][:, :2]).max()) / (60 / 6.4e6)
    for key in ("calibration", "calibration_sigma"):
        out[key] = _ratio(getattr(rust, key), ref[key], SCALES[key])
    return out


@pytest.mark.parametrize("calibrate", [False, True])
@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
@pytest.mark.parametrize("covariance_step", [0.0, 0.07])
def test_rust_filter_with_the_correlated_dvl_error_matches_reference(
    calibrate, formulation, covariance_step
) -> None:
    """22 states, at every IMU sample and at a 0.07 s covariance step (the last step of
    each second closed early by the DVL update): equal to 1e-8 relative everywhere,
    ``b̂`` and its σ included, on readings whose correlated error moves ``b̂`` by
    centimetres per second."""
    inputs = _readings(calibrate)
    rust = _rust(inputs, calibrate, formulation, covariance_step)
    ref = _reference(inputs, calibrate, formulation, covariance_step)
    assert len(ref["nis"]) == 60
    assert rust.calibration.shape == ref["calibration"].shape == (len(inputs[0]) + 1, 7)
    worst = _differences(rust, ref)
    assert max(worst.values()) <= RTOL, worst
    b_hat, b_sigma = rust.calibration[:, 4:], rust.calibration_sigma[:, 4:]
    # b̂ moved far beyond the tolerance's floor; its σ starts at σ_b, never rises above
    # it (the exact discrete noise holds the stationary variance) and the updates take
    # some off (with a 1 Hz DVL and 0.1 m/s white noise, little).
    assert np.abs(b_hat).max() > 1e-3
    np.testing.assert_array_equal(b_sigma[0], SIGMA_B)
    assert (b_sigma <= SIGMA_B * (1 + 1e-12)).all() and (b_sigma[-1] < SIGMA_B).all()
    if not calibrate:  # the scale and misalignment held at nominal
        assert not rust.calibration[:, :4].any() and not rust.calibration_sigma[:, :4].any()
    else:
        assert np.abs(rust.calibration[-1, :4] - rust.calibration[0, :4]).max() > 1e-4


@pytest.mark.parametrize("covariance_step", [0.0, 0.07])
def test_a_slightly_wrong_model_is_caught(covariance_step, monkeypatch) -> None:
    """The comparison can fail: a reference whose τ is 1 % off, or whose Gauss–Markov
    noise is the first-order ``σ_b² 2Δt/τ`` instead of the exact ``σ_b² (1 − e²)``,
    differs from the core by far more than the tolerance."""
    inputs = _readings(True)
    rust = _rust(inputs, True, "invariant", covariance_step)
    tau_off = _differences(rust, _reference(inputs, True, "invariant", covariance_step, 1.01 * TAU))
    assert tau_off["calibration"] > 1e3 * RTOL and tau_off["calibration_sigma"] > 1e3 * RTOL

    exact = numpy_reference_dvl.DvlErrors.transition

    def first_order(self, dt):
        phi, noise = exact(self, dt)
        noise[4:] = self.sigma_b**2 * 2 * dt / self.tau
        return phi, noise

    monkeypatch.setattr(numpy_reference_dvl.DvlErrors, "transition", first_order)
    euler = _differences(rust, _reference(inputs, True, "invariant", covariance_step))
    assert euler["calibration_sigma"] > 1e2 * RTOL, euler


def test_both_refuse_the_dvl_error_states_with_navigation_frame_aiding() -> None:
    """The correlated error lies in the DVL's axes: a DVL velocity in NED carries none
    the model describes, and neither filter runs it."""
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(2.0, np.zeros(3), "nav")
    start = dict(lla0=lla0, vel0=vel0, rpy0=rpy0)
    with pytest.raises(ValueError, match="^dvl_bias_sigma: .* body-frame aiding"):
        cfg = pronet.FilterConfig(aiding="nav", dvl_bias_sigma=SIGMA_B)
        pronet.run_filter(imu, imu_time, [pronet.Dvl(dvl_time, dvl)], t0=0.0, **start,
                          config=cfg, warn=False)  # fmt: skip
    with pytest.raises(ValueError, match="aiding='body' only"):
        run_reference_filter(
            imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, accel_bias_psd=1e-6,
            gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3, p0_sigma=P0, imu_dt=0.01,
            aiding="nav", dvl_bias=(SIGMA_B, TAU),
        )  # fmt: skip
