"""A real, multi-process Ray cluster on this machine: a head (``ray start --head``) and
a second node (``ray start --address``), each its own set of processes listening on the
loopback only. ``pronet sweep --engine ray --address`` gives the local engine's
``metrics.csv`` byte for byte, also when a worker process is killed in the middle of a
shard (Ray runs the shard again; shards are deterministic).

The nodes run with ``--block``, so that stopping their ``ray start`` processes stops
every process they started and no other Ray on the machine is touched. Where the
machine allows it (root, ``unshare``), the nodes and the sweep run in a network
namespace of their own whose only interface is the loopback: Ray binds its GCS and
raylet ports on every interface whatever ``--node-ip-address`` says, and there every
interface is the loopback. Elsewhere they run in the machine's namespace. Ray ≥ 2.59
turns token authentication on for such clusters: the nodes and the sweep share a token
of this test's own (``RAY_AUTH_MODE=token``, ``RAY_AUTH_TOKEN``), as every client of a
real cluster must (docs/how-to/sweeps.md)."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Why no test here is in the fast tier (tests/test_tiers.py).
ALL_SLOW_REASON = "its one test starts a two-node Ray cluster and sweeps on it"
RAY = Path(sys.executable).parent / "ray"

#: Shards long enough (about a second each) to be killed while they run.
SCENARIO = """
name = "long"
[trajectory]
segments = [[120, 0, 0, 0], [120, 0, 2, 0]]
"""
GRID = """
scenarios = ["long.toml"]
strategies = ["constant", "mehra:5"]
noise_levels = [1, 4]
runs = 12
shard_runs = 3
seed = 5
"""


#: Every port this module has handed out: the kernel may give a closed port again, and
#: Ray refuses to start when two of its components are given the same one.
_GIVEN: set[int] = set()


def free_port() -> int:
    """A free port on the loopback, none handed out before in this process."""
    while True:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = int(s.getsockname()[1])
        if port not in _GIVEN:
            _GIVEN.add(port)
            return port


#: The environment of the nodes and of the sweep: token authentication, this test's token.
ENV = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16)}


@pytest.fixture
def inside() -> Iterator[list[str]]:
    """The prefix that runs a command in a network namespace with only the loopback
    (``nsenter`` into one held by a sleeping process), or ``[]`` where namespaces
    cannot be made here."""
    tools = all(shutil.which(t) for t in ("unshare", "nsenter", "ip"))
    if not tools or subprocess.run(["unshare", "-n", "true"], capture_output=True).returncode:
        yield []
        return
    hold = "ip link set lo up && exec sleep 3600"
    holder = subprocess.Popen(["unshare", "-n", "--", "sh", "-c", hold])
    prefix = ["nsenter", "-t", str(holder.pid), "-n", "--"]

    def lo_up() -> bool:
        shown = subprocess.run([*prefix, "ip", "link", "show", "lo"], capture_output=True)
        return b"UP" in shown.stdout

    try:
        wait_for(lo_up, 10, "the loopback of the test's network namespace did not come up")
        yield prefix
    finally:
        holder.kill()
        holder.wait()


def start_node(args: list[str], log: Path, inside: list[str]) -> subprocess.Popen[bytes]:
    """``ray start --block ARGS`` on the loopback, one CPU, its own agent ports."""
    ports = [
        f"--dashboard-agent-listen-port={free_port()}",
        f"--dashboard-agent-grpc-port={free_port()}",
        f"--runtime-env-agent-port={free_port()}",
        f"--metrics-export-port={free_port()}",
    ]
    cmd = [*inside, str(RAY), "start", "--block", "--node-ip-address=127.0.0.1", "--num-cpus=1"]
    cmd += ["--disable-usage-stats", *ports, *args]
    with log.open("wb") as out:
        return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=ENV)


def stop(node: subprocess.Popen[bytes]) -> None:
    if node.poll() is None:
        node.send_signal(signal.SIGTERM)
        try:
            node.wait(timeout=30)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait()


def shard_workers() -> list[int]:
    """Processes running a shard now: Ray names a worker after the task it runs."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if cmdline.startswith(b"ray::run_shard"):
                found.append(int(entry.name))
    return found


def wait_for(what, timeout: float, message: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = what()
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(message)


@pytest.fixture
def cluster(tmp_path, inside) -> Iterator[str]:
    """A head and a second node on this machine; yields the head's address."""
    port = free_port()
    temp = Path(os.environ.get("TMPDIR", "/tmp")) / f"pronet-ray-{port}"  # short: socket paths
    head = start_node(
        ["--head", f"--port={port}", "--include-dashboard=false", f"--temp-dir={temp}"],
        tmp_path / "head.log",
        inside,
    )
    nodes = [head]
    try:
        address = f"127.0.0.1:{port}"
        wait_for(
            lambda: _reachable(port, inside), 60, f"the head did not start: {tmp_path / 'head.log'}"
        )
        nodes.append(start_node([f"--address={address}"], tmp_path / "node.log", inside))
        yield address
    finally:
        for node in reversed(nodes):
            stop(node)
        subprocess.run(["rm", "-rf", str(temp)], check=False)


def _reachable(port: int, inside: list[str]) -> bool:
    """Whether something listens on 127.0.0.1:port, seen from where the nodes run."""
    if not inside:
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", port)) == 0
    probe = f"import socket, sys; sys.exit(socket.socket().connect_ex(('127.0.0.1', {port})))"
    return subprocess.run([*inside, sys.executable, "-c", probe]).returncode == 0


@pytest.mark.slow
def test_a_sweep_on_a_real_cluster_survives_a_killed_worker(tmp_path, cluster, inside) -> None:
    (tmp_path / "long.toml").write_text(SCENARIO)
    (tmp_path / "grid.toml").write_text(GRID)
    sweep = [sys.executable, "-m", "pronet.cli", "sweep", "grid.toml", "--quiet"]
    local = subprocess.run([*sweep, "--out", "local"], cwd=tmp_path, capture_output=True, env=ENV)
    assert local.returncode == 0, local.stderr
    if inside:  # the nodes' namespace has no interface but the loopback
        addresses = subprocess.run([*inside, "ip", "-o", "addr"], capture_output=True, text=True)
        assert {line.split()[1] for line in addresses.stdout.splitlines()} == {"lo"}
    on_ray = subprocess.Popen(
        [*inside, *sweep, "--engine", "ray", "--address", cluster, "--out", "ray"],
        cwd=tmp_path,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    try:
        victims = wait_for(shard_workers, 120, "no worker ever ran a shard")
        os.kill(victims[0], signal.SIGKILL)
        _, err = on_ray.communicate(timeout=300)
    finally:
        if on_ray.poll() is None:
            on_ray.kill()
    assert on_ray.returncode == 0, err
    assert (tmp_path / "ray" / "metrics.csv").read_bytes() == (
        tmp_path / "local" / "metrics.csv"
    ).read_bytes()
