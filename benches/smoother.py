"""The RTS smoother's cost and memory, each measured in one process.

    python benches/smoother.py cost RUNS REPEAT SECONDS [STEP ...]
    python benches/smoother.py memory HOURS STEP [OUTPUT_STEP]

``cost``: for each covariance step (default 0 and 0.1 s), the forward and the smoothed
passes alternating ``repeat`` times, best of each: ``run_filter`` on ``SECONDS`` of a
100 Hz recording with a 1 Hz DVL and the filter told its model
(``benches/covariance_step.py``'s ``recording`` and ``RECORDING_CONFIG``), every epoch kept
(``forward``, ``smoothed``) and one per second (``forward_thinned``, ``thinned``), and
the constant-Q Monte Carlo of ``paper`` (``RUNS`` runs, one thread; its CPU time too,
measured the same way, which other work on a shared machine moves less than the wall);
prints one JSON object of the times [s] and the ratios smoothed / forward.

``memory``: ``run_filter(smooth=True)`` on ``HOURS`` of a 100 Hz IMU with a 5 Hz DVL
(every epoch kept, or one per ``OUTPUT_STEP`` seconds), in a fresh process that loads
the arrays from files; prints one JSON object: that process's peak resident memory
[GiB] with the arrays loaded and after the pass (``VmHWM``), the IMU samples, DVL and
kept epochs, and the bytes per IMU sample the pass added. ``benches/run.py --only
smoother`` runs both and reports the rows.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from functools import partial
from typing import Any

# The timed work is the native core's, on one thread; NumPy's idle BLAS threads would
# spin beside it and add to the CPU time measured (set before NumPy is imported).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from covariance_step import RECORDING_CONFIG, alternating, recording

import pronet
from pronet.config import filter_config
from pronet.recorded.alignment import dcm_from_euler
from pronet.sim import paper, scenarios

#: The output period [s] of the thinned smoothed pass (``run_filter(output_step=...)``).
OUTPUT_STEP = 1.0


def peak_gib() -> float:
    """The process's peak resident memory [GiB] (``VmHWM``)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    raise RuntimeError("no VmHWM in /proc/self/status")


def cost(runs: int, repeat: int, seconds: float, steps: list[float]) -> dict[str, Any]:
    data = recording(seconds)
    sc = scenarios.SCENARIOS["paper"](0)
    out: dict[str, Any] = {"imu_steps": len(data["imu"])}
    for step in steps:
        cfg = filter_config({"covariance_step": step}, "covariance_step:", RECORDING_CONFIG)
        passes = {
            "forward": partial(pronet.run_filter, **data, config=cfg),
            "smoothed": partial(pronet.run_filter, **data, config=cfg, smooth=True),
            "forward_thinned": partial(
                pronet.run_filter, **data, config=cfg, output_step=OUTPUT_STEP
            ),
            "thinned": partial(
                pronet.run_filter, **data, config=cfg, smooth=True, output_step=OUTPUT_STEP
            ),
        }

        paper_cfg = filter_config({"covariance_step": step}, "covariance_step:", sc.config)

        def mc(smooth: bool, cfg: pronet.FilterConfig = paper_cfg) -> object:
            return pronet.monte_carlo(
                sc.trajectory, pronet.Strategy.constant(sc.q_nominal), sensors=sc.sensors,
                config=cfg, n_runs=runs, seed=0, threads=1, smooth=smooth,
            )  # fmt: skip

        walls = alternating(repeat, passes)
        mc_calls = {"forward": partial(mc, False), "smoothed": partial(mc, True)}
        mcs = alternating(repeat, mc_calls)
        cpu = alternating(repeat, mc_calls, time.process_time)
        out[f"{step:g}"] = {
            "run_filter_s": walls,
            "run_filter_ratio": walls["smoothed"] / walls["forward"],
            "run_filter_thinned_ratio": walls["thinned"] / walls["forward_thinned"],
            "monte_carlo_s": mcs,
            "monte_carlo_ratio": mcs["smoothed"] / mcs["forward"],
            "monte_carlo_cpu_s": cpu,
            "monte_carlo_cpu_ratio": cpu["smoothed"] / cpu["forward"],
        }
    return out


