"""The filter tuning of recorded sections and the rows ``pronet real`` runs on them:
the initial 1σ, bias walks and DVL noise of a FOG INS started from its post-processed
solution (:func:`real_filter_config`), the IMU noise q of a section
(:func:`white_noise_q`), the strategy rows (:func:`real_strategies`) and the labels of
the variant rows (the DVL noise from the data, the DVL calibration states, both).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.validate import float_array
from pronet.config import FILTER_KEYS
from pronet.recorded.dvlnoise import DVL_NOISE_SOURCES
from pronet.recorded.plausible import NOMINAL_RATE_TOLERANCE
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
    imu_dt: float | None = None,
    base: _core.FilterConfig | None = None,
    covariance_step: float | None = None,
    correlated: tuple[tuple[float, float, float], float] | None = None,
) -> _core.FilterConfig:
    """The filter tuning used on recorded sections, with the DVL ``lever_arm`` from the
    IMU [m, body FRD], the DVL noise ``dvl_variance`` per body axis [(m/s)²] (default:
    the datasheet's, :data:`REAL_DVL_VARIANCE`), with ``calibration`` the DVL
    scale-factor and misalignment states (their default prior: 1 %, 1° per axis), the
    filter's ``formulation`` (default ``FilterConfig``'s, the invariant one), the
    IMU's nominal step ``imu_dt`` [s] (:func:`imu_step`; default ``FilterConfig``'s
    0.01 s) and ``covariance_step`` [s] (default ``FilterConfig``'s, 0.1 s; 0: every
    IMU sample); see :data:`REAL_P0_SIGMA` and the PSD constants for sources.

    ``base`` (a vehicle's own tuning, ``pronet real --filter``): every key of a filter
    file (:data:`pronet.config.FILTER_KEYS`: its P0, bias PSDs, DVL noise unless
    ``dvl_variance`` is given, aiding, innovation gate, the DVL's correlated error,
    formulation and covariance step unless ``formulation`` or ``covariance_step`` is
    given, the second-order heading term but beside ``calibration``, whose states do not
    take it) instead of the FOG defaults above. ``correlated = (σ, τ)``: the DVL's
    correlated error fitted from the data (:func:`pronet.recorded.dvlnoise.match_correlated`,
    1σ per body axis [m/s], correlation time [s]) instead of ``base``'s; its states, as
    the calibration's, do not take the second-order heading term."""
    given = {
        key: value
        for key, value in (
            ("dvl_variance", dvl_variance),
            ("imu_dt", imu_dt),
            ("formulation", formulation),
            ("covariance_step", covariance_step),
        )
        if value is not None
    }
    own: dict[str, Any] = (
        {key: getattr(base, key) for key in FILTER_KEYS}
        if base is not None
        else {
            "p0_sigma": REAL_P0_SIGMA,
            "accel_bias_psd": REAL_ACCEL_BIAS_PSD,
            "gyro_bias_psd": REAL_GYRO_BIAS_PSD,
            "dvl_variance": (REAL_DVL_VARIANCE,) * 3,
        }
    )
    own.update(given, lever_arm=lever_arm, dvl_calibration=calibration)
    if correlated is not None:
        own.update(dvl_bias_sigma=correlated[0], dvl_bias_time_constant=correlated[1])
    if calibration or correlated is not None:  # FilterConfig refuses both with the term
        own["heading_second_order"] = False
    return _core.FilterConfig(**own)


def correlation_time(base: _core.FilterConfig | None) -> float:
    """The correlation time [s] at which to fit the DVL's correlated error from the data
    (:func:`pronet.recorded.dvlnoise.match_correlated`, ``scripts/dvl_correlated.py``;
    ``pronet real`` does not): ``base``'s (a vehicle file's ``dvl_bias_time_constant``),
    else the filter's default (read from the core, which owns it)."""
    own = None if base is None else base.dvl_bias_time_constant
    if own is not None:
        return own
    default = _core.FilterConfig(dvl_bias_sigma=(1.0, 1.0, 1.0)).dvl_bias_time_constant
    assert default is not None  # set whenever the states are
    return default


def imu_step(imu_time: F64) -> float:
    """The IMU's nominal step [s] for the filter's white-noise term: the mean step of
    ``imu_time``, at the whole rate in Hz it is within
    :data:`~pronet.recorded.plausible.NOMINAL_RATE_TOLERANCE` of (a logger's clock
    drift aside: the Snapir IMU's stamps step by 0.01000025 s, its rate 100 Hz). The
    filter adds ``q · imu_dt · dt`` per step with each step's own
    ``dt`` from the stamps: ``q · imu_dt`` is the noise PSD of ``q`` per sample of
    ``imu_dt``, and a jittered IMU is integrated exactly over each of its steps, not
    resampled."""
    t = float_array(imu_time, "imu_time", (None,))
    if len(t) < 2:
        raise ValueError(f"imu_time: needs at least two samples, got {len(t)}")
    if not (np.diff(t) > 0).all():
        raise ValueError("imu_time: must increase strictly")
    step = (t[-1] - t[0]) / (len(t) - 1)  # the mean: a jitter averages out
    rate = 1.0 / step
    whole = round(rate)
    if whole >= 1 and abs(rate - whole) <= NOMINAL_RATE_TOLERANCE * rate:
        return 1.0 / whole
    return step


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
    shipped name), and a row ``learned:PATH`` for each model keyed so (a user's model
    file, ``pronet real --model PATH``)."""
    rows = paper_strategies(q, dict(models), tuning_period)
    out = {REAL_LABELS.get(label, label): s for label, s in rows.items()}
    for label, text in REAL_EXTRA_ROWS.items():
        spec = StrategySpec.parse(text)
        if spec.kind == "learned" and spec.model not in models:
            continue  # as the paper's learned rows: only with the models given
        out[label] = strategy(spec, q, tuning_period, models.get(spec.model))
    for key, model in models.items():  # model files given by path: "learned:PATH"
        if key.startswith("learned:"):
            out[key] = strategy(StrategySpec.parse(key), q, tuning_period, model)
    return out
