"""The RTS smoother against the filter on every built-in scenario, as
docs/results/smoother.md shows it.

    python scripts/smoother.py [--runs 100] [--oracle] [--seed 0]
                               [--part scenarios|psd|outage|steps|nonlinear|seeds]

Per scenario: the constant strategy at the scenario's nominal q (``--oracle``: the
filter told the simulated IMU's true variance at every step), 100 runs (seed 0, or
``--seed``), histories every second. ``scenarios`` prints a Markdown table: velocity SRMSE and
final horizontal error of the filter and the smoother, the share of DVL epochs whose
run-averaged NEES lies in its 95 % band for each error block (filter / smoother), and
the recorded epochs where the smoothed velocity error RMS is above 1.05 x the
filter's (and where above it beyond the runs' noise, by a paired bootstrap).
``psd``: ``paper``'s IMU (no bias walk) with the filter told bias walks from the
paper's ε = 0.001 down to the matched scenario's: the same two columns.
``outage``: per DVL outage of ``outage``, the horizontal error RMS over the runs at
its start and middle, filter and smoother, the drift accrued between them, and the
σ of the horizontal position each reports at the middle; then the same without an
initial error drawn from P0. ``steps``: ``matched`` with a
0.1 s covariance step and at every sample, histories at every IMU epoch (9 of 10 inside
a step at 0.1 s): per error block, the run-averaged σ-normalized squared error
``Σ (e/σ)²`` over the block's three states (the NEES with σ alone, 3 when consistent),
its mean over the epochs and the share of epochs inside its 95 % band, filter /
smoother (docs/results/smoother.md, "With a covariance step"). ``nonlinear``: ``varying-matched``'s
schedule with every IMU variance scaled by 1, 0.1, 0.01 and 0.001, the filter told the
true variance (the oracle): the tilt error, the down accelerometer bias's error against
``g E[θ²]/2`` (the vertical specific force a tilt error θ leaves to second order, which
the linear error model lacks) and its σ-normalized squared error, filter / smoother
(docs/results/smoother.md, "Told the true IMU noise"). ``seeds``: ``matched`` (the filter told the
simulated model) at seeds 0–9: per block the share of DVL epochs in band and the NEES
averaged over the runs and the epochs, filter / smoother (docs/results/smoother.md, "One
draw of 100 runs").
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

import pronet
from pronet.config import filter_config
from pronet.results import markdown
from pronet.sim.scenarios import (
    MATCHED_BIAS_PSD,
    SCENARIOS,
    matched_filter_config,
    noise_schedule,
    scheduled_scenario,
)
from pronet.stats import chi2_mean_band
from pronet.trajectory import builtin_trajectory


def _run(
    sc,
    runs: int,
    config: pronet.FilterConfig | None = None,
    oracle: bool = False,
    seed: int = 0,
    initial_error: bool = True,
) -> pronet.MonteCarloResult:
    strategy = pronet.Strategy.oracle() if oracle else pronet.Strategy.constant(sc.q_nominal)
    return pronet.monte_carlo(
        sc.trajectory, strategy, sensors=sc.sensors,
        config=config or sc.config, n_runs=runs, seed=seed, record_every=100, smooth=True,
        sample_initial_error=initial_error,
    )  # fmt: skip


def _worse(r: pronet.MonteCarloResult) -> str:
    """Recorded epochs whose smoothed velocity error RMS is above 1.05 x the filter's,
    and in brackets those where it is above the filter's beyond the noise of the runs:
    the 2.5 % quantile of the ratio over 2000 paired bootstrap draws of the runs
    (resampled alike for both) above 1."""
    s = r.smoothed
    assert s is not None and r.error is not None and s.error is not None
    ef = np.sum(r.error[:, :, 3:6] ** 2, axis=2)  # (runs, epochs)
    es = np.sum(s.error[:, :, 3:6] ** 2, axis=2)
    ratio = np.sqrt(np.nanmean(es, axis=0) / np.nanmean(ef, axis=0))
    # Each bootstrap draw as how often it takes each run: (2000, runs) weights, so the
    # draws' means are two matrix products (not 2000 copies of the runs).
    runs = len(ef)
    draws = np.random.default_rng(0).integers(0, runs, (2000, runs))
    weights = np.zeros((2000, runs))
    np.add.at(weights, (np.arange(2000)[:, None], draws), 1.0)

    def mean(e: np.ndarray) -> np.ndarray:
        return (weights @ np.nan_to_num(e)) / (weights @ np.isfinite(e))

    low = np.quantile(np.sqrt(mean(es) / mean(ef)), 0.025, axis=0)
    return f"{int(np.sum(ratio > 1.05))} / {len(ratio)} ({int(np.sum(low > 1))})"


def row(name: str, runs: int, oracle: bool = False, seed: int = 0) -> list[str]:
    r = _run(SCENARIOS[name](0), runs, oracle=oracle, seed=seed)
    s = r.smoothed
    assert s is not None
    band = [f"{r.nees_in_band(b):.2f} / {s.nees_in_band(b):.2f}" for b in pronet.STATE_BLOCKS]
    return [
        name,
        f"{np.nanmean(r.srmse):.4f} / {np.nanmean(s.srmse):.4f}",
        f"{np.nanmean(r.final_horizontal_error):.2f} / {np.nanmean(s.final_horizontal_error):.2f}",
        *band,
        _worse(r),
    ]


def psd_rows(runs: int) -> list[list[str]]:
    sc = SCENARIOS["paper"](0)
    rows = []
    for accel, gyro in ((1e-3, 1e-3), (1e-5, 1e-7), (1e-7, 1e-10), MATCHED_BIAS_PSD[2:4]):
        walks = {"accel_bias_psd": accel, "gyro_bias_psd": gyro}
        cfg = filter_config(walks, "psd", sc.config)
        r = _run(sc, runs, cfg)
        s = r.smoothed
        assert s is not None
        rows.append([
            f"{accel:g} / {gyro:g}",
            f"{np.nanmean(r.srmse):.4f} / {np.nanmean(s.srmse):.4f}",
            f"{r.nees_in_band('attitude'):.2f} / {s.nees_in_band('attitude'):.2f}",
            _worse(r),
        ])  # fmt: skip
    return rows


def outage_rows(runs: int, initial_error: bool = True) -> list[list[str]]:
    sc = SCENARIOS["outage"](0)
    r = _run(sc, runs, initial_error=initial_error)
    s = r.smoothed
    assert s is not None and r.error is not None and s.error is not None
    assert r.sigma is not None and s.sigma is not None

    def rms(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

    errors, sigmas = (r.error, s.error), (r.sigma, s.sigma)  # filter, smoother
    rows = []
    for start, end in sc.dvl_outages:
        a, m = (int(np.argmin(np.abs(r.record_time - t))) for t in (start, (start + end) / 2))
        at = [rms(e[:, k, :2]) for e in errors for k in (a, m)]
        drift = [rms(e[:, m, :2] - e[:, a, :2]) for e in errors]
        sigma = [float(np.sqrt(np.mean(np.sum(x[:, m, :2] ** 2, axis=1)))) for x in sigmas]
        rows.append([
            f"{start:g}–{end:g} s",
            f"{at[0]:.2f} / {at[2]:.2f}",
            f"{at[1]:.2f} / {at[3]:.2f} ({at[3] / at[1]:.2f})",
            f"{drift[0]:.2f} / {drift[1]:.2f} ({drift[1] / drift[0]:.2f})",
            f"{sigma[0]:.2f} / {sigma[1]:.2f}",
        ])  # fmt: skip
    return rows


def steps_rows(runs: int) -> list[list[str]]:
    sc = SCENARIOS["matched"](0)
    low, high = chi2_mean_band(3, runs)
    rows = []
    for step in (0.1, 0.0):
        r = pronet.monte_carlo(
            sc.trajectory, pronet.Strategy.constant(sc.q_nominal), sensors=sc.sensors,
            config=filter_config({"covariance_step": step}, "steps", sc.config), n_runs=runs,
            seed=0, record_every=1, smooth=True,
        )  # fmt: skip
        cells = []
        for x in (r, r.smoothed):
            assert x is not None and x.error is not None and x.sigma is not None
            e, sigma = x.error[:, 1:], x.sigma[:, 1:]  # the first epoch: σ of the prior
            for b in range(0, 15, 3):
                nees = np.sum((e[:, :, b : b + 3] / sigma[:, :, b : b + 3]) ** 2, axis=2)
                mean = nees.mean(axis=0)
                cells.append((mean.mean(), np.mean((mean >= low) & (mean <= high))))
        rows.append([
            f"{step:g} s" if step else "every sample",
            *(f"{f[0]:.4f} / {m[0]:.4f} ({f[1]:.2f} / {m[1]:.2f})"
              for f, m in zip(cells[:5], cells[5:], strict=True)),
        ])  # fmt: skip
    return rows


def nonlinear_rows(runs: int) -> list[list[str]]:
    trajectory = builtin_trajectory("paper")
    times, q = noise_schedule(trajectory.duration, 0)
    g = 9.81
    rows = []
    for scale in (1.0, 0.1, 0.01, 0.001):
        sc = scheduled_scenario(
            "varying-matched", trajectory, times, q * scale, matched_filter_config(), 0,
            MATCHED_BIAS_PSD,
        )  # fmt: skip
        r = _run(sc, runs, oracle=True)
        s = r.smoothed
        assert s is not None and r.error is not None and s.error is not None
        assert r.sigma is not None and s.sigma is not None
        e = r.error
        tilt2 = e[:, :, 6] ** 2 + e[:, :, 7] ** 2
        second_order = g * float(np.mean(tilt2[:, -150:])) / 2  # the last 150 s
        bias = e[:, -1, 11]  # the down (body z) accelerometer bias at the end
        normalized = [
            float(np.mean((x[:, 1:, 11] / sx[:, 1:, 11]) ** 2))
            for x, sx in ((r.error, r.sigma), (s.error, s.sigma))
        ]
        rows.append([
            f"{scale:g}",
            f"{np.degrees(np.sqrt(np.mean(tilt2))):.2f}",
            f"{np.degrees(np.sqrt(np.mean(e[:, -1, 8] ** 2))):.1f}",
            f"{second_order:.2e}",
            f"{np.mean(bias):.2e} / {np.sqrt(np.mean(bias**2)):.2e}",
            f"{np.mean(r.sigma[:, -1, 11]):.2e}",
            f"{np.mean(bias) / second_order:.2f}",
            f"{normalized[0]:.1f} / {normalized[1]:.1f}",
        ])  # fmt: skip
    return rows


def seeds_rows(runs: int) -> list[list[str]]:
    sc = SCENARIOS["matched"](0)
    rows = []
    for seed in range(10):
        r = _run(sc, runs, seed=seed)
        s = r.smoothed
        assert s is not None
        rows.append([
            str(seed),
            *(f"{r.nees_in_band(b):.2f} / {s.nees_in_band(b):.2f} "
              f"({np.nanmean(r.block_nees(b)):.2f} / {np.nanmean(s.block_nees(b)):.2f})"
              for b in pronet.STATE_BLOCKS),
        ])  # fmt: skip
    return rows


def _blocks(suffix: str) -> list[str]:
    return [f"{b.replace('_', ' ')} {suffix}" for b in pronet.STATE_BLOCKS]


#: Each part's table header.
HEADERS: dict[str, list[str]] = {
    "scenarios": [
        "scenario",
        "SRMSE [m/s] filter / smoother",
        "final horiz. [m]",
        *_blocks("NEES in band"),
        "epochs smoothed > 1.05 x filtered (beyond noise)",
    ],
    "psd": [
        "filter's bias walk ε (accel / gyro)",
        "SRMSE [m/s] filter / smoother",
        "att. NEES in band",
        "epochs smoothed > 1.05 x filtered (beyond noise)",
    ],
    "outage": [
        "outage",
        "horiz. error at start [m] filter / smoother",
        "at middle (ratio)",
        "drift start → middle (ratio)",
        "horiz. σ at middle",
    ],
    "steps": ["covariance step", *_blocks("Σ(e/σ)² mean (in band)")],
    "nonlinear": [
        "IMU variance x",
        "tilt error RMS [°]",
        "heading error at end [°]",
        "g E[θ²]/2 [m/s²]",
        "down accel bias error at end, mean / RMS [m/s²]",
        "its σ",
        "mean / (g E[θ²]/2)",
        "its (e/σ)² filter / smoother",
    ],
    "seeds": ["seed", *_blocks("in band (NEES)")],
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--part", choices=tuple(HEADERS), default="scenarios")
    parser.add_argument(
        "--oracle", action="store_true", help="scenarios: the filter told the true IMU variance"
    )
    parser.add_argument("--seed", type=int, default=0, help="scenarios: the Monte Carlo's seed")
    args = parser.parse_args()
    header, runs = HEADERS[args.part], args.runs
    parts: dict[str, Callable[[], list[list[str]]]] = {
        "scenarios": lambda: [row(name, runs, args.oracle, args.seed) for name in SCENARIOS],
        "psd": lambda: psd_rows(runs),
        "outage": lambda: outage_rows(runs),
        "steps": lambda: steps_rows(runs),
        "nonlinear": lambda: nonlinear_rows(runs),
        "seeds": lambda: seeds_rows(runs),
    }
    print(markdown(header, parts[args.part]()), end="")
    if args.part == "outage":
        print("\nWithout an initial error drawn (sample_initial_error=False):\n")
        print(markdown(header, outage_rows(runs, initial_error=False)), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
