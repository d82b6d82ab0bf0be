"""The covariance step's speed, measured side by side in one process: the
constant-Q Monte Carlo of ``paper`` and ``run_filter`` on a long 100 Hz recording with
a 1 Hz DVL, each at one IMU step (``covariance_step=0``) and at a covariance step,
alternating the two settings ``repeat`` times and keeping the best of each.

    python benches/covariance_step.py RUNS REPEAT SECONDS STEP [THREADS]

prints one JSON object: the Monte Carlo walls [s] and ``run_filter``'s ns per IMU step
at both settings, keeping the last epoch only (the filter alone) and every epoch.
``benches/run.py --only covariance-step`` runs it in a fresh process (without torch's
threads beside rayon's) and reports the ratios.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import numpy as np

import pronet
from pronet.config import filter_config
from pronet.recorded.alignment import dcm_from_euler
from pronet.sim import paper, scenarios


def recording(seconds: float, dvl_rate: int = 1) -> dict[str, Any]:
    """``run_filter``'s arguments for ``seconds`` of a vehicle turning every minute
    at 100 Hz, with the paper's IMU noise and a ``dvl_rate`` Hz body-frame DVL (a
    divisor of 100; 0.1 m/s noise)."""
    n_legs = max(1, int(seconds // 60))
    legs = [[60.0, 0.0, (-1) ** i * 0.02, 0.0] for i in range(n_legs)]
    traj = pronet.trajectory_from_segments(
        legs, lla0=(np.radians(32.0), np.radians(34.0), -5.0), speed0=1.5
    )
    rng = np.random.default_rng(0)
    imu = traj.imu + rng.normal(size=traj.imu.shape) * np.sqrt(paper.PAPER_Q)
    k = np.arange(100, traj.n_samples + 1, 100 // dvl_rate)
    body = np.einsum("nji,nj->ni", dcm_from_euler(traj.rpy[k]), traj.vel_ned[k])
    return dict(
        imu=imu,
        imu_time=traj.time[1:],
        streams=[pronet.Dvl(traj.time[k], body + rng.normal(size=body.shape) * 0.1)],
        t0=traj.time[0],
        lla0=traj.lla[0],
        vel0=traj.vel_ned[0],
        rpy0=traj.rpy[0],
        strategy=pronet.Strategy.constant(paper.PAPER_Q),
    )


#: The filter told :func:`recording`'s model: its DVL's R, and bias random walks far
#: below anything its bias-free IMU shows (its heading σ still grows with the gyro's
#: white noise, to about 6° in 20 minutes; DVL NIS 0.97 per degree of freedom there).
RECORDING_CONFIG = pronet.FilterConfig(
    accel_bias_psd=1e-8, gyro_bias_psd=1e-12, dvl_variance=(0.01,) * 3
)


def alternating(
    repeat: int,
    calls: Mapping[str, Callable[[], object]],
    clock: Callable[[], float] = time.perf_counter,
) -> dict[str, float]:
    """Best time [s] of each call over ``repeat`` rounds, the calls alternating: wall
    time, or ``clock``'s (``time.process_time``: the CPU time of the process's threads,
    less moved than the wall by other work on a shared machine)."""
    best = dict.fromkeys(calls, np.inf)
    for _ in range(repeat):
        for name, call in calls.items():
            t0 = clock()
            call()
            best[name] = min(best[name], clock() - t0)
    return best


def main(argv: list[str]) -> int:
    runs, repeat, seconds, step = int(argv[0]), int(argv[1]), float(argv[2]), float(argv[3])
    threads = int(argv[4]) if len(argv) > 4 else 2
    sc = scenarios.SCENARIOS["paper"](0)
    settings = {"every": 0.0, "step": step}

    def config(s: float) -> pronet.FilterConfig:
        base = paper.paper_filter_config()
        return filter_config({"covariance_step": s}, "covariance_step:", base)

    def monte_carlo_at(s: float) -> object:
        return pronet.monte_carlo(
            sc.trajectory,
            pronet.Strategy.constant(sc.q_nominal),
            sensors=sc.sensors,
            config=config(s),
            n_runs=runs,
            seed=0,
            threads=threads,
        )

    monte_carlo = alternating(
        repeat, {name: partial(monte_carlo_at, s) for name, s in settings.items()}
    )
    data = recording(seconds)
    n = len(data["imu"])
    out = {
        "monte_carlo_every_s": monte_carlo["every"],
        "monte_carlo_step_s": monte_carlo["step"],
        "imu_steps": n,
    }

    # epochs="last": the filter alone; "all": with every epoch's estimate and σ kept;
    # the four calls alternate, so that each ratio is taken side by side. The filter is
    # told the recording's model (the paper's ε of 1e-3 for a bias-free IMU over an hour
    # took its heading σ past 1,000° and its DVL NIS out of band: a bench of a filter
    # users would not run)
    def run(s: float, epochs: str) -> object:
        told = filter_config({"covariance_step": s}, "covariance_step:", RECORDING_CONFIG)
        return pronet.run_filter(**data, config=told, epochs=epochs, warn=False)  # type: ignore[call-overload]

    calls = {
        f"run_filter_{epochs}_{name}_ns": partial(run, s, epochs)
        for epochs in ("last", "all")
        for name, s in settings.items()
    }
    for key, wall in alternating(repeat, calls).items():
        out[key] = wall / n * 1e9
    assert "torch" not in sys.modules
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
