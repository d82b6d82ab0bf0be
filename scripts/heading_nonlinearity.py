"""Why the long MEMS mission's position NEES leaves its band, in a model small enough to
solve exactly (``docs/results/consistency.md``, "A long MEMS mission without fixes").

A vehicle dead-reckons in the plane with perfectly known body velocity along the
lawnmower of :func:`pronet.experiments.consistency.lawnmower_segments` (1.5 m/s, 60 s
legs joined by 180° turns at 6 °/s through east, so it drifts east at 0.32 m/s), but
its heading is off by ``ψ(t) = ψ₀ + b t``: ``ψ₀ ~ N(0, 1°)`` and a vertical gyro-bias
error ``b`` drawn once per run so that ``σ_ψ`` reaches 25° after the hour, as the MEMS
filter's does there. A white velocity error adds 1 m of position σ over the hour. The
position error is ``e = ∫ (R(θ + ψ) − R(θ)) v_b dt``. Against the exact distribution
(Monte Carlo), three Gaussian treatments of it, each giving a mean and a covariance:

- **linear**: the EKF's propagation of ``(e, ψ, b)`` (mean zero);
- **sigma points, redrawn**: an unscented transform of every step, its points drawn
  afresh from the last step's mean and covariance (a UKF of the same state);
- **sigma points, kept**: five hypotheses of ``(ψ₀, b)`` dead-reckoned over the whole
  run, never redrawn; their weighted mean and covariance.

Printed: the position NEES of the Monte Carlo errors against each (2 if consistent),
and against the linear covariance about the Monte Carlo's own mean error (what a correct
mean alone would give).

``--filter``: the same question put to pronet's filter, the invariant row of the long
MEMS mission (:func:`pronet.experiments.consistency.run_lawnmower`'s Monte Carlo, 20
runs, its errors kept every second): each horizontal axis's mean squared error over σ²
against the position NEES, the runs' mean east error against the along-drift mean
``∫ (cos ψ − 1) v dt`` the model predicts from each run's own heading error (east is not
the filter's thin axis: ``--second-order`` compares along that axis), and the
heading RMS of the same 20 runs started at the truth (no initial error drawn, the same
P0): how much of the heading error the process noise makes on its own.

``--second-order``: the same mission, 20 runs simulated here with the Monte Carlo's
model (the MEMS grade's white noise, turn-on biases drawn from P0 and bias walks; a 5 Hz
body-frame DVL of 0.02 m/s with bottom-lock losses, depth at 1 Hz; every initial error
drawn from P0) and run through :func:`pronet.run_filter` in the invariant formulation,
its full covariance kept every 10 s. Along each run's *thin* horizontal axis (the
smaller eigenvector of its horizontal position covariance), the position error against
the second-order term ``½ ∫ δψ² v_h dt`` taken from that run's own heading error ``δψ``
and estimated horizontal velocity ``v_h`` (slope, correlation, and the error's RMS over
σ before and after the term is taken off); then the run-averaged position NEES with the
covariance as it is and with ``κ m mᵀ`` added, ``m = ∫ σ_ψ² v_h dt`` from the filter's
own heading σ: ``κ = ¼`` is the term's squared mean (its second moment's lower bound),
``κ = ¾`` its second moment if the heading error were one Gaussian draw for the whole
run.

    python scripts/heading_nonlinearity.py [--runs 4000] [--seed 0] [--filter | --second-order]
"""

from __future__ import annotations

import argparse
from typing import Any, NamedTuple

import numpy as np
from scipy.stats import chi2

DT = 0.1  # [s]
DT_IMU = 0.01  # [s]: the IMU step of ``--filter`` and ``--second-order``
HOURS = 1.0
SPEED = 1.5  # [m/s]
SIGMA_PSI0 = np.deg2rad(1.0)  # [rad]
SIGMA_B = np.deg2rad(25.0) / 3600.0  # [rad/s]: σ_ψ 25° after an hour
Q_POSITION = 1.0 / 3600.0  # [m²/s]: 1 m of position σ over the hour
REPORT_EVERY = 600.0  # [s]


