"""One filter pass over arrays of your own: IMU and DVL in, a table and local metres out.

Run:  python examples/own_arrays.py [--seed S]

The arrays here are made from the built-in ``paper`` trajectory with numpy (white IMU
noise, a 5 Hz DVL with 0.02 m/s noise): replace them by your own recording's. The pass
returns the estimate at every IMU epoch and every DVL update as arrays;
``to_dataframe`` turns them into pandas tables, ``local_ned`` turns latitude, longitude
and height into metres north, east and down of a point, and ``covariance_time`` keeps
the full covariance at the times you name (its position block gives the horizontal
error ellipse, which σ alone cannot).
"""

from __future__ import annotations

import argparse

import numpy as np

import pronet
from pronet.recorded.alignment import dcm_from_euler

Q = (1e-4,) * 3 + (1e-6,) * 3  # per-sample IMU noise variances [(m/s²)², (rad/s)²]
DVL_SIGMA = 0.02  # [m/s]
DVL_EVERY = 20  # IMU samples per DVL reading: 5 Hz at 100 Hz


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    truth = pronet.builtin_trajectory("paper")
    # Your arrays: IMU rows [f (m/s²), ω (rad/s)] in the body frame (forward-right-down),
    # row k covering (imu_time[k-1], imu_time[k]]; a stream per aiding sensor, here the
    # DVL's body velocity [m/s] with its 1σ [m/s] (the others: pronet.Depth, pronet.Fix,
    # pronet.Heading).
    imu = truth.imu + rng.normal(size=truth.imu.shape) * np.sqrt(Q)
    imu_time = truth.time[1:]
    k = np.arange(DVL_EVERY, truth.n_samples + 1, DVL_EVERY)
    c_nb = dcm_from_euler(truth.rpy[k])  # body to NED
    dvl = np.einsum("kji,kj->ki", c_nb, truth.vel_ned[k])  # C_nᵇ v_NED
    dvl += rng.normal(size=dvl.shape) * DVL_SIGMA
    streams = [pronet.Dvl(truth.time[k], dvl, sigma=DVL_SIGMA)]
    out = pronet.run_filter(
        imu, imu_time, streams,
        t0=0.0, lla0=truth.lla[0], vel0=truth.vel_ned[0], rpy0=truth.rpy[0],
        config=pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14),  # bias walks
        strategy=pronet.Strategy.constant(Q),
        covariance_time=[60.0, 180.0, 300.0],
    )  # fmt: skip
    epochs, updates = out.to_dataframe(), out.to_dataframe("updates")
    origin = truth.lla[0]
    error = pronet.local_ned(out.lla, origin) - pronet.local_ned(truth.lla, origin)  # [m]
    print(f"{len(epochs)} epochs, {len(updates)} DVL updates, mean NIS {updates['nis'].mean():.2f}")
    print(f"final horizontal error {np.hypot(*error[-1, :2]):.2f} m")
    kept = out.covariance_epoch
    for t, e, p in zip(out.time[kept], kept, out.covariances, strict=True):
        axes = np.sqrt(np.linalg.eigvalsh(p[:2, :2]))  # the 1σ ellipse's half-axes [m]
        print(
            f"t = {t:5.1f} s: north/east error {error[e, 0]:+.2f}/{error[e, 1]:+.2f} m, "
            f"1σ ellipse {axes[1]:.2f} x {axes[0]:.2f} m"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
