"""The DVL's innovations per body axis on the Snapir sections, and R fitted together
with a correlated (first-order Gauss–Markov) DVL error.

For each section, the constant (estimated q) row:

1. with the datasheet R and with the innovation-matched R (``pronet real``'s "R from
   data"), the lag-one autocorrelation of each body axis's innovations, each divided
   by its predicted 1σ (:func:`pronet.recorded.dvlnoise.lag_one`), with its 95 % band,
   and the forward (x) axis's with the IMU's q 20 and 100 times the estimate;
   beside it, without any filter, the DVL − truth residual along the body x axis split
   into its slow and fast parts (:func:`pronet.recorded.trutherror.residual_parts`);
2. R and the correlated error's 1σ fitted together at a correlation time τ
   (:func:`pronet.recorded.dvlnoise.match_correlated`), and the row run with them:
   velocity SRMSE, final horizontal error, mean NIS and the share of truth rows within
   3σ with the truth's error counted, forward and smoothed.

Printed as Markdown (docs/results/snapir-smoothed.md quotes it):

    python scripts/dvl_correlated.py [--data ../shared/data/snapir] [--time-constant 60]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import pronet
from pronet.recorded import alignment, real
from pronet.recorded.dvlnoise import (
    MatchedVariance,
    Variance,
    lag_one,
    match_correlated,
    match_innovations,
    second_difference_variance,
)
from pronet.recorded.dvltruth import truth_body_velocity
from pronet.recorded.passes import section_recorded, smoothed_run
from pronet.recorded.reading import stated_truth_error
from pronet.recorded.trutherror import residual_parts
from pronet.recorded.tuning import correlation_time, imu_step, real_filter_config
from pronet.results import markdown
from pronet.run import run


def axes(values: np.ndarray | Variance, digits: int = 2, sign: bool = True) -> str:
    """``x / y / z`` to ``digits`` decimals."""
    form = f"{{:{'+' if sign else ''}.{digits}f}}"
    return " / ".join(form.format(float(v)) for v in values)


#: The figures averaged over the sections, per row: SRMSE forward and smoothed [m/s],
#: final horizontal error [m], share within 3σ with the truth's error forward and smoothed.
Scores = tuple[float, float, float, float, float]


def scores(
    section: alignment.Section, strategy: pronet.Strategy, config: pronet.FilterConfig
) -> Scores:
    """The row run forward and smoothed on ``section``: its :data:`Scores`."""
    done = real.run_section(section, strategy, config, smooth=True)
    forward, smoothed = done.metrics, smoothed_run(section, done).metrics
    return (
        forward.srmse,
        smoothed.srmse,
        forward.final_horizontal,
        forward.velocity_3sigma_truth,
        smoothed.velocity_3sigma_truth,
    )


def section_rows(
    section: alignment.Section, tau: float
) -> tuple[list[str], list[str], Scores, Scores]:
    """One section's row of each table (the innovations' lag-one autocorrelations; the
    joint fit with the row run on it), and the :data:`Scores` of R from data alone and
    of the joint fit."""
    strategy = pronet.Strategy.constant(real.white_noise_q(section.imu))
    arm, dt = section.alignment.filter_lever_arm, imu_step(section.imu_time)
    step = float(np.median(np.diff(section.dvl_time)))

    def config(r: Variance | None, sigma: Variance | None = None) -> pronet.FilterConfig:
        fitted = None if sigma is None else (sigma, tau)
        return real_filter_config(arm, r, imu_dt=dt, correlated=fitted)

    def one_pass(r: Variance, sigma: Variance | None = None) -> pronet.FilterResult:
        return run(strategy, section_recorded(section, config(r, sigma), epochs="last")).result

    sheet = config(None).dvl_variance
    datasheet = one_pass((sheet[0], sheet[1], sheet[2]))
    white = match_innovations(one_pass, second_difference_variance(section.dvl))
    _, rho_sheet, band = lag_one(datasheet)
    _, rho_white, _ = lag_one(one_pass(white.variance))
    # the datasheet R with the IMU's q 20 and 100 times the estimate: the forward axis
    # then (the INS's own along-track error given room in the model)
    more_q = [
        lag_one(run(pronet.Strategy.constant([f * v for v in real.white_noise_q(section.imu)]),
                    section_recorded(section, config(None), epochs="last")).result)[1][0]
        for f in (20, 100)
    ]  # fmt: skip
    fit: MatchedVariance = match_correlated(one_pass, white, tau, step)
    rows, v_b = truth_body_velocity(section)  # the DVL against the truth, no filter
    residual = section.dvl[rows] - v_b
    own = residual_parts(residual[np.isfinite(residual).all(axis=1)])
    lags = [
        section.name,
        axes(rho_sheet),
        axes(rho_white),
        axes(np.array(more_q)),
        f"±{band:.2f}",
        f"{own.slow[0]:.4f} / {own.white[0]:.4f}",
    ]
    alone = scores(section, strategy, config(white.variance))
    both = scores(section, strategy, config(fit.variance, fit.correlated))
    state = f"{fit.passes}" + ("" if fit.converged else ", not converged")
    joint = [
        section.name,
        axes(np.sqrt(white.variance), 4, False),
        axes(np.sqrt(fit.variance), 4, False),
        "none" if fit.correlated is None else axes(fit.correlated, 4, False),
        state,
        f"{both[0]:.4f} / {both[1]:.4f}",
        f"{both[2]:.2f}",
        f"{both[3]:.3f} / {both[4]:.3f}",
    ]
    return lags, joint, alone, both


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/snapir"))
    parser.add_argument("--time-constant", type=float, default=None, help="τ [s]")
    args = parser.parse_args()
    tau = args.time_constant if args.time_constant is not None else correlation_time(None)
    lags: list[list[str]] = []
    joint: list[list[str]] = []
    means: list[tuple[Scores, Scores]] = []
    for aligned, _ in alignment.load_snapir_sections(args.data):
        a, b, alone, both = section_rows(stated_truth_error(aligned, "snapir"), tau)
        lags.append(a)
        joint.append(b)
        means.append((alone, both))
    print(
        markdown(
            [
                "section",
                "datasheet R",
                "R from data",
                "x, datasheet R, 20 × / 100 × q",
                "95 % band",
                "DVL − truth along x, slow / fast [m/s]",
            ],
            lags,
            "DVL innovations' lag-one autocorrelation per body axis x / y / z "
            "(constant (estimated q) row)",
        )
    )
    print()
    header = [
        "section",
        "white R alone, 1σ [m/s]",
        "white R with it, 1σ [m/s]",
        f"correlated error 1σ [m/s] (τ {tau:g} s)",
        "passes (the white fit's with them)",
        "SRMSE [m/s] fwd / smoothed",
        "final horiz. [m]",
        "within 3σ, truth's error incl., fwd / smoothed",
    ]
    print(markdown(header, joint, "R and the correlated DVL error fitted together"))
    print()
    mean = np.mean(np.array(means), axis=0)
    summary = [
        [label, f"{m[0]:.4f} / {m[1]:.4f}", f"{m[2]:.2f}", f"{m[3]:.3f} / {m[4]:.3f}"]
        for label, m in zip(
            ("R from data (white)", "R and the correlated error"), mean, strict=True
        )
    ]
    head = ["row", "SRMSE [m/s] fwd / smoothed", "final horiz. [m]", "within 3σ, fwd / smoothed"]
    print(markdown(head, summary, "Mean over the sections (truth's error included)"))


if __name__ == "__main__":
    main()
