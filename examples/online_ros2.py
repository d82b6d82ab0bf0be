"""A ROS 2 bag navigated message by message, as a vehicle's ROS node would: the filter fed
as the data arrives (pronet.recorded.online.Navigator), a starting point to run it live.

Run:  python examples/online_ros2.py BAG [--vehicle vehicle.toml] [--imu-topic T] ...

Each message goes, in the bag's order, to the callback of :class:`Node` a subscription
would call: ``sensor_msgs/Imu`` → ``Navigator.imu``; the DVL's TwistWithCovarianceStamped
→ reading 0 (body velocity); FluidPressure → 1 (depth); NavSatFix → 2 (latitude,
longitude: the depth gives the height); with ``--heading-topic`` (the IMU's own: its
AHRS yaw) a heading a second → 3. The conversions (REP-103's FLU and ENU to FRD and NED,
pressure to depth, covariance to σ) are the bag reader's, one message at a time
(pronet.recorded.messages.MessageConverter); a reading without a
covariance takes the vehicle file's σ (pronet.recorded.vehicle: grade, σ, lever arms).

The initial state is pronet.recorded.initial.initial_state's (not built by hand) on the
newest ``--init-seconds`` of messages, kept until it starts (tried once that many have
come, then each second): levelled and the fixes averaged while the vehicle rests, else
the AHRS attitude and the DVL velocity at t0. The kept messages also give the depth's
surface offset (pronet.recorded.surface: readings beside fixes while afloat), the IMU
step and q (the IMU's noise); those after t0 are then replayed.

It prints the state once a second of message time (latitude, longitude, depth, yaw,
horizontal 1σ √(σN² + σE²)) and, at the end, each stream's tally (``late``: stamped
before the newest IMU sample when it came, applied at its own epoch by running the
stretch again). In an rclpy node the ``on_*``
methods are the subscriptions' callbacks (``create_subscription(Imu, "/imu/data",
node.on_imu, 10)``, …), ``nav.state()`` is published on a timer as
``nav_msgs/Odometry``, and the bag loop in :func:`main` stands for the executor.
"""

from __future__ import annotations

import argparse
import math
from collections import deque
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

import pronet
from pronet.filter import Stream
from pronet.recorded.aiding import AidingTuning
from pronet.recorded.attitude import yaw_degrees
from pronet.recorded.bags import BagTopics, require_rosbags
from pronet.recorded.initial import initial_state
from pronet.recorded.messages import MessageConverter
from pronet.recorded.navigate import lever_arms
from pronet.recorded.online import Navigator
from pronet.recorded.surface import surface_offset
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q
from pronet.recorded.vehicle import load_vehicle
from pronet.strategies import StrategySpec, strategy

STREAMS = ("dvl", "depth", "fix", "heading")  # the navigator's streams, by index
TOPICS = {"imu": "/imu/data", "dvl": "/dvl/twist", "depth": "/bar30/pressure", "fix": "/usbl/fix"}
TALLY = ("received", "accepted", "rejected", "late", "refused", "skipped", "queued")


class Reading(NamedTuple):
    kind: str  # "imu", "orientation" (kept for the start only) or one of STREAMS
    time: float
    value: Any
    sigma: Any  # None: the stream's own


