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
``∫ (cos ψ − 1) v dt`` the model predicts from each run's own heading error, and the
heading RMS of the same 20 runs started at the truth (no initial error drawn, the same
P0): how much of the heading error the process noise makes on its own.

    python scripts/heading_nonlinearity.py [--runs 4000] [--seed 0] [--filter]
"""

from __future__ import annotations

import argparse

import numpy as np

DT = 0.1  # [s]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4000, help="Monte Carlo runs (default 4000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--filter", action="store_true", help="pronet's filter instead")
    args = parser.parse_args()
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
