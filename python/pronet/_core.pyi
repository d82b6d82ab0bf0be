"""Type stubs for the native core ``pronet._core`` (Rust, pyo3).

Conventions: NED navigation frame, FRD body frame; positions ``[lat rad, lon rad, h m]``
(height positive up); attitude roll, pitch, yaw (ZYX) in rad; IMU rows
``[f_x, f_y, f_z, w_x, w_y, w_z]`` in m/s² and rad/s. q is the per-sample variance of an
IMU channel. Array arguments take real numbers in any form alike: NumPy arrays of any
integer or float dtype and layout, nested lists and tuples (booleans, complex numbers,
strings and objects are refused). Every error raises ``ValueError`` starting with the
argument's name.
Heavy calls release the GIL.
"""

from collections.abc import Sequence
from typing import Any, Literal, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "__version__", "MAX_THREADS", "THREADS_PER_CORE", "THREADS_ENV", "MAX_LEVER_ARM",
    "MAX_COVARIANCE_STEP", "MAX_LINEAR_HEADING_SIGMA_DEG", "MAX_SPEED",
    "MAX_ABS_HEIGHT", "MAX_POSITION_SIGMA", "MAX_RUN_INDEX", "MAX_IMU_GAP",
    "MAX_GRAVITY_HEIGHT", "MAX_LATITUDE_DEG", "LONGITUDE_RANGE_DEG", "WGS84_A",
    "WGS84_F", "Trajectory", "builtin_trajectory", "builtin_trajectory_names",
    "trajectory_from_segments", "normal_gravity", "earth_radii", "mechanize",
    "FilterConfig", "Strategy", "SensorConfig", "Dvl", "Depth", "Fix", "Heading",
    "run_filter", "monte_carlo", "check_result_size", "check_fixes_fire",
    "check_threads", "max_threads", "Ensemble", "tuning_instants", "Navigator",
    "ConvNet", "HcfEnsemble", "attitude_increment_costs"]  # fmt: skip

#: The package version (the crate's, from ``Cargo.toml``).
__version__: str
#: Most worker threads a pool may have on any machine (``threads::MAX_THREADS``).
MAX_THREADS: int
#: Most worker threads per core this process may use (``threads::THREADS_PER_CORE``):
#: a pool has 1 to :func:`max_threads` threads.
THREADS_PER_CORE: int
#: The environment variable that sets the thread count of calls given none,
#: ``"RAYON_NUM_THREADS"`` (checked as an explicit count is).
THREADS_ENV: str
#: Longest lever arm component [m] a sensor may have (``sensors::MAX_LEVER_ARM``, 1 km).
MAX_LEVER_ARM: float
#: Longest covariance step [s] (``ekf::MAX_COVARIANCE_STEP``, 1 s): its approximation of
#: the error process is measured up to 0.5 s (``docs/results/covariance-step.md``).
MAX_COVARIANCE_STEP: float
#: The heading 1σ [°] past which a pass says its heading error is no longer small
#: (``pass::MAX_LINEAR_HEADING_SIGMA_DEG``, 5°; :func:`pronet.stats.heading_linearity`).
MAX_LINEAR_HEADING_SIGMA_DEG: float
#: A speed [m/s] past which a pass says it diverged (``pass::MAX_SPEED``).
MAX_SPEED: float
#: A height [m] beyond which (±) a pass says it diverged (``pass::MAX_ABS_HEIGHT``).
MAX_ABS_HEIGHT: float
#: A horizontal 1σ [m] past which a pass says it diverged (``pass::MAX_POSITION_SIGMA``).
MAX_POSITION_SIGMA: float
#: An IMU step longer than this many usual ones is a gap (``online::MAX_IMU_GAP``, 5).
MAX_IMU_GAP: float
#: One past the largest run index, 2^62 (``montecarlo::MAX_RUN_INDEX``; streams 4·i + k).
MAX_RUN_INDEX: int
#: Heights [m] within which :func:`normal_gravity` answers (``earth::MAX_GRAVITY_HEIGHT``).
MAX_GRAVITY_HEIGHT: float
#: Largest |latitude| [°] a navigation state may start at (``earth::MAX_LATITUDE_DEG``).
MAX_LATITUDE_DEG: float
#: The longitudes [°] a position fix may be given in, ``(-180.0, 360.0)``: the ±180°
#: and the 0–360° conventions (``earth::LONGITUDE_RANGE_DEG``; the fix update wraps the
#: longitude difference into (−π, π]).
LONGITUDE_RANGE_DEG: tuple[float, float]
#: WGS-84 semi-major axis [m] (``earth::A``).
WGS84_A: float
#: WGS-84 flattening (``earth::F``).
WGS84_F: float

