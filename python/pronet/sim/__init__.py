"""Simulated evaluation scenarios: what is simulated and how the filter is tuned for it.

- :mod:`~pronet.sim.paper`: the paper's numbers (Or & Klein 2022, Tables I and II), its
  filter configuration and its seven rows;
- :mod:`~pronet.sim.scenarios`: the built-in scenarios (a trajectory, its sensors, the
  filter's tuning and the true IMU noise schedule), :data:`~pronet.sim.scenarios.SCENARIOS`.

A user's scenario is a TOML file (:func:`pronet.config.load_scenario`); a scenario is run
by :func:`pronet.run.run` and, with its result folder, by
:func:`pronet.experiments.simulation.simulate`.
"""

__all__ = ["paper", "scenarios"]
