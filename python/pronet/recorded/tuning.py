"""The filter tuning of recorded sections and the rows ``pronet real`` runs on them:
the initial 1σ, bias walks and DVL noise of a FOG INS started from its post-processed
solution (:func:`real_filter_config`), the IMU noise q of a section
(:func:`white_noise_q`), the strategy rows (:func:`real_strategies`) and the labels of
the variant rows (the DVL noise from the data, the DVL calibration states, both).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.validate import float_array
from pronet.recorded.dvlnoise import DVL_NOISE_SOURCES
from pronet.sim.paper import paper_strategies
from pronet.strategies import StrategyLike, StrategySpec, strategy

if TYPE_CHECKING:  # torch loads only when a net is trained or run through torch
    from pronet.learn.models import Regressor

F64 = NDArray[np.float64]


#: Initial 1σ of a run started from the post-processed ground truth: position 0.1 m,
#: velocity 0.02 m/s, roll and pitch 2e-4 rad (0.01°), yaw 1e-3 rad (0.06°) — the
#: accuracy class of a post-processed FOG INS solution — then the biases: accelerometer
#: 5e-4 m/s² (50 µg) and gyro 1e-6 rad/s (0.2°/h), a navigation-grade FOG IMU's
#: turn-on biases.
REAL_P0_SIGMA = (0.1,) * 3 + (0.02,) * 3 + (2e-4, 2e-4, 1e-3) + (5e-4,) * 3 + (1e-6,) * 3
#: Bias random-walk PSDs: accelerometer 1e-9 (m/s²)²/s and gyro 1e-14 (rad/s)²/s, i.e.
#: 6e-4 m/s² and 2e-6 rad/s (0.4°/h) of drift over a 400 s section: FOG-grade.
REAL_ACCEL_BIAS_PSD = 1e-9
REAL_GYRO_BIAS_PSD = 1e-14
#: DVL velocity variance: (0.02 m/s)², the Workhorse Navigator's specified 1σ.
REAL_DVL_VARIANCE = 0.02**2

#: Table labels of the real-data rows (q is estimated, not true).
REAL_LABELS = {
    "constant (true q)": "constant (estimated q)",
    "constant (20 x q)": "constant (20 x estimated q)",
}


def check_dvl_noise(source: str) -> None:
    """ValueError naming ``--dvl-noise`` unless ``source`` is one of
    :data:`pronet.recorded.dvlnoise.DVL_NOISE_SOURCES`."""
    if source not in DVL_NOISE_SOURCES:
        choices = ", ".join(DVL_NOISE_SOURCES)
        raise ValueError(f"--dvl-noise: must be one of {choices}, got {source!r}")


def real_filter_config(
    lever_arm: tuple[float, float, float],
    dvl_variance: tuple[float, float, float] | None = None,
    calibration: bool = False,
    formulation: str | None = None,
    covariance_step: float = 0.0,
) -> _core.FilterConfig:
    """The filter tuning used on recorded sections, with the DVL ``lever_arm`` from the
    IMU [m, body FRD], the DVL noise ``dvl_variance`` per body axis [(m/s)²] (default:
    the datasheet's, :data:`REAL_DVL_VARIANCE`), with ``calibration`` the DVL
    scale-factor and misalignment states (their default prior: 1 %, 1° per axis), and
    the filter's ``formulation`` (default ``FilterConfig``'s, the invariant one) and
    ``covariance_step`` [s] (0: every IMU sample); see :data:`REAL_P0_SIGMA` and the
    PSD constants for sources."""
    chosen = {} if formulation is None else {"formulation": formulation}
    return _core.FilterConfig(
        **chosen,  # type: ignore[arg-type]
        p0_sigma=REAL_P0_SIGMA,
        accel_bias_psd=REAL_ACCEL_BIAS_PSD,
        gyro_bias_psd=REAL_GYRO_BIAS_PSD,
        dvl_variance=(REAL_DVL_VARIANCE,) * 3 if dvl_variance is None else dvl_variance,
        lever_arm=lever_arm,
        dvl_calibration=calibration,
        covariance_step=covariance_step,
    )


def white_noise_q(imu: F64) -> tuple[float, ...]:
    """Per-sample white-noise variance of each IMU channel, ``var(first differences)/2``
    [(m/s²)², (rad/s)²]: differencing removes the slowly varying motion and bias, and
    doubles the white noise's variance. On a moving vehicle it includes vibration."""
    samples = float_array(imu, "imu", (None, 6))
    if len(samples) < 2:
        raise ValueError(f"imu: needs at least two samples, got {len(samples)}")
    return tuple(float(v) for v in np.var(np.diff(samples, axis=0), axis=0) / 2)


#: The study's estimators beside the paper's rows on recorded data, by label: their specs
#: (:class:`~pronet.strategies.StrategySpec`); the oracle has no place here (no truth q).
REAL_EXTRA_ROWS = {
    "detvar": "detvar",
    "adaptive": "adaptive",
    "HCF-ensemble (grades)": "learned:hcf",
    "baseline net (grades)": "learned:baseline",
    "detrend net (grades)": "learned:detrend",
}


#: Rows beside the strategies: the first strategy (constant, estimated q) under another
#: filter tuning, by label: the DVL noise R from the recording instead of the
#: datasheet's, the DVL calibration states, and both (R matched with the states on).
R_FROM_DATA = "constant (estimated q), R from data"
DVL_CALIBRATION = "constant (estimated q), DVL calibration"
BOTH = "constant (estimated q), R from data, DVL calibration"
REAL_VARIANT_ROWS = (R_FROM_DATA, DVL_CALIBRATION, BOTH)


def real_strategies(
    q: tuple[float, ...], models: Mapping[str, Regressor], tuning_period: float
) -> dict[str, StrategyLike]:
    """The paper's seven rows around the estimated ``q`` (relabelled for real data), then
    :data:`REAL_EXTRA_ROWS`; learned rows only for the regressors in ``models`` (by
    shipped name)."""
    rows = paper_strategies(q, dict(models), tuning_period)
    out = {REAL_LABELS.get(label, label): s for label, s in rows.items()}
    for label, text in REAL_EXTRA_ROWS.items():
        spec = StrategySpec.parse(text)
        if spec.kind == "learned" and spec.model not in models:
            continue  # as the paper's learned rows: only with the models given
        out[label] = strategy(spec, q, tuning_period, models.get(spec.model))
    return out
