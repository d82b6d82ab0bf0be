"""A simulated recording with the quirks of a real one: stream clocks that are offset
and scaled against the IMU's, ground truth at a point away from the IMU, a DVL with a
lever arm. Everything is known, so readers, clock estimation and lever-arm handling can
be checked against the truth."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

import pronet
from pronet.recorded.alignment import Clock, dcm_from_euler
from pronet.recorded.recordings import Recording

GT_CLOCK = Clock(offset=-0.45, scale=0.9975)
DVL_CLOCK = Clock(offset=1.0, scale=0.9975)
IMU_LEVER_ARM = (-1.78, -0.04, -1.04)
DVL_LEVER_ARM = (-1.85, -0.03, 0.12)


@dataclass(frozen=True)
class Synthetic:
    recording: Recording
    trajectory: pronet.Trajectory  # the truth at the IMU
    truth_time: np.ndarray  # ground-truth rows on the IMU clock [s]


def _at(t: np.ndarray, tp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t, tp, fp[:, j]) for j in range(fp.shape[1])], axis=1)


def gauss_markov(
    t: np.ndarray, sigma: tuple[float, float, float], tau: float, rng: np.random.Generator
) -> np.ndarray:
    """A stationary first-order Gauss–Markov process ``(len(t), 3)`` at the times
    ``t`` [s], exact at them: 1σ ``sigma`` per axis [m/s], correlation time ``tau`` [s]."""
    s = np.asarray(sigma, dtype=np.float64)
    out = np.empty((len(t), 3))
    out[0] = rng.normal(size=3) * s
    for k in range(1, len(t)):
        phi = np.exp(-(t[k] - t[k - 1]) / tau)
        out[k] = phi * out[k - 1] + rng.normal(size=3) * s * np.sqrt(1 - phi * phi)
    return out


def synthetic_recording(
    seed: int = 0,
    duration: float = 80.0,
    name: str = "synthetic",
    dvl_sigma: float | tuple[float, float, float] = 0.01,
    dvl_mounting: tuple[float, tuple[float, float, float]] = (0.0, (0.0, 0.0, 0.0)),
    imu_rate: float = 100.0,
    jitter: float = 0.0,
    gt_rate: float = 1.0,
    dvl_rate: float = 1.0,
    imu_bias: tuple[float, ...] | None = None,
    bias_psd: tuple[float, ...] | None = None,
    dvl_bias: tuple[tuple[float, float, float], float] | None = None,
) -> Synthetic:
    """An AUV-like section: turns and depth changes at 1.5–2 m/s, 100 Hz IMU with
    white noise (variance 1e-4 (m/s²)² and 1e-8 (rad/s)²), 1 Hz DVL with white noise of
    ``dvl_sigma`` [m/s] per body axis, and ground truth on their own clocks.
    ``dvl_mounting = (k, (roll, pitch, yaw))``: the DVL reads ``(1 + k) C_b^d v_b`` with
    ``C_d^b = R(roll, pitch, yaw)`` [rad] (as the core's ``DvlMounting``).
    ``imu_rate`` [Hz]: the IMU's rate; ``jitter``: each IMU stamp moved by up to
    ``jitter / 2`` of a step (a step then varies by up to ``jitter``), the sample the
    mean over its own interval (from a truth ten times finer); ``gt_rate``,
    ``dvl_rate`` [Hz]: the ground truth's and the DVL's rates. ``imu_bias`` (6) a turn-on
    bias ``[b_a (m/s²), b_g (rad/s)]`` and ``bias_psd`` (6) its random walk's PSD
    [(m/s²)²/s, (rad/s)²/s] (as a ``SensorConfig``'s). ``dvl_bias = (σ, τ)``: a
    correlated DVL error on top of the white one, a first-order Gauss–Markov process
    per DVL axis of stationary 1σ ``σ`` [m/s] and correlation time ``τ`` [s] (as the
    filter's ``dvl_bias_sigma`` and ``dvl_bias_time_constant``), drawn stationary."""
    # Smoothly varying turn rate, speed and pitch (one-second segments), as an AUV
    # manoeuvres: 1 Hz rows interpolate such motion well.
    t = np.arange(int(duration)) + 0.5
    segments = np.column_stack(
        [
            np.ones_like(t),
            0.05 * np.sin(2 * np.pi * t / 23.0),
            0.06 * np.sin(2 * np.pi * t / 40.0),
            0.01 * np.sin(2 * np.pi * t / 31.0),
        ]
    )
    fine = 10 if jitter else 1
    traj = pronet.trajectory_from_segments(
        segments,
        lla0=(0.5733, 0.6090, -20.0),
        speed0=1.8,
        rpy0=(0.01, 0.0, 0.3),
        **({} if imu_rate == 100.0 and not jitter else {"dt": 1.0 / (imu_rate * fine)}),
    )
    rng = np.random.default_rng(seed)
    t_epoch = traj.time
    imu_time = t_epoch[1:]
    ideal = traj.imu
    if jitter:  # stamps moved, each sample the mean over its own interval
        step = 1.0 / imu_rate
        k = np.arange(1, int(t_epoch[-1] * imu_rate))
        imu_time = k * step + np.random.default_rng(seed + 1).uniform(-0.5, 0.5, k.size) * (
            jitter * step
        )
        total = np.vstack([np.zeros(6), np.cumsum(traj.imu * np.diff(t_epoch)[:, None], axis=0)])
        edges = np.concatenate([[0.0], imu_time])
        ideal = np.diff(_at(edges, t_epoch, total), axis=0) / np.diff(edges)[:, None]
    imu = ideal + rng.normal(size=ideal.shape) * np.sqrt([1e-4] * 3 + [1e-8] * 3)
    if imu_bias is not None or bias_psd is not None:
        walk_rng = np.random.default_rng(seed + 2)
        steps = np.diff(np.concatenate([[t_epoch[0]], imu_time]))[:, None]
        walk = walk_rng.normal(size=imu.shape) * np.sqrt(np.asarray(bias_psd or [0.0] * 6) * steps)
        imu = imu + np.asarray(imu_bias or [0.0] * 6) + np.cumsum(walk, axis=0) - walk
    rpy = np.unwrap(traj.rpy, axis=0)
    r_imu, r_dvl = np.array(IMU_LEVER_ARM), np.array(DVL_LEVER_ARM)

    # Ground truth at the reference point, rows 1 s apart on the IMU clock.
    k = np.arange(1, int((t_epoch[-1] - GT_CLOCK.offset) * gt_rate) + 1)
    t_gt = GT_CLOCK.offset + (k * 1.0 if gt_rate == 1.0 else k / gt_rate)
    t_gt = t_gt[(t_gt > t_epoch[0]) & (t_gt < t_epoch[-1])]
    c = dcm_from_euler(_at(t_gt, t_epoch, rpy))
    w = _at(t_gt, t_epoch[1:], traj.imu[:, 3:6])
    lla = _at(t_gt, t_epoch, traj.lla)
    offset_ned = c @ r_imu
    radii = np.array([pronet.earth_radii(float(lat)) for lat in lla[:, 0]])
    lla_gt = lla.copy()
    lla_gt[:, 0] -= offset_ned[:, 0] / (radii[:, 0] + lla[:, 2])
    lla_gt[:, 1] -= offset_ned[:, 1] / ((radii[:, 1] + lla[:, 2]) * np.cos(lla[:, 0]))
    lla_gt[:, 2] += offset_ned[:, 2]
    vel_gt = _at(t_gt, t_epoch, traj.vel_ned) - np.einsum("kij,kj->ki", c, np.cross(w, r_imu))
    rpy_gt = _at(t_gt, t_epoch, rpy)
    rpy_gt[:, 2] = np.angle(np.exp(1j * rpy_gt[:, 2]))

    # DVL body velocity at the DVL, rows 1 s apart on the IMU clock, 1 s late.
    t_dvl = DVL_CLOCK.offset + (
        np.arange(0, int(t_epoch[-1])) * 1.0
        if dvl_rate == 1.0
        else np.arange(0, int(t_epoch[-1] * dvl_rate)) / dvl_rate
    )
    t_dvl = t_dvl[(t_dvl > t_epoch[0]) & (t_dvl < t_epoch[-1])]
    cd = dcm_from_euler(_at(t_dvl, t_epoch, rpy))
    v_body = np.einsum("kji,kj->ki", cd, _at(t_dvl, t_epoch, traj.vel_ned))
    v_body += np.cross(_at(t_dvl, t_epoch[1:], traj.imu[:, 3:6]), r_dvl - r_imu)
    scale, angles = dvl_mounting
    if scale != 0.0 or any(angles):
        body_to_dvl = dcm_from_euler(np.asarray(angles, dtype=np.float64)).T
        v_body = (1.0 + scale) * v_body @ body_to_dvl.T
    dvl = v_body + rng.normal(scale=dvl_sigma, size=v_body.shape)
    if dvl_bias is not None:  # its own draws: the white ones stay those of the seed
        dvl = dvl + gauss_markov(t_dvl, *dvl_bias, np.random.default_rng(seed + 3))

    def stamps(clock: Clock, t: np.ndarray) -> np.ndarray:
        return (t - clock.offset) / clock.scale

    rec = Recording(
        name=name,
        imu_time=imu_time.copy(),
        imu=np.ascontiguousarray(imu),
        dvl_time=stamps(DVL_CLOCK, t_dvl),
        dvl=dvl,
        gt_time=stamps(GT_CLOCK, t_gt),
        gt_lla=lla_gt,
        gt_vel=vel_gt,
        gt_rpy=rpy_gt,
        source="synthetic",
    )
    return Synthetic(rec, traj, t_gt)


def with_aiding(
    synthetic: Synthetic,
    seed: int = 0,
    depth_every: float = 0.5,
    depth_sigma: float = 0.05,
    fix_every: float = 30.0,
    fix_sigma: float = 2.0,
    sigma_in_file: bool = True,
) -> Recording:
    """``synthetic``'s recording with depth readings every ``depth_every`` s (white
    noise of ``depth_sigma`` [m]) and position fixes every ``fix_every`` s (white noise
    of ``fix_sigma`` [m] per NED axis, every other one horizontal), both at the IMU's
    point and stamped on its clock (:mod:`pronet.recorded.aiding`); their σ in the
    recording with ``sigma_in_file``, else none (the filter's as tuned)."""
    from pronet.recorded.aiding import DepthReadings, PositionFixes

    traj, rng = synthetic.trajectory, np.random.default_rng(seed + 7)
    step = int(round(depth_every / traj.dt))
    k = np.arange(step, len(traj.time), step)
    depth = -traj.lla[k, 2] + rng.normal(size=len(k)) * depth_sigma
    f = np.arange(int(round(fix_every / traj.dt)), len(traj.time), int(round(fix_every / traj.dt)))
    radii = np.array([pronet.earth_radii(float(lat)) for lat in traj.lla[f, 0]])
    noise = rng.normal(size=(len(f), 3)) * fix_sigma
    lla = traj.lla[f].copy()
    lla[:, 0] += noise[:, 0] / (radii[:, 0] + lla[:, 2])
    lla[:, 1] += noise[:, 1] / ((radii[:, 1] + lla[:, 2]) * np.cos(lla[:, 0]))
    lla[:, 2] -= noise[:, 2]
    lla[1::2, 2] = np.nan
    sigma = np.full((len(f), 3), fix_sigma)
    return replace(
        synthetic.recording,
        depth=DepthReadings(
            traj.time[k], depth, np.full(len(k), depth_sigma) if sigma_in_file else None
        ),
        fixes=PositionFixes(traj.time[f], lla, sigma if sigma_in_file else None),
    )