class Node:
    """The navigator behind a node's subscriptions: the first messages kept until it can
    start, then each fed as it comes, the state printed once a second."""

    def __init__(self, topics: BagTopics, vehicle: str, init_seconds: float, spec: str) -> None:
        self.topics, self.init_seconds, self.spec = topics, init_seconds, StrategySpec.parse(spec)
        self.vehicle = load_vehicle(vehicle)
        self.arms = lever_arms(self.vehicle)  # from the reference point; the filter's: the IMU
        self.depth_arm, self.fix_arm = map(self.arms.from_imu, (self.arms.depth, self.arms.fix))
        self.sigma = self.vehicle.aiding(AidingTuning())  # σ of readings without their own
        if topics.heading is not None and self.sigma.heading_sigma is None:
            raise ValueError("--heading-topic: give heading_sigma [deg] in the vehicle file")
        self.convert = MessageConverter(topics)  # one message at a time, as the reader
        self.kept: deque[Reading] = deque()
        self.next_try: float | None = None  # when to try to start next
        self.nav: Navigator | None = None
        self.why = f"less than {init_seconds:g} s of IMU messages"  # why not started yet
        self.next_print = self.next_heading = -math.inf
        self.offset = 0.0  # the depth's surface offset [m]

    def on_imu(self, msg: Any) -> None:
        t, sample = self.convert.imu(msg)
        self._event(Reading("imu", t, sample, None))
        attitude = self.convert.orientation(msg)
        if self.nav is None and attitude is not None:  # an AHRS attitude, for the start
            t, rpy, sigma = attitude
            self._event(Reading("orientation", t, rpy, sigma))
        if self.topics.heading == self.topics.imu:
            self.on_heading(msg)

    def on_dvl(self, msg: Any) -> None:
        t, velocity, sigma = self.convert.dvl(msg)
        self._event(Reading("dvl", t, velocity, sigma))  # σ None: the vehicle's R

    def on_pressure(self, msg: Any) -> None:
        t, depth, sigma = self.convert.depth(msg)
        self._event(Reading("depth", t, depth, self.sigma.depth_sigma if sigma is None else sigma))

    def on_fix(self, msg: Any) -> None:
        fix = self.convert.fix(msg)
        if fix is not None:  # None: STATUS_NO_FIX
            t, lla, sigma = fix
            lla[2] = np.nan  # horizontal: the depth gives the height
            self._event(Reading("fix", t, lla, self.sigma.fix_sigma if sigma is None else sigma))

    def on_heading(self, msg: Any) -> None:
        if self.convert.stamp(msg) < self.next_heading:
            return  # a compass's error is slow: one reading a second
        heading = self.convert.heading(msg)
        if heading is None:
            return  # no orientation
        t, yaw, sigma = heading
        self.next_heading = t + 1.0
        self._event(
            Reading("heading", t, yaw, self.sigma.heading_sigma if sigma is None else sigma)
        )

    def _event(self, r: Reading) -> None:
        if self.nav is None:
            self.kept.append(r)
            while r.time - self.kept[0].time > self.init_seconds:
                self.kept.popleft()  # the newest init_seconds only
            if r.kind == "imu":
                if self.next_try is None:  # the first IMU message
                    self.next_try = r.time + self.init_seconds
                if r.time >= self.next_try:
                    self.next_try += 1.0
                    self._start()
        elif r.kind == "imu":
            self.nav.imu(r.time, r.value)
            if r.time >= self.next_print:
                self.next_print = math.floor(r.time) + 1.0
                self.print_state()
        elif r.kind in STREAMS:
            value = r.value - self.offset if r.kind == "depth" else r.value
            self.nav.reading(STREAMS.index(r.kind), r.time, value, r.sigma)

    def _kept(self, kind: str, default: Any = None) -> tuple[Any, Any, Any] | None:
        """The kept readings of ``kind`` as ``initial_state`` takes them (or None)."""
        rows = [r for r in self.kept if r.kind == kind]
        sigma = [default if r.sigma is None else r.sigma for r in rows]
        time, value = np.array([r.time for r in rows]), np.array([r.value for r in rows])
        return (time, value, np.array(sigma)) if rows else None

    def _start(self) -> None:
        """Find the initial state in the kept messages and start, or say why not yet."""
        kept_imu = self._kept("imu", 0.0)
        assert kept_imu is not None  # tried on an IMU message
        imu_time, imu, _ = kept_imu
        config = real_filter_config(
            self.arms.from_imu(self.arms.dvl), imu_dt=imu_step(imu_time), base=self.vehicle.base
        )
        depth, fixes = self._kept("depth"), self._kept("fix")
        surface = None
        if depth is not None:
            fix_time = np.empty(0) if fixes is None else fixes[0]
            at = self.vehicle.surface_depth or 0.0
            surface = surface_offset(depth[0], depth[1], fix_time, surface_depth=at)
            self.offset, depth = surface.offset, (depth[0], depth[1] - surface.offset, depth[2])
        try:
            initial = initial_state(
                imu_time, imu, config.p0_sigma, fixes=fixes, depth=depth,
                heading=self._kept("heading"), orientation=self._kept("orientation"),
                dvl=self._kept("dvl", np.sqrt(config.dvl_variance)),
                fix_lever_arm=self.fix_arm, depth_lever_arm=self.depth_arm,
                dvl_lever_arm=config.lever_arm,
            )  # fmt: skip
        except ValueError as exc:
            self.why = str(exc)
            return
        no, no3, s = np.empty(0), np.empty((0, 3)), self.sigma  # sensors without readings
        streams: list[Stream] = [
            pronet.Dvl(no, no3),  # R and lever arm: the config's (the vehicle's)
            pronet.Depth(no, no, sigma=s.depth_sigma, lever_arm=self.depth_arm),
            pronet.Fix(no, no3, sigma=s.fix_sigma, lever_arm=self.fix_arm),
        ]
        if self.topics.heading is not None:
            streams.append(pronet.Heading(no, no, sigma=s.heading_sigma))
        chosen = strategy(self.spec, white_noise_q(imu))  # q: the IMU's noise while kept
        self.nav = Navigator(
            streams, initial=initial, strategy=chosen, config=config, imu_dt=config.imu_dt,
            names=STREAMS[: len(streams)],  # its errors and findings name the sensor
        )  # fmt: skip
        methods = "; ".join(f"{k}: {v}" for k, v in initial.methods.items())
        print(f"start at {initial.t0:.3f} s: {methods}")
        print(f"surface: {surface.note}" if surface is not None else "surface: no depth")
        print(f"{'time [s]':>14} {'lat [deg]':>12} {'lon [deg]':>12} depth [m] yaw [deg] σh [m]")
        kept, self.kept = self.kept, deque()
        for r in kept:
            if r.time > initial.t0:
                self._event(r)

    def print_state(self) -> None:
        assert self.nav is not None
        s = self.nav.state()
        lat, lon = np.degrees(s.lla[:2])
        yaw, horizontal = float(yaw_degrees(np.array(s.rpy[2]))), math.hypot(*s.sigma[:2])
        print(
            f"{s.time:14.3f} {lat:12.7f} {lon:12.7f} {-s.lla[2]:9.2f} {yaw:9.2f} {horizontal:6.2f}"
        )

    def print_tally(self) -> None:
        assert self.nav is not None
        print(f"{'stream':8}" + "".join(f"{c:>9}" for c in TALLY) + "  NIS/dof")
        for t in self.nav.tally():
            counts = "".join(f"{getattr(t, c):9d}" for c in TALLY)
            print(f"{t.name:8}{counts}{t.mean_nis_per_dof:9.2f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="a ROS 2 bag (a folder with metadata.yaml)")
    parser.add_argument("--vehicle", default="mems", help="vehicle TOML file, or a grade")
    for kind, topic in TOPICS.items():
        parser.add_argument(f"--{kind}-topic", default=topic)
    parser.add_argument("--heading-topic", help="a heading topic; the IMU's: its AHRS yaw")
    parser.add_argument("--surface-pressure", type=float, default=101_325.0, help="[Pa]")
    parser.add_argument("--water-density", type=float, default=1025.0, help="[kg/m³]")
    parser.add_argument("--init-seconds", type=float, default=10.0, help="kept to start [s]")
    parser.add_argument("--strategy", default="constant", help="e.g. adaptive, learned:detrend")
    args = parser.parse_args(argv)
    require_rosbags()
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    topics = BagTopics(
        imu=args.imu_topic, dvl=args.dvl_topic, truth=None, depth=args.depth_topic,
        fix=args.fix_topic, heading=args.heading_topic, water_density=args.water_density,
        surface_pressure=args.surface_pressure,
    )  # fmt: skip
    node = Node(topics, args.vehicle, args.init_seconds, args.strategy)
    callbacks = {  # topic → subscription callback (the IMU's wins for a heading on it)
        topics.dvl: node.on_dvl, topics.depth: node.on_pressure, topics.fix: node.on_fix,
        topics.heading: node.on_heading, topics.imu: node.on_imu,
    }  # fmt: skip
    with AnyReader([args.bag], default_typestore=get_typestore(Stores.LATEST)) as reader:
        subscribed = [c for c in reader.connections if c.topic in callbacks]
        for connection, _, raw in reader.messages(connections=subscribed):
            callbacks[connection.topic](reader.deserialize(raw, connection.msgtype))
    if node.nav is None:
        print(f"{args.bag}: not started: {node.why}")
        return 1
    node.print_tally()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
