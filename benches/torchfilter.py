"""The differentiable filter's cost for training: forward and backward of a
Kalman-informed loss over every window of the Snapir sections, batched.

    python benches/torchfilter.py [--data DIR] [--sections 10] [--seconds 20]
        [--threads 2] [--batch N] [--repeat 1]

Loads the first ``--sections`` sections (aligned as ``pronet real`` does), runs the core
over each with its white-noise q (``pronet.learn.torchfilter.windows``), cuts them into
windows of ``--seconds`` and times, in batches of ``--batch`` windows (default: all in
one), ``advance`` over every window with q = q0·exp(s) and the backward pass of the mean
squared velocity error against the ground truth (interpolated to the epochs) to s.
Prints one JSON object: the walls [s] (loading, the core's runs and cutting, forward,
backward; best of ``--repeat``; and the pass's CPU time, which a shared machine does
not inflate), the windows and IMU samples, and the peak resident
memory [GiB]. Nothing here is a test: the numbers are for docs/results/learning-q.md.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pronet.learn import torchfilter as tf
from pronet.learn.torchfilter.windows import Windows, windows
from pronet.recorded.alignment import load_snapir_sections
from pronet.recorded.passes import section_recorded
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q

SNAPIR = Path(__file__).resolve().parents[2] / "shared" / "data" / "snapir"


def peak_gib() -> float:
    """The process's peak resident memory [GiB] (``VmHWM``)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    raise RuntimeError("no VmHWM in /proc/self/status")


def truth_at_epochs(cut: Windows, sections: list[Any]) -> torch.Tensor:
    """``(W, T, 3)`` each window's ground-truth NED velocity at its epochs."""
    out = np.zeros((cut.batch.size, cut.batch.length, 3))
    times = cut.batch.time.numpy()
    for w, s in enumerate(cut.section):
        sec = sections[s]
        for j in range(3):
            out[w, :, j] = np.interp(times[w], sec.truth_time, sec.truth_vel[:, j])
    return torch.as_tensor(out)


def one_pass(cut: Windows, truth: torch.Tensor, q0: torch.Tensor, batch: int) -> dict[str, float]:
    """Forward and backward over every window, ``batch`` windows at a time: the walls
    [s] and the process's CPU time [s] (the machine may be shared)."""
    s = torch.zeros_like(q0, requires_grad=True)
    forward = backward = 0.0
    cpu = time.process_time()
    total = cut.batch.size
    for lo in range(0, total, batch):
        part = slice(lo, min(lo + batch, total))
        b, start = cut.batch.select(part), cut.start.select(part)
        t = time.perf_counter()
        _, out = tf.advance(start, b, 0, b.length, q0[part] * torch.exp(s[part]))
        loss = ((out.vel - truth[part]) ** 2).mean() * (part.stop - part.start) / total
        forward += time.perf_counter() - t
        t = time.perf_counter()
        loss.backward()
        backward += time.perf_counter() - t
    assert s.grad is not None and bool(torch.isfinite(s.grad).all())
    return {"forward": forward, "backward": backward, "cpu": time.process_time() - cpu}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=str(SNAPIR))
    parser.add_argument("--sections", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--batch", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    t = time.perf_counter()
    sections = [a for a, _ in load_snapir_sections(args.data)][: args.sections]
    loading = time.perf_counter() - t
    t = time.perf_counter()
    passes, schedules = [], []
    for sec in sections:
        cfg = real_filter_config(sec.alignment.filter_lever_arm, imu_dt=imu_step(sec.imu_time))
        rec = section_recorded(sec, cfg)
        passes.append(rec)
        schedules.append((np.array([rec.t0]), np.array([white_noise_q(rec.imu)])))
    cut = windows(passes, schedules, schedules[0][1][0], args.seconds)
    q0 = torch.as_tensor(np.stack([schedules[s][1][0] for s in cut.section]))
    truth = truth_at_epochs(cut, sections)
    cutting = time.perf_counter() - t
    walls = [one_pass(cut, truth, q0, args.batch or cut.batch.size) for _ in range(args.repeat)]
    best = min(walls, key=lambda w: w["forward"] + w["backward"])
    print(
        json.dumps(
            {
                "sections": len(sections),
                "windows": cut.batch.size,
                "imu_samples": cut.batch.size * cut.batch.length,
                "threads": args.threads,
                "batch": args.batch or cut.batch.size,
                "loading_s": round(loading, 2),
                "core_and_cutting_s": round(cutting, 2),
                "forward_s": round(best["forward"], 2),
                "backward_s": round(best["backward"], 2),
                "pass_s": round(best["forward"] + best["backward"], 2),
                "pass_cpu_s": round(best["cpu"], 2),
                "peak_gib": round(peak_gib(), 2),
            }
        )
    )


if __name__ == "__main__":
    main()
