"""The DVL calibration states with a prior of one's choosing (``FilterConfig``'s
``dvl_scale_sigma`` and ``dvl_misalignment_sigma``): the simulation check of
:func:`pronet.recorded.dvlcalibration.calibration_check` and, where the Snapir data is, the
constant row on the recorded sections without the states and with them, with the
datasheet's R and with R matched to the innovations of the filter with those states.
docs/results/calibration.md and docs/results/snapir.md quote it for a prior of 0.3 % and 0.3°.

    python scripts/calibration_prior.py [--scale 0.003] [--angle-deg 0.3] [--runs 100]
                                        [--data ../shared/data/snapir]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from pronet import _core
from pronet.recorded import dvlcalibration
from pronet.recorded.alignment import load_snapir_sections
from pronet.recorded.dvlnoise import match_innovations, second_difference_variance
from pronet.recorded.real import run_section
from pronet.recorded.tuning import (
    REAL_ACCEL_BIAS_PSD,
    REAL_DVL_VARIANCE,
    REAL_GYRO_BIAS_PSD,
    REAL_P0_SIGMA,
    white_noise_q,
)
from pronet.results import markdown

Prior = tuple[float, float]


def config(
    arm: tuple[float, float, float], r: tuple[float, float, float], prior: Prior | None
) -> _core.FilterConfig:
    """The recorded sections' tuning with DVL noise ``r``, with the states under
    ``prior`` (scale σ, angle σ [rad]) or without them (None)."""
    return _core.FilterConfig(
        p0_sigma=REAL_P0_SIGMA,
        accel_bias_psd=REAL_ACCEL_BIAS_PSD,
        gyro_bias_psd=REAL_GYRO_BIAS_PSD,
        dvl_variance=r,
        lever_arm=arm,
        dvl_calibration=prior is not None,
        dvl_scale_sigma=None if prior is None else prior[0],
        dvl_misalignment_sigma=None if prior is None else (prior[1],) * 3,
    )


def snapir_table(data: Path, prior: Prior) -> str:
    """Mean SRMSE, final horizontal error and the range of the mean NIS over the
    sections, per row."""
    datasheet = (REAL_DVL_VARIANCE,) * 3
    rows: dict[str, list[tuple[float, float, float]]] = {}
    for aligned, _ in load_snapir_sections(data):
        arm = aligned.alignment.filter_lever_arm
        strategy = _core.Strategy.constant(white_noise_q(aligned.imu))

        def run(r: tuple[float, float, float], with_prior: Prior | None):  # noqa: B023
            return run_section(aligned, strategy, config(arm, r, with_prior))  # noqa: B023

        matched = match_innovations(
            lambda r: run(r, prior).result, second_difference_variance(aligned.dvl)
        )
        for label, r, p in (
            ("constant (estimated q), no calibration states", datasheet, None),
            ("calibration states, datasheet R", datasheet, prior),
            ("calibration states, R matched with them", matched.variance, prior),
        ):
            m = run(r, p).metrics
            rows.setdefault(label, []).append((m.srmse, m.final_horizontal, m.mean_nis))
    lines = []
    for label, values in rows.items():
        v = np.array(values)
        nis = f"{v[:, 2].min():.2f}–{v[:, 2].max():.2f}"
        lines.append([label, f"{v[:, 0].mean():.4f}", f"{v[:, 1].mean():.2f}", nis])
    header = ["row", "mean SRMSE [m/s]", "mean final horiz. error [m]", "mean NIS per section"]
    return markdown(header, lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scale", type=float, default=0.003, help="scale-factor σ (0.003)")
    parser.add_argument("--angle-deg", type=float, default=0.3, help="angle σ [°] (0.3)")
    parser.add_argument("--runs", type=int, default=100, help="simulation runs (100)")
    default_data = Path(__file__).resolve().parents[2] / "shared" / "data" / "snapir"
    parser.add_argument("--data", type=Path, default=default_data, help="Snapir folder")
    args = parser.parse_args()
    prior = (args.scale, math.radians(args.angle_deg))
    rows = dvlcalibration.calibration_check(args.runs, prior=prior)
    print(dvlcalibration.calibration_table(rows))
    if args.data.is_dir():
        print(snapir_table(args.data, prior))
    else:
        print(f"(no Snapir data at {args.data}: the recorded sections are skipped)")


if __name__ == "__main__":
    main()