@final
class Trajectory:
    """Truth of a trajectory at n + 1 epochs and the ideal IMU over the n intervals."""

    @property
    def name(self) -> str: ...
    @property
    def dt(self) -> float:
        """Sample period [s]."""
    @property
    def duration(self) -> float:
        """Length [s]."""
    @property
    def n_samples(self) -> int:
        """Number of IMU samples n."""
    @property
    def time(self) -> NDArray[np.float64]:
        """``(n+1,)`` epoch times [s], starting at 0."""
    @property
    def lla(self) -> NDArray[np.float64]:
        """``(n+1, 3)`` latitude, longitude [rad], height [m]."""
    @property
    def vel_ned(self) -> NDArray[np.float64]:
        """``(n+1, 3)`` NED velocity [m/s]."""
    @property
    def rpy(self) -> NDArray[np.float64]:
        """``(n+1, 3)`` roll, pitch, yaw [rad]."""
    @property
    def imu(self) -> NDArray[np.float64]:
        """``(n, 6)`` ideal IMU; row k covers ``(time[k], time[k+1]]``."""
    @property
    def segments(self) -> NDArray[np.float64]:
        """``(k, 4)`` rows ``[duration s, accel m/s², yaw_rate rad/s, pitch_rate rad/s]``."""
    @property
    def speed0(self) -> float:
        """Initial forward speed [m/s]."""

def builtin_trajectory(name: str, dt: float = 0.01) -> Trajectory: ...
def builtin_trajectory_names() -> list[str]:
    """Names of the built-in trajectories (see :func:`pronet.builtin_trajectory`)."""

def trajectory_from_segments(
    segments: ArrayLike,
    *,
    lla0: Any,
    speed0: float,
    rpy0: Any | None = None,
    dt: float = 0.01,
    name: str = "custom",
) -> Trajectory: ...
def normal_gravity(lat: float, h: float = 0.0) -> float:
    """WGS-84 normal gravity [m/s²] at latitude [rad] and height [m], |h| <= 100 km (a
    near-surface model; ValueError beyond)."""

