"""Your own trajectory and IMU grade: a lawnmower survey with a MEMS IMU and a 5 Hz DVL.

Run:  python examples/mems_survey.py [--runs N]

The survey: three 120 s legs at 1.5 m/s joined by 180° turns (12 s at 15°/s), 20 m
deep. The IMU is a MEMS grade (gyro angle random walk ≈ 1.5 °/√h, turn-on bias
≈ 41 °/h; the grade of docs/results/consistency.md's heading-consistency suite), the DVL reads
body velocity at 5 Hz with 0.02 m/s noise. The filter is told this model exactly: its
P0 holds the turn-on biases, its bias walks the simulated ones, its R the DVL's noise.
Each run starts from a draw of P0, so the NEES of every state block says whether the
filter's σ can be believed.
"""

from __future__ import annotations

import argparse
import math

import pronet
from pronet import Segment

#: The IMU grade, at 100 Hz: per-sample white-noise variances [(m/s²)², (rad/s)²],
#: turn-on bias 1σ [m/s², rad/s] and bias random-walk PSDs [(m/s²)²/s, (rad/s)²/s].
Q = (2e-3,) * 3 + (2e-5,) * 3
TURN_ON = (1e-3,) * 3 + (2e-4,) * 3
WALK = (1e-9,) * 3 + (2.35e-12,) * 3
DVL_SIGMA = 0.02  # [m/s] per axis
DVL_HZ = 5.0


def lawnmower() -> pronet.Trajectory:
    """Three 120 s legs joined by a left and a right 180° turn, 20 m deep."""
    leg = Segment(120.0)
    left, right = Segment.degrees(12.0, yaw_rate=15.0), Segment.degrees(12.0, yaw_rate=-15.0)
    return pronet.trajectory_from_segments(
        [leg, left, leg, right, leg],
        lla0=(math.radians(32.0), math.radians(34.0), -20.0),
        speed0=1.5,
        name="lawnmower",
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50, help="Monte Carlo runs (default 50)")
    args = parser.parse_args(argv)
    traj = lawnmower()
    sensors = pronet.SensorConfig(
        imu_variance=Q,
        imu_bias_psd=WALK,
        dvl_variance=[DVL_SIGMA**2] * 3,
        dvl_period=1.0 / DVL_HZ,
    )
    p0_sigma = [1.0] * 3 + [0.02] * 3 + [1e-3, 1e-3, math.radians(1.0)] + list(TURN_ON)
    config = pronet.FilterConfig(
        p0_sigma=p0_sigma,  # position [m], velocity [m/s], attitude [rad], biases
        accel_bias_psd=WALK[0],
        gyro_bias_psd=WALK[3],
        dvl_variance=[DVL_SIGMA**2] * 3,
    )
    res = pronet.monte_carlo(
        traj,
        pronet.Strategy.constant(Q),
        sensors=sensors,
        config=config,
        n_runs=args.runs,
        seed=0,
        record_every=100,  # a 1 Hz error history
    )
    s = res.summary()
    print(f"{traj.name}: {traj.duration:.0f} s, {traj.n_samples} IMU samples, {DVL_HZ:g} Hz DVL")
    print(f"SRMSE {s['srmse']} m/s, final horizontal error {s['final_horizontal_error']} m")
    low, high = res.nees_band()
    print(f"NEES per block (3 when consistent; 95 % band of the run mean {low:.2f}-{high:.2f}):")
    for block in pronet.STATE_BLOCKS:
        nees, inside = s[f"{block}_nees"].mean, res.nees_in_band(block)
        print(f"  {block:10s} {nees:6.2f}, in band at {inside:.0%} of epochs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
