"""Recorded missions: reading a vehicle's IMU, DVL and (optional) ground truth, aligning their
clocks and lever arms, tuning the filter for them, running every strategy and reporting.

Reading and preparing:

- :mod:`~pronet.recorded.recordings`: the readers (the Snapir layout, the generic CSV
  and ``.npz`` formats, the ground truth optional), validated before any computation;
- :mod:`~pronet.recorded.csvtext`: CSV text as numbers, fast, or naming the bad row
  and cell;
- :mod:`~pronet.recorded.alignment`: clocks and lever arms, a recording turned into a
  filter-ready :class:`~pronet.recorded.alignment.Section`;
- :mod:`~pronet.recorded.bags`: ROS 1 and ROS 2 bags as recordings (the ``rosbags``
  extra): topics, frames (REP-103 FLU/ENU to FRD/NED), the DVL covariance as R;
- :mod:`~pronet.recorded.bagfields`: a bag's topics read in one pass, a topic's
  messages as columns of numbers (raw messages of a fixed layout decoded with NumPy,
  to the deserializer's bits);
- :mod:`~pronet.recorded.aiding`: depth readings and position fixes (the generic
  format's optional ``depth`` and ``fix`` tables), their missing values, checks and σ;
- :mod:`~pronet.recorded.heading`: heading readings (the optional ``heading`` table, a
  bag's heading topic), true or magnetic, their σ and missing values;
- :mod:`~pronet.recorded.missing`: missing DVL readings (no bottom lock), skipped as
  updates and counted;
- :mod:`~pronet.recorded.plausible`: plausibility checks naming file and column (stuck
  channels, angle units, duplicate columns, physical bounds, long lever arms);
- :mod:`~pronet.recorded.tuning`: the filter tuning of recorded sections and the rows
  ``pronet real`` runs;
- :mod:`~pronet.recorded.vehicle`: your own vehicle's tuning (``--filter``: grade
  presets, a scenario's ``[filter]`` keys, lever arms);
- :mod:`~pronet.recorded.dvlnoise`: the DVL's noise variance R from the data;
- :mod:`~pronet.recorded.dvltruth`: the DVL scale and mounting the ground truth implies;
- :mod:`~pronet.recorded.trutherror`: the ground truth's own velocity error, from the
  DVL–truth residual (the Snapir truth's stated once);
- :mod:`~pronet.recorded.dvlcalibration`: the DVL calibration states in simulation.

Running and reporting (``pronet real``):

- :mod:`~pronet.recorded.reading`: every section read and aligned side by side, each
  that cannot be its one-line reason beside the others;
- :mod:`~pronet.recorded.passes`: one section's filter passes (where a run starts, its
  sensors, one strategy's pass and metrics, the rows of a section);
- :mod:`~pronet.recorded.real`: every strategy on the sections, the result folder
  (:func:`~pronet.recorded.real.run_real`);
- :mod:`~pronet.recorded.runs`: what a run produced, as plain records;
- :mod:`~pronet.recorded.metrics`: errors against the ground truth;
- :mod:`~pronet.recorded.tables`: the tables, ``metrics.csv`` and ``config.json``;
- :mod:`~pronet.recorded.aidingtables`: their depth, fix and heading tables and records;
- :mod:`~pronet.recorded.figures`: the section figures, drawn in worker processes.

Navigating a recording without ground truth (``pronet navigate``):

- :mod:`~pronet.recorded.navigate`: one filter over every stream, forward and smoothed,
  from an initial state found in the data (:func:`~pronet.recorded.navigate.navigate`);
- :mod:`~pronet.recorded.solution`: what it produces, as plain records;
- :mod:`~pronet.recorded.surface`: the depth's surface reference measured at the surface;
- :mod:`~pronet.recorded.attitude`: its attitude as users read it (yaw in [0, 360),
  roll, pitch and yaw σ from the filter's attitude-error σ);
- :mod:`~pronet.recorded.export`: the files a user loads (``trajectory.csv``,
  ``track.geojson``, ``config.json``) and :func:`~pronet.recorded.export.write_all`;
- :mod:`~pronet.recorded.odometry`: the solution as ``nav_msgs/Odometry`` in a ROS 1 or
  ROS 2 bag (the ``rosbags`` extra);
- :mod:`~pronet.recorded.report`: its figures and ``report.md``;
- :mod:`~pronet.recorded.initial`: the initial state from the data (or given), each part
  with the P0 its method earns;
- :mod:`~pronet.recorded.initialinputs`: its inputs checked, the readings around t0;
- :mod:`~pronet.recorded.levelling`: still intervals, levelling and gyrocompassing;
- :mod:`~pronet.recorded.online`: the filter fed as the data arrives
  (:class:`~pronet.recorded.online.Navigator`: late readings within a lag window, the
  learned loop inside), equal to the batch pass in time order;
- :mod:`~pronet.recorded.messages`: one ROS message at a time in pronet's frames and
  units, as the bag reader converts a topic (a node's callbacks).
"""

__all__ = [
    "aiding",
    "aidingtables",
    "alignment",
    "attitude",
    "bagfields",
    "bags",
    "csvtext",
    "dvlcalibration",
    "dvlnoise",
    "dvltruth",
    "export",
    "figures",
    "heading",
    "initial",
    "initialinputs",
    "levelling",
    "messages",
    "metrics",
    "missing",
    "navigate",
    "odometry",
    "online",
    "passes",
    "plausible",
    "reading",
    "real",
    "recordings",
    "report",
    "runs",
    "solution",
    "surface",
    "tables",
    "trutherror",
    "tuning",
    "vehicle",
]