def memory(hours: float, step: float, output_step: float | None) -> dict[str, Any]:
    """A smoothed pass over ``hours`` of a straight, turning 100 Hz run with a 5 Hz DVL
    (the paper's IMU noise), keeping every epoch or one per ``output_step`` [s]; its
    peak memory, measured in a fresh process (:func:`smoothed_pass`) that loads the
    recording's arrays from files: building the trajectory here peaks higher than a
    10 h pass and would hide its peak."""
    n_legs = max(1, int(hours * 60))
    legs = [[60.0, 0.0, (-1) ** i * 0.02, 0.0] for i in range(n_legs)]
    traj = pronet.trajectory_from_segments(
        legs, lla0=(np.radians(32.0), np.radians(34.0), -5.0), speed0=1.5
    )
    rng = np.random.default_rng(0)
    k = np.arange(20, traj.n_samples + 1, 20)
    body = np.einsum("nji,nj->ni", dcm_from_euler(traj.rpy[k]), traj.vel_ned[k])
    arrays = {
        "imu": traj.imu + rng.normal(size=traj.imu.shape) * np.sqrt(paper.PAPER_Q),
        "imu_time": traj.time[1:],
        "dvl": body + rng.normal(size=body.shape) * 0.1,
        "dvl_time": traj.time[k],
        "initial": np.array([traj.time[0], *traj.lla[0], *traj.vel_ned[0], *traj.rpy[0]]),
    }
    del traj
    with tempfile.TemporaryDirectory() as folder:
        for name, values in arrays.items():
            np.save(os.path.join(folder, f"{name}.npy"), values)
        del arrays
        command = [sys.executable, __file__, "pass", folder, str(step), str(output_step)]
        done = subprocess.run(command, check=True, capture_output=True, text=True)
    return {"hours": hours, **json.loads(done.stdout)}


def smoothed_pass(folder: str, step: float, output_step: float | None) -> dict[str, Any]:
    """``run_filter(smooth=True)`` on the arrays :func:`memory` saved in ``folder``; the
    peak resident memory [GiB] with the arrays loaded and after the pass."""
    a = {name: np.load(os.path.join(folder, f"{name}.npy")) for name in NAMES}
    initial = a.pop("initial")
    config = filter_config(
        {"covariance_step": step}, "covariance_step:", paper.paper_filter_config()
    )
    dvl = pronet.Dvl(a["dvl_time"], a["dvl"])
    before = peak_gib()
    result = pronet.run_filter(
        a["imu"], a["imu_time"], [dvl], t0=initial[0], lla0=initial[1:4],
        vel0=initial[4:7], rpy0=initial[7:10], config=config,
        strategy=pronet.Strategy.constant(paper.PAPER_Q), smooth=True,
        output_step=output_step,
    )  # fmt: skip
    after = peak_gib()
    assert result.smoothed is not None
    n = len(a["imu"])
    return {
        "output_step": output_step,
        "kept_epochs": len(result.time),
        "imu_samples": n,
        "dvl_epochs": len(a["dvl"]),
        "peak_before_gib": before,
        "peak_gib": after,
        "bytes_per_imu_sample": (after - before) * 2**30 / n,
    }


NAMES = ("imu", "imu_time", "dvl", "dvl_time", "initial")


def main(argv: list[str]) -> int:
    if not argv:
        raise SystemExit(__doc__.split("\n\n")[1])  # the usage lines
    if argv[0] == "cost":
        runs, repeat, seconds = int(argv[1]), int(argv[2]), float(argv[3])
        steps = [float(s) for s in argv[4:]] or [0.0, 0.1]
        out = cost(runs, repeat, seconds, steps)
    elif argv[0] == "memory":
        out = memory(float(argv[1]), float(argv[2]), float(argv[3]) if len(argv) > 3 else None)
    elif argv[0] == "pass":
        out = smoothed_pass(argv[1], float(argv[2]), None if argv[3] == "None" else float(argv[3]))
    else:
        raise SystemExit(f"unknown mode {argv[0]!r}: cost or memory")
    assert "torch" not in sys.modules
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