def headings(t: np.ndarray) -> np.ndarray:
    """The lawnmower's heading [rad] at times ``t`` [s]: 60 s north, a 30 s turn to
    starboard, 60 s south, a 30 s turn to port (both through east)."""
    c = t % 180.0
    turn = np.pi / 30.0
    return np.select(
        [c < 60.0, c < 90.0, c < 150.0], [0.0, (c - 60.0) * turn, np.pi], np.pi - (c - 150.0) * turn
    )


def error_rate(psi: np.ndarray, theta: float) -> np.ndarray:
    """``(R(θ + ψ) − R(θ)) v_b`` [m/s], north and east, for each ψ [rad] in ``psi``."""
    return SPEED * np.stack(
        [np.cos(theta + psi) - np.cos(theta), np.sin(theta + psi) - np.sin(theta)], axis=-1
    )


def unscented(mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 2n + 1 sigma points (κ = 3 − n) of N(mean, cov) and their weights."""
    n = len(mean)
    kappa = 3.0 - n
    root = np.linalg.cholesky(cov) * np.sqrt(n + kappa)
    points = np.vstack([mean, mean + root.T, mean - root.T])
    weights = np.r_[kappa / (n + kappa), np.full(2 * n, 0.5 / (n + kappa))]
    return points, weights


def moments(points: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted mean and covariance of ``points``."""
    mean = weights @ points
    d = points - mean
    return mean, (weights[:, None] * d).T @ d


def nees(errors: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> float:
    """The mean NEES of ``errors`` (runs × 2) about ``mean`` under ``cov``."""
    r = errors - mean
    return float(np.mean(np.einsum("ij,jk,ik->i", r, np.linalg.inv(cov), r)))


def run(runs: int, seed: int) -> list[tuple[float, ...]]:
    """Every :data:`REPORT_EVERY` s: time [s], the Monte Carlo's σ_ψ [deg], its mean
    error north and east [m], and the NEES against each treatment."""
    rng = np.random.default_rng(seed)
    b, psi = rng.normal(0.0, SIGMA_B, runs), rng.normal(0.0, SIGMA_PSI0, runs)
    e = rng.normal(0.0, np.sqrt(Q_POSITION * DT), (runs, 2))  # one step's white error
    start = np.diag([Q_POSITION * DT, Q_POSITION * DT, SIGMA_PSI0**2, SIGMA_B**2])
    p_lin, (m_ukf, p_ukf) = start.copy(), (np.zeros(4), start.copy())
    kept, w_kept = unscented(np.zeros(2), start[2:, 2:])  # (ψ₀, b) hypotheses
    e_kept, psi_kept = np.zeros((len(w_kept), 2)), kept[:, 0].copy()
    white = Q_POSITION * DT * np.eye(2)
    rows = []
    steps = round(HOURS * 3600.0 / DT)
    for k in range(steps):
        theta = float(headings(np.array(k * DT)))
        e += error_rate(psi, theta) * DT + rng.normal(0.0, np.sqrt(Q_POSITION * DT), (runs, 2))
        psi += b * DT
        f = np.eye(4)
        f[0, 2], f[1, 2], f[2, 3] = -SPEED * np.sin(theta) * DT, SPEED * np.cos(theta) * DT, DT
        p_lin = f @ p_lin @ f.T
        p_lin[:2, :2] += white
        x, w = unscented(m_ukf, p_ukf)
        x[:, :2] += error_rate(x[:, 2], theta) * DT
        x[:, 2] += x[:, 3] * DT
        m_ukf, p_ukf = moments(x, w)
        p_ukf[:2, :2] += white
        e_kept += error_rate(psi_kept, theta) * DT
        psi_kept += kept[:, 1] * DT
        t = (k + 1) * DT
        if round(t / DT) % round(REPORT_EVERY / DT) == 0:
            m_kept, p_kept = moments(e_kept, w_kept)
            p_kept += Q_POSITION * (t + DT) * np.eye(2)
            mean = e.mean(axis=0)
            rows.append(
                (
                    t,
                    float(np.rad2deg(psi.std())),
                    *mean,
                    nees(e, np.zeros(2), p_lin[:2, :2]),
                    nees(e, m_ukf[:2], p_ukf[:2, :2]),
                    nees(e, m_kept, p_kept),
                    nees(e, mean, p_lin[:2, :2]),
                )
            )
    return rows


def filter_check(seed: int) -> None:
    """``--filter``: pronet's invariant filter on the long MEMS mission, 20 runs."""
    from pronet import _core
    from pronet.experiments import consistency as c

    segments = c.lawnmower_segments(HOURS)
    out, at_truth = (
        c._monte_carlo(
            ("mems", "invariant", segments, "lawnmower"),
            (20, seed, 100, draw, False),
            dvl_period=0.2,
            dvl_dropout=c.LAWNMOWER_DROPOUT,
            depth_sigma=c.LAWNMOWER_DEPTH[0],
            depth_period=c.LAWNMOWER_DEPTH[1],
        )
        for draw in (True, False)
    )
    assert out.error is not None and out.sigma is not None  # kept every second
    assert at_truth.error is not None
    truth = _core.trajectory_from_segments(
        np.array(segments), lla0=[np.radians(32.0), np.radians(34.0), -20.0], speed0=1.5,
        dt=0.01, name="lawnmower",
    )  # fmt: skip
    t = out.record_time
    v = np.stack([np.interp(t, truth.time, truth.vel_ned[:, i]) for i in (0, 1)], axis=-1)
    psi, psi_at_truth = out.error[:, :, 8], at_truth.error[:, :, 8]
    predicted = np.cumsum((np.cos(psi) - 1.0)[..., None] * v * np.diff(t, prepend=0.0)[:, None], 1)
    nees = out.block_nees("position")
    print(
        "| t [s] | heading RMS [°] | started at the truth [°] | error² / σ² N, E, D | NEES "
        "| mean east error [m] | predicted [m] |"
    )
    print("|---|---|---|---|---|---|---|")
    for at in (1200.0, 2400.0, 3600.0):
        k, j = (
            int(np.searchsorted(t, at)),
            min(int(np.searchsorted(out.dvl_time, at)), nees.shape[1] - 1),
        )
        z = ((out.error[:, k, :3] / out.sigma[:, k, :3]) ** 2).mean(axis=0)
        east = out.error[:, k, 1]
        print(
            f"| {t[k]:.0f} | {np.degrees(np.sqrt((psi[:, k] ** 2).mean())):.1f} | "
            f"{np.degrees(np.sqrt((psi_at_truth[:, k] ** 2).mean())):.1f} | "
            f"{z[0]:.2f}, {z[1]:.2f}, {z[2]:.2f} | {np.nanmean(nees[:, j]):.1f} | "
            f"{east.mean():.1f} ± {east.std(ddof=1) / np.sqrt(len(east)):.1f} | "
            f"{predicted[:, k, 1].mean():.1f} |"
        )


def _simulated_run(
    seed: int, run: int, traj: Any, config: Any
) -> tuple[Any, np.ndarray, np.ndarray]:
    """One run of ``--second-order``: the filter's result, its true yaw [rad] and
    position error [m, NED] at the kept covariances."""
    import pronet
    from pronet.experiments import consistency as c
    from pronet.recorded.alignment import dcm_from_euler

    g, rng = c.GRADES["mems"], np.random.default_rng([seed, run])
    t, ideal = traj.time, traj.imu
    q = np.array([g["q_a"]] * 3 + [g["q_g"]] * 3)
    psd = np.array([g["w_a"]] * 3 + [g["w_g"]] * 3)
    walk = rng.normal(size=ideal.shape) * np.sqrt(psd * DT_IMU)
    bias = rng.normal(size=6) * np.array([g["b_a"]] * 3 + [g["b_g"]] * 3) + np.cumsum(walk, 0)
    imu = ideal + bias + rng.normal(size=ideal.shape) * np.sqrt(q)

    def at(when: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(when, t, values[:, j]) for j in range(values.shape[1])], 1)

    yaw = np.unwrap(traj.rpy[:, 2])
    t_dvl = np.arange(0.2, t[-1], 0.2)
    c_nb = dcm_from_euler(at(t_dvl, np.unwrap(traj.rpy, axis=0)))
    v_b = np.einsum("kji,kj->ki", c_nb, at(t_dvl, traj.vel_ned))
    v_b += rng.normal(size=v_b.shape) * c.DVL_SIGMA
    locked, start = np.ones(len(t_dvl), dtype=bool), 0.0
    every, length = c.LAWNMOWER_DROPOUT
    while (start := start + rng.exponential(every)) < t[-1]:
        locked &= ~((t_dvl >= start) & (t_dvl < start + rng.exponential(length)))
    t_depth = np.arange(1.0, t[-1], c.LAWNMOWER_DEPTH[1])
    depth = -np.interp(t_depth, t, traj.lla[:, 2])
    depth += rng.normal(size=len(t_depth)) * c.LAWNMOWER_DEPTH[0]
    p0 = np.array(config.p0_sigma)[:9]
    e0 = rng.normal(size=9) * p0
    lat, lon, h = traj.lla[0]
    r_n, r_e = pronet.earth_radii(float(lat))
    metres = np.array([r_n + h, (r_e + h) * np.cos(lat), -1.0])
    res = pronet.run_filter(
        imu, t[1:],
        [pronet.Dvl(t_dvl[locked], v_b[locked]),
         pronet.Depth(t_depth, depth, sigma=c.LAWNMOWER_DEPTH[0])],
        t0=t[0], lla0=traj.lla[0] + e0[:3] / metres, vel0=traj.vel_ned[0] + e0[3:6],
        rpy0=traj.rpy[0] + e0[6:9], config=config,
        strategy=pronet.Strategy.constant(q.tolist()),
        covariance_time=np.arange(10.0, t[-1] - 1.0, 10.0), warn=False,
    )  # fmt: skip
    k = res.covariance_epoch
    error = (res.lla[k] - at(res.time[k], traj.lla)) * metres
    true_yaw = np.interp(res.time, t, yaw)
    return res, true_yaw, error


class SecondOrder(NamedTuple):
    """What ``--second-order`` measures: per time of ``marks`` [s] along each run's thin
    horizontal axis, the slope and correlation of the position error on ``½ ∫ δψ² v_h dt``
    and the error's RMS over σ before and after it is taken off (``fit``); per ``κ`` of
    ``KAPPAS``, the share of kept epochs whose run-averaged position NEES lies in its 95 %
    band, its mean, and its value at ``marks`` (``nees``); and ``∫ δψ² v_h`` over
    ``∫ σ_ψ² v_h`` projected on ``m`` (``ratio``, 1 where the heading σ is honest)."""

    fit: list[tuple[float, float, float, float, float]]
    nees: list[tuple[float, float, list[float]]]
    ratio: float


#: The bounds on the term's second moment added to the position covariance (``κ m mᵀ``).
KAPPAS = (0.0, 0.25, 0.75)


def second_order(
    seed: int,
    runs: int = 20,
    hours: float = HOURS,
    marks: tuple[float, ...] = (1200.0, 2400.0, 3600.0),
) -> SecondOrder:
    """``--second-order``'s numbers (see the module's docstring)."""
    from pronet import _core
    from pronet.experiments import consistency as c

    segments = c.lawnmower_segments(hours)
    traj = _core.trajectory_from_segments(
        np.array(segments), lla0=[np.radians(32.0), np.radians(34.0), -20.0], speed0=1.5,
        dt=DT_IMU, name="lawnmower",
    )  # fmt: skip
    config = c.filter_config("mems", "invariant")
    errors, covariances, own, expected, kept = [], [], [], [], np.empty(0)
    for run in range(runs):
        res, true_yaw, error = _simulated_run(seed, run, traj, config)
        dpsi = np.angle(np.exp(1j * (res.rpy[:, 2] - true_yaw)))
        v_h = res.vel[:, :2] * np.diff(res.time, prepend=res.time[0])[:, None]
        kept = res.time[res.covariance_epoch]
        own.append(0.5 * np.cumsum(dpsi[:, None] ** 2 * v_h, 0)[res.covariance_epoch])
        expected.append(np.cumsum(res.sigma[:, 8:9] ** 2 * v_h, 0)[res.covariance_epoch])
        errors.append(error)
        covariances.append(res.covariances[:, :3, :3])
    e, p, half, m = (np.array(a) for a in (errors, covariances, own, expected))
    _, vectors = np.linalg.eigh(p[..., :2, :2])
    thin = vectors[..., 0]
    at = np.searchsorted(kept, marks) - 1
    fit = []
    for k in at:
        x = np.einsum("ri,ri->r", half[:, k], thin[:, k])
        y = np.einsum("ri,ri->r", e[:, k, :2], thin[:, k])
        sd = np.sqrt(np.einsum("ri,rij,rj->r", thin[:, k], p[:, k, :2, :2], thin[:, k]))
        before, after = (float(np.sqrt(np.mean((d / sd) ** 2))) for d in (y, y - x))
        fit.append(
            (float(kept[k]), float(x @ y / (x @ x)), float(np.corrcoef(x, y)[0, 1]), before, after)
        )
    band = chi2.ppf([0.025, 0.975], 3 * runs) / runs  # the run-averaged 3-dof NEES
    m3 = np.concatenate([m, np.zeros(m.shape[:-1] + (1,))], axis=-1)
    nees = []
    for kappa in KAPPAS:
        pk = p + kappa * np.einsum("rki,rkj->rkij", m3, m3)
        mean = np.einsum("rki,rkij,rkj->rk", e, np.linalg.inv(pk), e).mean(axis=0)
        inside = float(np.mean((mean > band[0]) & (mean < band[1])))
        nees.append((inside, float(mean.mean()), [float(mean[k]) for k in at]))
    ratio = float(2.0 * np.einsum("rki,rki->", half, m) / np.einsum("rki,rki->", m, m))
    return SecondOrder(fit, nees, ratio)


def second_order_check(seed: int) -> None:
    """``--second-order``: :func:`second_order`'s tables."""
    result = second_order(seed)
    print("| t [s] | slope | correlation | error / σ, thin axis (RMS) | less the term |")
    print("|---|---|---|---|---|")
    for t, slope, corr, before, after in result.fit:
        print(f"| {t:.0f} | {slope:.2f} | {corr:.2f} | {before:.2f} | {after:.2f} |")
    print("\n| covariance | NEES in band | mean NEES | at 1200 / 2400 / 3600 s |")
    print("|---|---|---|---|")
    for label, (inside, mean, at) in zip(
        ("P", "P + ¼ m mᵀ", "P + ¾ m mᵀ"), result.nees, strict=True
    ):
        print(f"| {label} | {inside:.0%} | {mean:.1f} | {' / '.join(f'{v:.1f}' for v in at)} |")
    print(f"\n∫δψ² v_h dt over ∫σ_ψ² v_h dt (projected on m): {result.ratio:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4000, help="Monte Carlo runs (default 4000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--filter", action="store_true", help="pronet's filter instead")
    parser.add_argument(
        "--second-order", action="store_true", help="the filter's thin axis and the ½∫δψ²v term"
    )
    args = parser.parse_args()
    if args.second_order:
        second_order_check(args.seed)
        return
    if args.filter:
        filter_check(args.seed)
        return
    print(
        "| t [s] | σ_ψ [°] | mean error N, E [m] | NEES: linear | sigma points, redrawn "
        "| sigma points, kept | linear about the true mean |"
    )
    print("|---|---|---|---|---|---|---|")
    for t, sd, n, e, *scores in run(args.runs, args.seed):
        cells = " | ".join(f"{s:.1f}" for s in scores)
        print(f"| {t:.0f} | {sd:.1f} | {n:.2f}, {e:.2f} | {cells} |")


if __name__ == "__main__":
    main()
