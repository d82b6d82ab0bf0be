"""The RTS smoother against the filter on every built-in scenario, as docs/filter.md
shows it ("The RTS smoother", Measured).

    python scripts/smoother.py [--runs 100]

Per scenario: the constant strategy at the scenario's nominal q, 100 runs (seed 0),
histories every second. Prints a Markdown table: velocity SRMSE and final horizontal
error of the filter and the smoother, the share of DVL epochs whose run-averaged NEES
lies in its 95 % band for velocity and attitude, and the recorded epochs where the
smoothed velocity error RMS is above 1.05 x the filter's.
"""

from __future__ import annotations

import argparse

import numpy as np

import pronet
from pronet.results import markdown
from pronet.sim.scenarios import SCENARIOS


def row(name: str, runs: int) -> list[object]:
    sc = SCENARIOS[name](0)
    r = pronet.monte_carlo(
        sc.trajectory, pronet.Strategy.constant(sc.q_nominal), sensors=sc.sensors,
        config=sc.config, n_runs=runs, seed=0, record_every=100, smooth=True,
    )  # fmt: skip
    s = r.smoothed
    assert s is not None and r.error is not None and s.error is not None
    rms_f = np.sqrt(np.nanmean(np.sum(r.error[:, :, 3:6] ** 2, axis=2), axis=0))
    rms_s = np.sqrt(np.nanmean(np.sum(s.error[:, :, 3:6] ** 2, axis=2), axis=0))
    band = [f"{r.nees_in_band(b):.2f} / {s.nees_in_band(b):.2f}" for b in ("velocity", "attitude")]
    return [
        name,
        f"{np.nanmean(r.srmse):.4f} / {np.nanmean(s.srmse):.4f}",
        f"{np.nanmean(r.final_horizontal_error):.2f} / {np.nanmean(s.final_horizontal_error):.2f}",
        *band,
        f"{int(np.sum(rms_s > 1.05 * rms_f))} / {len(rms_f)}",
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    args = parser.parse_args()
    header = [
        "scenario",
        "SRMSE [m/s] filter / smoother",
        "final horiz. [m]",
        "vel. NEES in band",
        "att. NEES in band",
        "epochs smoothed > 1.05 x filtered",
    ]
    print(markdown(header, [row(name, args.runs) for name in SCENARIOS]), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
