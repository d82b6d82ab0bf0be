"""Still intervals, levelling and gyrocompassing: the attitude an IMU finds by itself
while the vehicle is at rest, each angle with the 1σ its method earns (the formulas and
sources are in :mod:`pronet.recorded.initial` and docs/reference/aiding.md, "Initial state").

Frames as everywhere in pronet: body FRD, navigation NED, ``C = Rz(yaw) Ry(pitch)
Rx(roll)`` body to NED; IMU rows ``[f (m/s²), ω (rad/s)]``. At rest ``f = −Cᵀ g^n``
and ``ω = Cᵀ ω_ie^n`` with ``ω_ie^n = Ω [cos φ, 0, −sin φ]``.

Still detection. The IMU is cut into windows of ``window`` seconds (at least 10
samples). A window's spread is the largest per-axis standard deviation of its gyro
samples (``s_ω``) and of its accelerometer samples (``s_f``). The IMU's own noise is the
quietest window's spread over the record, ``n_ω = max(min s_ω, 1e-6 rad/s)`` and
``n_f = max(min s_f, 1e-4 m/s²)`` (the floors stand for quantisation: an ideal,
noise-free IMU would otherwise give zero). A window is still when ``s_ω ≤ k n_ω``,
``s_f ≤ k n_f`` (``k = factor``, 3 by default) and its mean rate is no more than the
Earth's plus a gyro bias and noise could make it, ``|ω̄| ≤ Ω + 3 σ_bg + k n_ω``; and
only while the quietest spreads are those of a vehicle at rest at all, ``n_ω ≤ 0.02
rad/s`` and ``n_f ≤ 0.2 m/s²`` (else no window is still). A run of still windows
continues while each window's mean stays within ``n_f`` (per accelerometer axis) and
``n_ω`` (per gyro axis) of the run's first window's mean: the per-sample noise, many
times the noise of a 1 s mean, so that rest is not split but the onset of a steady
acceleration or turn (which a window's spread does not show when it starts between two
windows) ends the run. Runs lasting ``min_duration`` or more are the still intervals.
An IMU alone cannot tell rest from uniform straight motion (both read ``f = −Cᵀ g``,
``ω ≈ Cᵀ ω_ie``), nor from an acceleration that builds up more slowly than the
tolerance: a vehicle drifting steadily may be taken as still; give the interval (or
none) then.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pronet.recorded.alignment import dcm_from_euler

F64 = NDArray[np.float64]

#: The Earth's rotation rate Ω [rad/s] (WGS-84).
EARTH_RATE = 7.292115e-5
#: The least noise a window's spread is compared with [rad/s, m/s²] (quantisation).
NOISE_FLOOR = (1e-6, 1e-4)
#: The largest quietest spread of an IMU at rest [rad/s, m/s²]: beyond, nothing is still.
REST_SPREAD = (0.02, 0.2)
#: Blocks the noise of a mean is estimated over (see :func:`mean_noise`).
BLOCKS = 10


@dataclass(frozen=True)
class StillSettings:
    """How still intervals are detected (see the module docstring).

    Attributes:
        window: the windows' length [s] (at least 10 samples each).
        factor: ``k``, how many times the IMU's quietest spread a still window may have.
        min_duration: the shortest still interval [s].
    """

    window: float = 1.0
    factor: float = 3.0
    min_duration: float = 5.0

    def __post_init__(self) -> None:
        for name, least in (("window", 0.0), ("factor", 1.0), ("min_duration", 0.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > least:
                raise ValueError(
                    f"StillSettings.{name}: expected a number above {least:g}, got {value!r}"
                )


def wrapped_mean(angles: F64) -> float:
    """The circular mean of ``angles`` [rad], in (−π, π]."""
    return float(np.arctan2(np.mean(np.sin(angles)), np.mean(np.cos(angles))))


def psi_sigma(rpy: F64, rpy_sigma: F64) -> F64:
    """The 1σ ``(3,)`` of the attitude error ψ (about N, E, D [rad]) of independent
    errors of roll, pitch and yaw with 1σ ``rpy_sigma`` at ``rpy``.

    An Euler error ``δ = (δr, δp, δy)`` turns the body by ``δy`` about D, ``δp`` about
    the pitch axis ``Rz e_y`` and ``δr`` about the roll axis ``Rz Ry e_x``, so
    ``ψ = −M δ`` with those axes as M's columns, and ``cov ψ = M diag(σ²) Mᵀ``: level,
    ``σ_N, σ_E`` mix roll and pitch by the yaw and ``σ_D = σ_y``; pitched by θ, the roll
    error adds ``sin θ σ_r`` about D.
    """
    cy, sy = math.cos(rpy[2]), math.sin(rpy[2])
    cp, sp = math.cos(rpy[1]), math.sin(rpy[1])
    m = np.array([[cp * cy, -sy, 0.0], [cp * sy, cy, 0.0], [-sp, 0.0, 1.0]])
    cov = m @ np.diag(np.asarray(rpy_sigma, dtype=float) ** 2) @ m.T
    return np.sqrt(np.diag(cov))


def mean_noise(x: F64) -> F64:
    """The 1σ ``(c,)`` of the mean of the columns of ``x (n, c)`` over its rows: the
    larger of the white-noise value ``s/√n`` and the spread of :data:`BLOCKS` block
    means ``s_B/√B``, which keeps the value honest when the noise is coloured (a
    vibration, a slow wander) and the white estimate would be too small."""
    n = len(x)
    white = np.std(x, axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(x.shape[1])
    if n < 2 * BLOCKS:
        return np.asarray(white, dtype=float)
    size = n // BLOCKS
    means = x[: size * BLOCKS].reshape(BLOCKS, size, -1).mean(axis=1)
    block = np.std(means, axis=0, ddof=1) / math.sqrt(BLOCKS)
    return np.asarray(np.maximum(white, block), dtype=float)


def _windows(imu_time: F64, window: float) -> tuple[int, int]:
    """Samples per window and the number of windows."""
    step = float(np.median(np.diff(imu_time))) if len(imu_time) > 1 else window
    size = max(10, int(round(window / step)))
    return size, len(imu_time) // size


def still_intervals(
    imu_time: F64, imu: F64, gyro_bias_sigma: float, settings: StillSettings
) -> list[tuple[float, float]]:
    """The still intervals ``[(t_start, t_end), …]`` [s] of an IMU record, in time order
    (see the module docstring for the test and its thresholds)."""
    size, count = _windows(imu_time, settings.window)
    if count == 0:
        return []
    blocks = imu[: size * count].reshape(count, size, 6)
    spread_f = blocks[:, :, :3].std(axis=1).max(axis=1)
    spread_w = blocks[:, :, 3:].std(axis=1).max(axis=1)
    rate = np.linalg.norm(blocks[:, :, 3:].mean(axis=1), axis=1)
    noise_w = max(float(spread_w.min()), NOISE_FLOOR[0])
    noise_f = max(float(spread_f.min()), NOISE_FLOOR[1])
    if noise_w > REST_SPREAD[0] or noise_f > REST_SPREAD[1]:
        return []
    k = settings.factor
    still = (
        (spread_w <= k * noise_w)
        & (spread_f <= k * noise_f)
        & (rate <= EARTH_RATE + 3.0 * gyro_bias_sigma + k * noise_w)
    )
    means = blocks.mean(axis=1)
    tolerance = np.array([noise_f] * 3 + [noise_w] * 3)
    found = []
    start = None
    for i in range(count + 1):
        steady = i < count and start is not None
        if steady and still[i] and np.all(np.abs(means[i] - means[start]) <= tolerance):
            continue
        if start is not None:
            t_a, t_b = float(imu_time[start * size]), float(imu_time[i * size - 1])
            if t_b - t_a >= settings.min_duration:
                found.append((t_a, t_b))
        start = i if i < count and still[i] else None
    return found


def level(imu: F64, accel_bias_sigma: float) -> tuple[float, float, float, F64]:
    """Roll and pitch [rad] from the mean specific force of still samples ``imu``, the
    tilt's 1σ [rad] and ``f̄``.

    ``roll = atan2(−f̄_y, −f̄_z)``, ``pitch = atan2(f̄_x, √(f̄_y² + f̄_z²))``. An error
    ``δf`` (bias ``σ_ba`` per axis and the mean's noise ``σ_f̄``, :func:`mean_noise`)
    tilts the measured gravity by ``σ_t = √(σ_ba² + σ_f̄²)/g`` about either horizontal
    axis: ``σ_pitch = σ_t`` and ``σ_roll = σ_t / cos θ`` (roll is about the body's x
    axis, which the pitch tips out of the level plane).
    """
    f = imu[:, :3].mean(axis=0)
    g = float(np.linalg.norm(f))
    roll = math.atan2(-f[1], -f[2])
    pitch = math.atan2(f[0], math.hypot(f[1], f[2]))
    noise = float(mean_noise(imu[:, :3]).max())
    tilt = math.hypot(accel_bias_sigma, noise) / g
    return roll, pitch, tilt, f


def gyrocompass(
    imu: F64,
    roll: float,
    pitch: float,
    tilt_sigma: float,
    latitude: float,
    gyro_bias_sigma: float,
) -> tuple[float, float]:
    """The heading [rad] and its 1σ [rad] from the mean body rate of still samples.

    The levelled frame ``L = Ry(pitch) Rx(roll)`` (the body turned level, its heading
    y unknown) sees ``ω^L = L ω̄ = Rz(y)ᵀ ω_ie^n``, that is
    ``[Ω cos φ cos y, −Ω cos φ sin y, −Ω sin φ]`` (φ the latitude), so
    ``y = atan2(−ω^L_y, ω^L_x)``. A rate error ``δω`` across the horizontal Earth
    rate turns the heading by ``δω / (Ω cos φ)``; a tilt error ``ε`` leaks the vertical
    Earth rate ``Ω sin φ ε`` into the horizontal: ``σ_y² = (σ_bg² + σ_ω̄²)/(Ω cos φ)² +
    (σ_t tan φ)²``. It is useful only while ``σ_bg ≪ Ω cos φ`` (a navigation-grade gyro).
    """
    w = imu[:, 3:].mean(axis=0)
    level_frame = dcm_from_euler(np.array([roll, pitch, 0.0]))
    w_level = level_frame @ w
    heading = math.atan2(-w_level[1], w_level[0])
    noise = float(mean_noise(imu[:, 3:]).max())
    horizontal = EARTH_RATE * math.cos(latitude)
    sigma = math.sqrt(
        (gyro_bias_sigma**2 + noise**2) / horizontal**2 + (tilt_sigma * math.tan(latitude)) ** 2
    )
    return heading, sigma
