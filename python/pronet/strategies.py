"""Process-noise strategies named in text, and the learned wrapper.

A strategy decides the filter's IMU process noise q (six per-sample variances
[(m/s²)², (rad/s)²], see ``docs/reference/concepts.md``). Native strategies (constant, Mehra,
adaptive, oracle) run entirely in the Rust core as a :class:`pronet._core.Strategy`; a
:class:`Learned` one runs a regressor in Python every tuning period (the hybrid loop;
``detvar`` is the detrended-variance estimator in that loop). :func:`strategy` turns a
:class:`StrategySpec` into either.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pronet import _core
from pronet._util.validate import float_array
from pronet.learn.hybrid import DEFAULT_TUNING_PERIOD
from pronet.learn.windowstats import DetrendedVariance

if TYPE_CHECKING:  # torch loads only when a model does
    from pronet.learn.models import Regressor


@dataclass(frozen=True, repr=False)
class Learned:
    """A regressor-driven row: the hybrid loop with ``regressor`` (prior ``prior_q``
    until the first window is full)."""

    regressor: Regressor
    prior_q: tuple[float, ...]
    tuning_period: float = DEFAULT_TUNING_PERIOD

    def __repr__(self) -> str:
        """Stable, as result files need it (identical runs write identical files): the
        regressor's kind and its weights' SHA-256 where its card has them, never the
        object's address."""
        card = getattr(self.regressor, "card", None) or {}
        name = card.get("kind") or type(self.regressor).__name__
        sha = card.get("weights_sha256")
        weights = f", weights sha256 {sha[:16]}" if isinstance(sha, str) else ""
        prior = ", ".join(repr(float(v)) for v in self.prior_q)
        period = float(self.tuning_period)
        return f"Learned({name}{weights}, prior_q=[{prior}], tuning_period={period!r} s)"


StrategyLike = _core.Strategy | Learned

#: Default window of the ``adaptive`` strategy [DVL updates]: one minute at 1 Hz, the
#: time scale over which the simulated noise regimes hold (30–90 s).
ADAPTIVE_WINDOW = 60


@dataclass(frozen=True)
class StrategySpec:
    """A strategy named in text, as configs and the command line give it:

    - ``constant`` or ``constant:S``: constant Q, the scenario's nominal q times S
      (default 1);
    - ``oracle``: the simulated IMU's true variance at every step (simulation only);
    - ``adaptive`` or ``adaptive:W``: robust covariance matching of a scale on the
      nominal q over W DVL updates (default :data:`ADAPTIVE_WINDOW`);
    - ``mehra:W``: Mehra's innovation-adaptive Q over a window of W DVL updates;
    - ``detvar`` (also ``learned:detvar``): the detrended-variance estimator on the
      learned rows' windows and instants; needs no torch;
    - ``learned:MODEL``: the hybrid loop with a regressor: a shipped model name
      (``baseline``, ``detrend``, ``hcf``) or the path of a model file; a
      section-scale model (:class:`pronet.learn.qmodels.SectionScale`) is a constant
      over the run, the nominal q times its group scales, run natively.

    Attributes:
        text: the spec as written (the row label in simulations and sweeps).
        kind: ``"constant"``, ``"oracle"``, ``"adaptive"``, ``"mehra"``, ``"detvar"``
            or ``"learned"``.
        factor: constant: the factor on q; adaptive, mehra: the window; otherwise 0.
        model: learned: the model name or path; otherwise ``""``.
    """

    text: str
    kind: str
    factor: float = 0.0
    model: str = ""

    @classmethod
    def parse(cls, text: object) -> StrategySpec:
        """The spec in ``text``, or ``ValueError`` saying what is wrong with it."""
        if not isinstance(text, str):
            raise ValueError(f"strategy: expected text such as 'mehra:5', got {text!r}")
        kind, colon, arg = text.strip().partition(":")
        arg = arg.strip()
        if colon and not arg and kind in ("constant", "adaptive", "oracle", "detvar"):
            raise ValueError(f"strategy {text!r}: nothing after ':'; write {kind!r} without it")
        if kind == "constant":
            factor = _spec_number(arg, text) if arg else 1.0
            if not 0 < factor < math.inf:
                raise ValueError(f"strategy {text!r}: the factor on q must be finite and > 0")
            return cls(text, kind, factor)
        if kind == "adaptive" and not arg:
            return cls(text, kind, float(ADAPTIVE_WINDOW))
        if kind in ("mehra", "adaptive"):
            if not arg.isdigit() or int(arg) < 1:
                what = "" if arg.isdigit() else f" (a whole number, not {arg!r})"
                raise ValueError(
                    f"strategy {text!r}: {kind} needs a window >= 1 [DVL updates]{what}, "
                    f"e.g. {kind}:5"
                )
            return cls(text, kind, float(int(arg)))
        if kind in ("oracle", "detvar"):
            if arg:
                raise ValueError(f"strategy {text!r}: {kind} takes no argument")
            return cls(text, kind)
        if kind == "learned":
            if not arg:
                raise ValueError(f"strategy {text!r}: learned needs a model, e.g. learned:detrend")
            if arg == "detvar":  # the statistical estimator, not a model file
                return cls(text, "detvar")
            return cls(text, kind, model=arg)
        raise ValueError(
            f"strategy {text!r}: expected constant[:S], oracle, adaptive[:W], mehra:W, "
            "detvar or learned:MODEL"
        )

    @property
    def uses_tuning_period(self) -> bool:
        """Whether the tuning period changes this strategy (the hybrid loop's: learned
        and detvar)."""
        return self.kind in ("learned", "detvar")


