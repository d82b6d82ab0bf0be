"""pronet: INS/DVL navigation with learned, adaptive process noise.

The navigation core (strapdown mechanization, the 15-state error-state EKF, the
Monte Carlo engine) is Rust, in :mod:`pronet._core`; this package adds validated,
documented Python entry points on top.

Conventions: navigation frame NED, body frame FRD (x forward, y right, z down);
positions are geodetic ``[lat, lon, h]`` in rad, rad, m (height positive up);
attitude is roll, pitch, yaw (ZYX) in rad; IMU samples are
``[f_x, f_y, f_z, w_x, w_y, w_z]`` in m/s² and rad/s, body frame. See
``docs/reference/filter.md`` for every formula.
"""

from pronet._core import (
    Depth,
    Dvl,
    FilterConfig,
    Fix,
    Heading,
    SensorConfig,
    Strategy,
    Trajectory,
    __version__,
    builtin_trajectory_names,
    earth_radii,
    normal_gravity,
)
from pronet._util.plausibility import PlausibilityWarning
from pronet.filter import FilterResult, SmoothedResult, StreamResult, run_filter
from pronet.montecarlo import STATE_BLOCKS, Ensemble, MonteCarloResult, monte_carlo
from pronet.navigation import NavSolution, lla_from_ned, local_ned, mechanize
from pronet.stats import FilterHealthWarning
from pronet.trajectory import Segment, builtin_trajectory, trajectory_from_segments

__all__ = [
    "Depth",
    "Dvl",
    "Ensemble",
    "FilterConfig",
    "FilterHealthWarning",
    "FilterResult",
    "Fix",
    "Heading",
    "MonteCarloResult",
    "NavSolution",
    "PlausibilityWarning",
    "STATE_BLOCKS",
    "Segment",
    "SmoothedResult",
    "SensorConfig",
    "Strategy",
    "StreamResult",
    "Trajectory",
    "__version__",
    "builtin_trajectory",
    "builtin_trajectory_names",
    "earth_radii",
    "lla_from_ned",
    "local_ned",
    "mechanize",
    "monte_carlo",
    "normal_gravity",
    "run_filter",
    "trajectory_from_segments",
]