def earth_radii(lat: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature [m]."""

def mechanize(
    imu: ArrayLike, dt: float, lla0: Any, vel0: Any, rpy0: Any
) -> dict[str, NDArray[np.float64]]:
    """Strapdown integration; keys ``lla``, ``vel``, ``rpy``, each ``(n+1, 3)``. Finite
    IMU rows, ``dt`` > 0, ``|lla0[0]|`` <= 89°; an overflow to non-finite states is a
    ValueError naming ``imu, dt, lla0, vel0``, more states than this process can still
    take one naming ``imu`` (docs/results/performance.md, "Memory")."""

@final
class FilterConfig:
    """EKF tuning: initial 1σ (15), bias random-walk PSDs ε_a [(m/s²)²/s] and ε_g
    [(rad/s)²/s], DVL variance R [(m/s)²], DVL lever arm [m, body], aiding ("body" velocity
    or "nav" NED velocity), nominal IMU period [s], the χ² innovation gate (a DVL update
    whose NIS exceeds it is rejected; None: no gate); opt-in DVL calibration states
    (``dvl_calibration=True``, body aiding): scale-factor error and misalignment, initial
    1σ (default 0.01, 1° per axis [rad]) and random-walk PSDs [1/s, rad²/s] (default 0);
    an opt-in correlated DVL velocity error (``dvl_bias_sigma``, stationary 1σ per DVL axis
    [m/s], body aiding; Gauss–Markov, correlation time ``dvl_bias_time_constant`` [s],
    default 60), three more states; the formulation, the velocity error's coordinates:
    "invariant" (default, ``δV = δv − [v̂×]ψ``, consistent in heading), "classic" (``δv``)
    or "se23" (the prior and every output in the classic ones either way); the covariance
    step [s] over which P is propagated at once (the navigation at every IMU sample),
    0.1 s by default (``docs/results/covariance-step.md``); 0 or under 1.5 IMU periods:
    every sample; longer ones rounded to whole IMU periods (at most
    :data:`MAX_COVARIANCE_STEP`), P brought up to date before every update and at a pass's
    end; ``heading_second_order=True``: P carries the second-order heading term of the
    position error, ``¾ u uᵀ`` (not with "se23" nor the DVL error states). See
    ``docs/reference/filter.md``."""

    def __new__(cls, *, p0_sigma: Any | None = None, accel_bias_psd: float = 1e-3,
                gyro_bias_psd: float = 1e-3, dvl_variance: Any | None = None,
                lever_arm: Any | None = None, aiding: Literal["body", "nav"] = "body",
                imu_dt: float = 0.01, innovation_gate: float | None = None,
                dvl_calibration: bool = False, dvl_scale_sigma: float | None = None,
                dvl_misalignment_sigma: Any | None = None, dvl_scale_psd: float | None = None,
                dvl_misalignment_psd: float | None = None, dvl_bias_sigma: Any | None = None,
                dvl_bias_time_constant: float | None = None,
                formulation: Literal["invariant", "classic", "se23"] = "invariant",
                covariance_step: float = 0.1,
                heading_second_order: bool = False) -> FilterConfig: ...  # fmt: skip
    @property
    def p0_sigma(self) -> list[float]: ...
    @property
    def accel_bias_psd(self) -> float: ...
    @property
    def gyro_bias_psd(self) -> float: ...
    @property
    def dvl_variance(self) -> list[float]: ...
    @property
    def lever_arm(self) -> list[float]: ...
    @property
    def aiding(self) -> str: ...
    @property
    def heading_second_order(self) -> bool:
        """Whether the second-order heading term of the position error is carried."""
    @property
    def imu_dt(self) -> float: ...
    @property
    def innovation_gate(self) -> float | None: ...
    @property
    def dvl_calibration(self) -> bool:
        """Whether the DVL scale-factor and misalignment states are estimated."""
    @property
    def dvl_bias_sigma(self) -> list[float] | None:
        """Stationary 1σ per DVL axis of its correlated velocity error [m/s], or None."""
    @property
    def dvl_bias_time_constant(self) -> float | None:
        """Its correlation time [s] (None without it)."""
    @property
    def dvl_scale_sigma(self) -> float | None:
        """Initial 1σ of the DVL scale-factor error (None without the calibration states)."""
    @property
    def dvl_misalignment_sigma(self) -> list[float] | None:
        """Initial 1σ of the DVL misalignment about body x, y, z [rad] (None without them)."""
    @property
    def dvl_scale_psd(self) -> float | None:
        """Random-walk PSD of the DVL scale factor [1/s] (None without the states)."""
    @property
    def dvl_misalignment_psd(self) -> float | None:
        """Random-walk PSD of each misalignment angle [rad²/s] (None without the states)."""
    @property
    def formulation(self) -> Literal["invariant", "classic", "se23"]:
        """The error coordinates: "invariant", "classic" or "se23" (``reference/filter.md``)."""
    @property
    def covariance_step(self) -> float:
        """The covariance step [s] (0: the covariance propagated at every IMU sample)."""

@final
class Strategy:
    """Process-noise strategy: constant Q^c, Mehra innovation-adaptive (window ξ),
    robust adaptive (covariance matching of a scale on q), the oracle (the simulated
    IMU's true variance), or external (q set by the caller through an :class:`Ensemble`)."""

    @staticmethod
    def constant(q: Any) -> Strategy:
        """Constant Q^c from 6 per-sample IMU variances q [(m/s²)², (rad/s)²]."""
    @staticmethod
    def mehra(window: int, prior_q: Any) -> Strategy:
        """Mehra's innovation-adaptive Q over the last ``window`` DVL innovations
        (``window`` >= 1); constant ``prior_q`` until that many exist."""
    @staticmethod
    def adaptive(window: int, prior_q: Any) -> Strategy:
        """q = λ·prior_q with the scale λ estimated by matching the DVL innovations'
        NIS over an exponentially forgetting window of ``window`` updates (>= 1);
        structure and full rank kept, λ in [1e-3, 1e3]. See ``docs/reference/filter.md``."""
    @staticmethod
    def oracle() -> Strategy:
        """The simulated IMU's true variance at every IMU step (the ceiling; simulation only)."""
    @staticmethod
    def external(prior_q: Any) -> Strategy:
        """q set from outside (the hybrid loop, an :class:`Ensemble`); ``prior_q`` until then."""
    @property
    def kind(self) -> Literal["constant", "mehra", "adaptive", "oracle", "external"]: ...
    @property
    def label(self) -> str: ...
    @property
    def q(self) -> list[float]:
        """q of a constant strategy, the prior q of the others; empty for the oracle."""
    @property
    def window(self) -> int | None: ...

@final
class SensorConfig:
    """Simulated sensors. ``imu_variance``: 6 per-sample variances, or with
    ``imu_variance_times`` (k,) [s, starting at 0] a ``(k, 6)`` piecewise-constant
    schedule. Constant bias, bias random-walk PSD, DVL variance [(m/s)²], DVL period [s]
    (a whole number of IMU steps), DVL lever arm [m, body], DVL outages ``(k, 2)``
    ``[start, end)`` [s] (sorted, not overlapping; no reading inside one), and the
    DVL's scale-factor error k (it reads ``1 + k`` times the velocity, k > −1) and
    mounting misalignment (its roll, pitch, yaw in the body frame [rad]), and
    ``dvl_dropout`` ``(mean_interval, mean_length)`` [s]: random bottom-lock loss, a
    locked/lost chain stepped at each due reading (mean time between losses, mean
    length of a loss; its own seeded stream, so a Monte Carlo stays the same for any
    thread count; a lost reading is a missed update, counted in
    ``MonteCarloResult.missed_updates``). ``dvl_period=0``: no DVL (a GNSS/INS or
    depth-only run; the other DVL arguments are then unused). The aiding sensors, each
    read at its lever arm and applied by the filter with the σ and the lever arm it is
    simulated with: ``depth_sigma`` [m] (None: no depth sensor) every ``depth_period``
    [s] (default 1; refused without ``depth_sigma``), the depth of a pressure sensor at
    ``depth_lever_arm`` [m, body FRD from the IMU; default 0: the IMU's point];
    ``heading_sigma`` [rad] (None: no heading sensor; at most π) every ``heading_period``
    [s] (default 1; refused without ``heading_sigma``), the body's yaw from true north
    (a compass corrected for declination, an AHRS); ``fixes``, a list of position-fix
    sources, each a dict with ``sigma`` (1σ [m] north, east and optionally down: without
    it the fixes carry no height), a schedule: ``period`` [s] (0 or absent: none),
    ``times`` [s] (single fixes, each at the IMU epoch nearest it) and ``max_depth`` [m]
    (fixes only while the true depth is at most this: at the surface), and ``lever_arm``
    [m, body FRD] of the antenna or transponder (default 0). Each aiding sensor draws
    from its own seeded stream: the other sensors' draws are the same with and without
    it. Defaults: the paper's (an ideal DVL, no dropout, no depth sensor, no heading
    sensor, no fixes)."""

    def __new__(cls, *, imu_variance: Any | None = None, imu_variance_times: Any | None = None,
                imu_bias: Any | None = None, imu_bias_psd: Any | None = None,
                dvl_variance: Any | None = None, dvl_period: float = 1.0,
                lever_arm: Any | None = None, dvl_outages: Any | None = None,
                dvl_scale: float = 0.0, dvl_misalignment: Any | None = None,
                dvl_dropout: Any | None = None, depth_sigma: float | None = None,
                depth_period: float | None = None, depth_lever_arm: Any | None = None,
                heading_sigma: float | None = None, heading_period: float | None = None,
                fixes: Any | None = None) -> SensorConfig: ...  # fmt: skip
    @property
    def imu_variance_times(self) -> list[float]: ...
    @property
    def imu_variance(self) -> NDArray[np.float64]: ...
    @property
    def imu_bias(self) -> list[float]: ...
    @property
    def imu_bias_psd(self) -> list[float]: ...
    @property
    def dvl_outages(self) -> NDArray[np.float64]:
        """``(k, 2)`` DVL outages ``[start, end)`` [s]."""
    @property
    def dvl_variance(self) -> list[float]: ...
    @property
    def dvl_period(self) -> float: ...
    @property
    def lever_arm(self) -> list[float]: ...
    @property
    def dvl_scale(self) -> float:
        """The DVL's scale-factor error k: it reads ``(1 + k)`` times the true velocity."""
    @property
    def dvl_misalignment(self) -> list[float]:
        """The DVL's roll, pitch, yaw in the body frame [rad] (its mounting misalignment)."""
    @property
    def dvl_dropout(self) -> tuple[float, float] | None:
        """``(mean_interval, mean_length)`` [s] of the random bottom-lock loss, or None."""
    @property
    def depth_sigma(self) -> float | None:
        """1σ of the depth sensor [m], or None without one."""
    @property
    def depth_period(self) -> float | None:
        """Period of the depth sensor [s], or None without one."""
    @property
    def depth_lever_arm(self) -> list[float] | None:
        """The depth sensor's lever arm [m, body FRD], or None without one."""
    @property
    def heading_sigma(self) -> float | None:
        """1σ of the heading sensor [rad], or None without one."""
    @property
    def heading_period(self) -> float | None:
        """Period of the heading sensor [s], or None without one."""
    @property
    def fixes(self) -> list[dict[str, Any]]:
        """The position-fix sources, as the dicts the constructor takes."""

@final
class Dvl:
    """A velocity stream for :func:`run_filter`: a DVL's readings, or velocities in NED.

    ``time`` ``(m,)`` [s], strictly increasing (each row is applied at the IMU epoch
    nearest it); ``velocity`` ``(m, 3)`` [m/s] in ``frame``: ``"body"``, a DVL's
    velocity in the body frame FRD at its lever arm r (``h = Ĉᵀv̂ + ω̂ × r``), or
    ``"ned"``, the NED velocity of the point at r (``h = v̂ + Ĉ(ω̂ × r)``). ``sigma``: 1σ
    [m/s] per axis, a number, ``(3,)`` or ``(m, 3)`` one per row; R: ``diag(σ²)`` + r's gyro noise.
    ``lever_arm`` ``(3,)`` [m, body FRD] from the IMU, within ±:data:`MAX_LEVER_ARM`.
    ``gate``: a χ² threshold (3 dof, > 0): a row whose NIS exceeds it is rejected. Each
    None is the pass's :class:`FilterConfig`'s (``dvl_variance``, ``aiding``,
    ``lever_arm``, ``innovation_gate``), so ``Dvl(time, velocity)`` is the DVL it
    describes. Beside the DVL calibration states (``dvl_calibration=True``: they read
    every body-frame stream) a ``"ned"`` stream is refused. The arrays are copied, the
    getters give them back as given (None: not given); a bad argument is a ValueError
    naming it."""

    def __new__(cls, time: ArrayLike, velocity: ArrayLike, *, sigma: Any | None = None,
                frame: Literal["body", "ned"] | None = None, lever_arm: Any | None = None,
                gate: float | None = None) -> Dvl: ...  # fmt: skip
    @property
    def time(self) -> NDArray[np.float64]: ...
    @property
    def velocity(self) -> NDArray[np.float64]: ...
    @property
    def sigma(self) -> NDArray[np.float64] | None:
        """1σ [m/s]: ``(3,)`` for every row (a number given: three), or ``(m, 3)``."""
    @property
    def frame(self) -> Literal["body", "ned"] | None: ...
    @property
    def lever_arm(self) -> list[float] | None: ...
    @property
    def gate(self) -> float | None: ...

@final
class Depth:
    """A depth stream for :func:`run_filter`: a pressure sensor's readings.

    ``time`` ``(d,)`` [s], strictly increasing (each row is applied at the IMU epoch
    nearest it); ``depth`` ``(d,)`` [m, positive down] of the sensor at ``lever_arm``
    ``(3,)`` [m, body FRD] from the IMU, within ±:data:`MAX_LEVER_ARM`
    (``h = −ĥ + (Ĉ r)_D``: 1 m below a level IMU reads 1 m deeper). ``sigma``: 1σ [m], a
    number or ``(d,)`` one per reading. A scalar update of the position error (NIS χ²,
    1 dof; no gate). The arrays are copied; a bad argument is a ValueError naming it."""

    def __new__(cls, time: ArrayLike, depth: ArrayLike, *, sigma: Any,
                lever_arm: Any = (0.0, 0.0, 0.0)) -> Depth: ...  # fmt: skip
    @property
    def time(self) -> NDArray[np.float64]: ...
    @property
    def depth(self) -> NDArray[np.float64]: ...
    @property
    def sigma(self) -> float | NDArray[np.float64]: ...
    @property
    def lever_arm(self) -> list[float]: ...

@final
class Fix:
    """A position-fix stream for :func:`run_filter`: GNSS, USBL or LBL fixes.

    ``time`` ``(f,)`` [s], strictly increasing (each row is applied at the IMU epoch
    nearest it); ``lla`` ``(f, 3)`` ``[lat, lon (rad), h (m, up; NaN: a horizontal
    fix)]`` of the antenna or transponder at ``lever_arm`` ``(3,)`` [m, body FRD] from
    the IMU, within ±:data:`MAX_LEVER_ARM`; ``|lat|`` <= 89°, ``lon`` within [−π, 2π]
    (±180° or 0–360°: its difference from the estimate is wrapped into (−π, π]).
    ``sigma``: 1σ [m] north, east, down, ``(3,)`` or ``(f, 3)`` one per fix (a
    horizontal fix's down σ unused, NaN allowed). Scalar updates of the position error
    (NIS χ², 2 or 3 dof; no gate). The arrays are copied; a bad argument is a
    ValueError naming it."""

    def __new__(cls, time: ArrayLike, lla: ArrayLike, *, sigma: Any,
                lever_arm: Any = (0.0, 0.0, 0.0)) -> Fix: ...  # fmt: skip
    @property
    def time(self) -> NDArray[np.float64]: ...
    @property
    def lla(self) -> NDArray[np.float64]: ...
    @property
    def sigma(self) -> NDArray[np.float64]: ...
    @property
    def lever_arm(self) -> list[float]: ...

@final
class Heading:
    """A heading stream for :func:`run_filter`: a compass's, an AHRS's or a gyrocompass's
    yaw.

    ``time`` ``(n,)`` [s], strictly increasing (each row is applied at the IMU epoch
    nearest it); ``heading`` ``(n,)`` [rad], the yaw of the body from true north (ZYX, as
    the filter's ``rpy``; a magnetic heading corrected for declination first), within
    ±2π (the innovation is wrapped into (−π, π]; degrees are refused). ``sigma``: 1σ
    [rad], > 0 and at most π, a number or ``(n,)`` one per reading. A scalar update of
    the attitude error (``h = atan2(Ĉ₁₀, Ĉ₀₀)``; NIS χ², 1 dof; no gate), no lever arm.
    The arrays are copied; a bad argument is a ValueError naming it."""

    def __new__(cls, time: ArrayLike, heading: ArrayLike, *, sigma: Any) -> Heading: ...
    @property
    def time(self) -> NDArray[np.float64]: ...
    @property
    def heading(self) -> NDArray[np.float64]: ...
    @property
    def sigma(self) -> float | NDArray[np.float64]: ...

def run_filter(imu: ArrayLike, imu_time: ArrayLike,
               streams: Sequence[Dvl | Depth | Fix | Heading], *, t0: float, lla0: Any,
               vel0: Any, rpy0: Any, config: FilterConfig,
               strategy: Strategy, bias0: Any | None = None, q_time: ArrayLike | None = None,
               q: ArrayLike | None = None, epochs: Literal["all", "last"] = "all",
               output_step: float | None = None, covariance_time: ArrayLike | None = None,
               smooth: bool = False) -> dict[str, Any]:  # fmt: skip
    """One filter pass: :func:`pronet.run_filter` (its arguments, ``config`` required),
    returning the dict :class:`pronet.FilterResult` is made of. ``streams``: a sequence
    of :class:`Dvl`, :class:`Depth`, :class:`Fix` and :class:`Heading`, applied at an
    epoch in this order. Key ``streams``: a dict per stream, in order, of ``kind``
    (``"velocity"``, ``"depth"``, ``"fix"`` or ``"heading"``), ``epoch`` (r,) (-1
    outside the run), ``nis`` (r,) (NaN outside) and, for a velocity stream,
    ``innovation``, ``innovation_cov``, ``gain``, ``accepted``, ``adaptive_q`` (None where
    no row has one, as the top-level key). The top-level update keys are the first
    velocity, depth and fix stream's (the same arrays; no rows without one; a heading has
    none). ``smoothed``: a dict of ``lla``, ``vel``, ``rpy``, ``bias``, ``sigma``,
    ``calibration``, ``calibration_sigma`` per epoch, or None. ``extent``: the forward
    pass's ``(bound, t_bound, σ_ψD², t_heading)`` (:class:`pronet.stats.Extent`), watched
    at every epoch, kept or not: the bound (``"non-finite"``, ``"speed"``, ``"height"``,
    ``"position-sigma"``; "" where none) the solution first broke and when [s], the largest
    heading variance [rad²] and when its σ first passed :data:`MAX_LINEAR_HEADING_SIGMA_DEG`
    (the close of the covariance step it passed in; NaN where none did). Before it
    allocates, a pass that would hold more than this process can still take is a ``ValueError``
    naming the argument that bounds the most of it (``output_step``, ``streams``,
    ``strategy``, ``covariance_time`` or ``smooth``) with the estimate (docs/results/performance.md,
    "Memory")."""

def monte_carlo(trajectory: Trajectory, sensors: SensorConfig, config: FilterConfig,
                strategy: Strategy, *, n_runs: int, seed: int = 0, record_every: int = 0,
                sample_initial_error: bool = True, threads: int | None = None, first_run: int = 0,
                smooth: bool = False) -> dict[str, Any]:  # fmt: skip
    """A Monte Carlo; see :class:`pronet.MonteCarloResult` for the keys. ``n_runs`` >= 1,
    ``first_run + n_runs`` <= :data:`MAX_RUN_INDEX`, ``threads`` 1 to :func:`max_threads`
    (None: :func:`check_threads`'s default). An external strategy is refused: nothing
    sets its q here. ``smooth``: also the RTS smoother's metrics of every run (key
    ``smoothed``: ``srmse``, ``smae``, ``final_horizontal_error``,
    ``max_horizontal_error``, ``nees`` and, with ``record_every``, ``error`` and
    ``sigma``). Before it allocates, one that would hold more than this process can still
    take (the records and their arrays, the runs under way and their smoothers) is a
    ``ValueError`` naming ``n_runs``, ``record_every`` or ``smooth`` (docs/results/performance.md,
    "Memory")."""

def check_result_size(
    trajectory: Trajectory, sensors: SensorConfig, *, n_runs: int, record_every: int = 0
) -> None:
    """``ValueError`` naming ``n_runs`` if the records of ``n_runs`` runs of
    ``trajectory`` would exceed the core's memory limit (4 GiB), as :func:`monte_carlo`
    checks before it allocates; nothing is run."""

def check_fixes_fire(trajectory: Trajectory, sensors: SensorConfig) -> None:
    """``ValueError`` naming ``fixes[j]`` (or its ``max_depth``) if fix source ``j`` of
    ``sensors`` takes no fix on ``trajectory``: none of its scheduled epochs falls inside
    it, or none comes at a true depth of at most its ``max_depth``. :func:`monte_carlo`
    runs such a source (``fix_updates`` counts the fixes taken); a scenario file is
    refused with it (:func:`pronet.config.load_scenario`)."""

def check_threads(threads: int | None = None) -> int:
    """The thread count a call given ``threads`` runs on: ``threads`` itself if it is 1
    to :func:`max_threads` (else ``ValueError`` naming ``threads``); for None,
    ``RAYON_NUM_THREADS`` if set (checked the same way, the error naming the variable),
    else one per usable core."""

def max_threads() -> int:
    """The most threads a pool may have here: :data:`THREADS_PER_CORE` per usable core,
    at most :data:`MAX_THREADS`."""

@final
class Ensemble:
    """All runs of a Monte Carlo stepped in lockstep for outside tuning.

    ``advance()`` steps every run to the next tuning instant (see
    :func:`tuning_instants`; ``window`` 1 to the trajectory's length) and returns the
    last ``window`` raw IMU samples of every run, float32 ``(n_runs, 6, window)`` oldest
    first, or None at the end; ``set_q(q)`` with ``q`` ``(n_runs, 6)`` sets each
    run's IMU variances. Until the first ``set_q`` every run uses ``prior_q``.
    ``advance`` and ``finish`` end within a fraction of a second on Ctrl-C or SIGTERM
    (KeyboardInterrupt); the ensemble is then unusable (ValueError). ``smooth``: as
    :func:`monte_carlo`'s; so is the memory check before it allocates (every run is
    under way at once).
    """

    def __new__(cls, trajectory: Trajectory, sensors: SensorConfig, config: FilterConfig,
                prior_q: Any, *, n_runs: int, seed: int = 0, window: int = 200,
                tuning_period: float = 1.0, record_every: int = 0,
                sample_initial_error: bool = True, threads: int | None = None, first_run: int = 0,
                smooth: bool = False) -> Ensemble: ...  # fmt: skip
    def advance(self) -> NDArray[np.float32] | None:
        """Step all runs to the next tuning instant; the windows ``(n_runs, 6, window)``
        float32, oldest sample first, or None at the end."""
    def set_q(self, q: ArrayLike) -> None:
        """Set each run's IMU variances: ``q`` ``(n_runs, 6)``."""
    def finish(self) -> dict[str, Any]:
        """Run to the end; the results as :func:`monte_carlo` returns them. The
        ensemble cannot be used afterwards."""
    @property
    def n_runs(self) -> int: ...
    @property
    def window(self) -> int: ...
    @property
    def steps(self) -> int:
        """IMU steps taken so far."""
    @property
    def time(self) -> float:
        """Current time [s]."""
    @property
    def done(self) -> bool: ...

def tuning_instants(
    n_samples: int, dt: float, window: int, tuning_period: float
) -> NDArray[np.int64]:
    """The hybrid loop's tuning instants over ``n_samples`` IMU samples of step ``dt``
    [s], each as the number of samples before it: every ``round(tuning_period / dt)``
    samples (halves round away from zero), from the first such multiple at which
    ``window`` samples exist, before the last sample. :class:`Ensemble` stops there;
    :func:`pronet.learn.hybrid.q_schedule` evaluates its regressor there. ``dt``,
    ``tuning_period`` finite, > 0 (a period of no step refused), ``window`` >= 1."""

@final
class Navigator:
    """The filter pass fed as the data arrives: :class:`pronet.recorded.online.Navigator`
    (its documentation is there). ``streams``: :class:`Dvl`, :class:`Depth`, :class:`Fix` and
    :class:`Heading` without rows, describing the sensors (noise, frame, lever arm,
    gate), whose readings are applied at an epoch in this order. ``lag`` [s] (finite,
    >= 0): how late a reading may be stamped before the newest IMU sample and still be
    applied at its own epoch; ``checkpoint_every`` (>= 1): a copy of the filter every so
    many epochs. ``tuning_period`` [s] with ``imu_dt`` [s] and ``window`` (samples): the
    learned loop's instants, as :func:`tuning_instants` places them. A feed whose lag
    window's history is about to outgrow the memory this process can still take is a
    ``ValueError`` naming ``lag`` (docs/results/performance.md, "Memory")."""

    def __new__(cls, streams: Sequence[Dvl | Depth | Fix | Heading], *, t0: float, lla0: Any,
                vel0: Any, rpy0: Any, config: FilterConfig, strategy: Strategy,
                bias0: Any | None = None, lag: float = 1.0, checkpoint_every: int = 32,
                tuning_period: float | None = None, imu_dt: float | None = None,
                window: int = 200) -> Navigator: ...  # fmt: skip
    def imu(self, time: float, sample: Any) -> None:
        """Feed one IMU sample ``[f (m/s²), ω (rad/s)]`` (body FRD) ending at ``time`` [s]."""
    def imu_block(self, times: ArrayLike, samples: ArrayLike) -> int:
        """Feed IMU samples ``(n, 6)`` ending at ``times`` ``(n,)`` [s], in order, stopping
        after a tuning instant (:attr:`tuning_due`): the number fed. Every sample and time
        is checked first: a block with a bad one feeds none."""
    def reading(self, stream: int, time: float, value: Any, sigma: Any | None = None) -> str:
        """Feed the reading ``value`` of ``streams[stream]`` stamped ``time`` [s], with its
        own 1σ ``sigma`` (None: the stream's): ``"queued"``, ``"current"``, ``"late"``,
        ``"refused"`` or ``"skipped"``."""
    def set_q(self, q: Any) -> None:
        """Set the IMU variances ``q`` (6) from the next IMU step on (an external strategy)."""
    def state(self) -> dict[str, Any]:
        """The estimate at the newest epoch: a dict of ``epoch``, ``time`` [s], ``lla``
        [rad, rad, m], ``vel`` [m/s NED], ``rpy`` [rad], ``bias`` (6), ``sigma`` (15,
        brought up to date), ``calibration`` and ``calibration_sigma`` (4, or None). A
        stopped navigator raises its failure."""
    def extent(self) -> tuple[str, float, float, float]:
        """What the pass watched for its health over every epoch so far (as
        ``run_filter``'s ``extent``, :class:`pronet.stats.Extent`)."""
    def imu_gaps(self) -> tuple[int, float, float, float, float]:
        """The IMU's gaps so far: their number, the first's end [s] and length [s], the
        longest's length [s] (NaN: none), and the usual step [s] (:data:`MAX_IMU_GAP`)."""
    def tally(self) -> list[dict[str, Any]]:
        """Each stream's tally, a list of dicts in the streams' order: ``name``, ``kind``
        (``"velocity"``, ``"depth"``, ``"fix"``, ``"heading"``), ``received``, ``queued``,
        ``accepted``, ``rejected`` (by the gate), ``late`` (stamped before the newest IMU
        sample when fed), ``refused`` (before the lag window), ``skipped`` (before the
        start), ``nis_sum`` and ``dof`` (the applied readings')."""
    @property
    def epoch(self) -> int:
        """The newest epoch: the number of IMU samples fed."""
    @property
    def tuning_due(self) -> bool:
        """Whether the newest epoch is a tuning instant (set q before the next sample)."""
    @property
    def window(self) -> NDArray[np.float32] | None:
        """The learned loop's window ``(6, window)`` float32, oldest sample first (None
        without a tuning or before it is full)."""
    @property
    def failure(self) -> str | None:
        """The error that stopped the navigator, or None."""

@final
class ConvNet:
    """The forward pass of a ProNet CNN regressor (``pronet.learn.models.BaselineNet`` or
    ``DetrendNet``) from its torch weights; build it with
    :meth:`pronet.learn.models.BaselineNet.native`.

    ``prepare``: ``"centre"`` or ``"detrend"``; ``scaling``: ``"fixed"`` (uses
    ``input_scale`` and ``q_scale``) or ``"spread"``. ``blocks``: per convolution block
    ``(weight (c_out, c_in, kernel), bias, norm_weight, norm_bias, stride, eps)``;
    ``head``: per Linear layer ``(weight (n_out, n_in), bias)``; arrays taken as float32.
    ``ramp``: the ``(window,)`` ramp a ``"detrend"`` net projects out, as the torch
    model stores it (None: the exact unit-norm centred ramp). ``threads``: worker
    threads for ``predict`` (None: all cores). ``precision``: ``"float64"`` (the torch
    model's function to ~1e-12 relative) or ``"float32"`` (the convolution blocks in
    float32, ~1.7× as fast, within ~1e-5 relative of float64; the window's
    preparation and the Linear layers stay float64). Either is deterministic: the same
    bits whatever the batch, thread count or CPU.
    """

    def __new__(
        cls,
        *,
        window: int,
        prepare: str,
        scaling: str,
        blocks: list[tuple[Any, Any, Any, Any, int, float]],
        head: list[tuple[Any, Any]],
        input_scale: float = 0.1,
        q_scale: float = 0.01,
        negative_slope: float = 0.01,
        ramp: ArrayLike | None = None,
        threads: int | None = None,
        precision: Literal["float64", "float32"] = "float64",
    ) -> ConvNet: ...
    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        """q ``(n,)`` [(unit)² per sample] for windows ``(n, window)`` (taken as float32)."""
    @property
    def window(self) -> int: ...
    @property
    def precision(self) -> Literal["float64", "float32"]:
        """``"float64"`` or ``"float32"``: the element type of the convolution blocks."""

@final
class HcfEnsemble:
    """The handcrafted-feature ensemble's prediction (``pronet.learn.hcf.HCFEnsemble``) from
    its exported trees; build it with :meth:`pronet.learn.hcf.HCFEnsemble.frozen`.

    ``gb``, ``rf``: ``(left, right, feature, roots)`` int32 and ``threshold``, ``value``
    float64 arrays, in the order ``(left, right, feature, threshold, value, roots)``;
    ``target``: ``"q"`` or ``"log-ratio"``. ``threads``: worker threads for ``predict``
    (None: all cores).
    """

    def __new__(
        cls,
        *,
        window: int,
        gb: tuple[Any, ...],
        gb_init: float,
        gb_rate: float,
        rf: tuple[Any, ...],
        target: str,
        threads: int | None = None,
    ) -> HcfEnsemble: ...
    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        """q ``(n,)`` for windows ``(n, window)``."""
    @property
    def window(self) -> int: ...

def attitude_increment_costs(
    edges: ArrayLike,
    cum: ArrayLike,
    gt_time: ArrayLike,
    gt_step: ArrayLike,
    offsets: ArrayLike,
    scale: float,
) -> NDArray[np.float64]:
    """The clock-alignment cost of ``pronet.recorded.alignment.estimate_gt_clock`` for the clocks
    ``(offset, scale)``, one per offset: the mean squared difference between the
    truth's Euler-angle steps ``gt_step (R - 1, 3)`` [rad] and the integrated gyro Euler
    rates ``cum (K, 3)`` [rad] at the IMU ``edges (K,)`` [s], interpolated linearly at
    ``offset + scale·gt_time``, over the pairs of rows mapped inside the edges; inf
    with fewer than 10 such pairs. More offsets than this process can still take are a
    ``ValueError`` naming ``offsets`` (docs/results/performance.md, "Memory")."""
