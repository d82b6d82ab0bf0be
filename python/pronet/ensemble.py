"""All runs of a Monte Carlo stepped in lockstep, for a q estimator of your own.

:class:`Ensemble` takes the arguments of :func:`pronet.monte_carlo` (an initial q in
place of the strategy, and the window and tuning period of the loop) and its
:meth:`~Ensemble.finish` returns the same :class:`~pronet.MonteCarloResult`. The runs
live in the native core (:class:`pronet._core.Ensemble`); this class converts the
arguments and the result.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import check_type, float_array
from pronet.montecarlo import MonteCarloResult

#: Default window of raw IMU samples handed out at each tuning instant (the paper's N)
#: and time between tuning instants [s]; :mod:`pronet.learn.hybrid` explains them.
DEFAULT_WINDOW = 200
DEFAULT_TUNING_PERIOD = 1.0


class Ensemble:
    """``n_runs`` simulated runs along ``trajectory``, filtered in lockstep, their IMU
    variances set from outside at every tuning instant.

    Loop: ``windows = ens.advance()`` steps every run to the next tuning instant
    (:func:`pronet._core.tuning_instants`) and returns the last ``window`` raw IMU
    samples of every run, float32 ``(n_runs, 6, window)`` oldest first (body FRD,
    ``[f (m/s²), ω (rad/s)]``), or None at the end; ``ens.set_q(q)`` sets each run's
    per-sample IMU variances ``q (n_runs, 6)`` [(m/s²)², (rad/s)²] until the next
    setting; ``ens.finish()`` runs to the end and returns the
    :class:`~pronet.MonteCarloResult`. Until the first ``set_q`` every run uses
    ``prior_q``. Run i draws its noise as run i of :func:`pronet.monte_carlo` with the
    same seed does (common random numbers), so the two compare pairwise.

    Args:
        trajectory: truth and ideal IMU (e.g. ``builtin_trajectory("paper")``).
        prior_q: 6 per-sample IMU variances [(m/s²)², (rad/s)²] in force until the first
            ``set_q``.
        sensors, config, n_runs, seed, record_every, sample_initial_error, threads,
            first_run: as for :func:`pronet.monte_carlo` (same defaults).
        window: IMU samples per window handed out, 1 to the trajectory's length.
        tuning_period: time between tuning instants [s], > 0.

    ``advance`` and ``finish`` end within a fraction of a second on Ctrl-C or SIGTERM
    (``KeyboardInterrupt``); the ensemble is then unusable (``ValueError``), as it is
    after ``finish``.
    """

    def __init__(
        self,
        trajectory: _core.Trajectory,
        prior_q: ArrayLike,
        *,
        sensors: _core.SensorConfig | None = None,
        config: _core.FilterConfig | None = None,
        n_runs: int = 100,
        seed: int = 0,
        window: int = DEFAULT_WINDOW,
        tuning_period: float = DEFAULT_TUNING_PERIOD,
        record_every: int = 0,
        sample_initial_error: bool = True,
        threads: int | None = None,
        first_run: int = 0,
    ) -> None:
        check_type(trajectory, _core.Trajectory, "trajectory")
        sensors = sensors if sensors is not None else _core.SensorConfig()
        config = config if config is not None else _core.FilterConfig()
        check_type(sensors, _core.SensorConfig, "sensors")
        check_type(config, _core.FilterConfig, "config")
        # The native core checks the counts, the seed, the window, the tuning period and
        # the thread count, naming each.
        self._native = _core.Ensemble(
            trajectory,
            sensors,
            config,
            prior_q,  # 6 finite real numbers of any sequence, checked by the core
            n_runs=n_runs,
            seed=seed,
            window=window,
            tuning_period=tuning_period,
            record_every=record_every,
            sample_initial_error=sample_initial_error,
            threads=threads,
            first_run=first_run,
        )

    def advance(self) -> NDArray[np.float32] | None:
        """Step all runs to the next tuning instant; the windows float32
        ``(n_runs, 6, window)``, oldest sample first, or None at the end."""
        return self._native.advance()

    def set_q(self, q: ArrayLike) -> None:
        """Set each run's per-sample IMU variances: ``q`` ``(n_runs, 6)``
        [(m/s²)², (rad/s)²], finite and >= 0."""
        self._native.set_q(float_array(q, "q", (None, 6)))

    def finish(self) -> MonteCarloResult:
        """Run to the end; the result as :func:`pronet.monte_carlo` returns it. The
        ensemble cannot be used afterwards."""
        return MonteCarloResult(**self._native.finish())

    @property
    def n_runs(self) -> int:
        return self._native.n_runs

    @property
    def window(self) -> int:
        """IMU samples per window."""
        return self._native.window

    @property
    def steps(self) -> int:
        """IMU steps taken so far."""
        return self._native.steps

    @property
    def time(self) -> float:
        """Current time [s]."""
        return self._native.time

    @property
    def done(self) -> bool:
        """Whether every run reached the end (or the ensemble finished)."""
        return self._native.done