def check_distinct(specs: Sequence[StrategySpec], where: str = "strategies") -> None:
    """``ValueError`` naming ``where`` when two of ``specs`` run the same strategy under
    different texts (``constant`` and ``constant:1``, ``detvar`` and ``learned:detvar``):
    two rows, one strategy."""
    seen: dict[tuple[str, float, str], str] = {}
    for spec in specs:
        same = seen.setdefault((spec.kind, spec.factor, spec.model), spec.text)
        if same != spec.text:
            raise ValueError(f"{where}: {same!r} and {spec.text!r} are the same strategy")


def _spec_number(text: str, spec: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"strategy {spec!r}: {text!r} is not a number") from None


def strategy(
    spec: StrategySpec,
    q: tuple[float, ...],
    tuning_period: float = DEFAULT_TUNING_PERIOD,
    regressor: Regressor | None = None,
) -> StrategyLike:
    """The strategy ``spec`` describes around the nominal ``q`` (6 per-sample
    variances [(m/s²)², (rad/s)²]); a learned one runs ``regressor`` (default:
    ``frozen.load_frozen(spec.model)``, the model frozen in the core) every
    ``tuning_period`` seconds."""
    q = tuple(float(v) for v in float_array(q, "q", (6,)))  # factor x q in float64
    if spec.kind == "constant":
        return _core.Strategy.constant(q if spec.factor == 1 else tuple(spec.factor * v for v in q))
    if spec.kind == "mehra":
        return _core.Strategy.mehra(int(spec.factor), q)
    if spec.kind == "adaptive":
        return _core.Strategy.adaptive(int(spec.factor), q)
    if spec.kind == "oracle":
        return _core.Strategy.oracle()
    if spec.kind == "detvar":
        return Learned(DetrendedVariance() if regressor is None else regressor, q, tuning_period)
    if regressor is None:  # frozen in the core: no torch
        from pronet.learn.qmodels import load_model_file

        regressor = load_model_file(spec.model)
    section_q = getattr(regressor, "q_for", None)
    if callable(section_q):  # a constant over the section (SectionScale): native
        return _core.Strategy.constant(section_q(q))
    return Learned(regressor, q, tuning_period)
