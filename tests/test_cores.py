"""The cores a process may use: its affinity, not the machine's count."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

from pronet._util import cores
from pronet._util.cores import usable_cores


def test_the_count_is_the_affinity_mask_and_falls_back_to_the_machine(monkeypatch):
    monkeypatch.setattr(cores.os, "sched_getaffinity", lambda pid: {0, 3, 5}, raising=False)
    assert usable_cores() == 3
    monkeypatch.setattr(cores.os, "sched_getaffinity", lambda pid: set(), raising=False)
    assert usable_cores() == 1

    def unsupported(pid):
        raise OSError("no affinity here")

    monkeypatch.setattr(cores.os, "sched_getaffinity", unsupported, raising=False)
    for machine, expected in [(None, 1), (1, 1), (6, 6)]:
        monkeypatch.setattr(cores.os, "cpu_count", lambda m=machine: m)
        assert usable_cores() == expected
    monkeypatch.delattr(cores.os, "sched_getaffinity")  # macOS, Windows
    assert usable_cores() == 6


@pytest.mark.skipif(
    shutil.which("taskset") is None or not hasattr(os, "sched_getaffinity"),
    reason="needs taskset and CPU affinity",
)
def test_a_process_pinned_to_one_core_counts_one():
    code = "from pronet._util.cores import usable_cores; print(usable_cores())"
    out = subprocess.run(
        ["taskset", "-c", "0", sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "1"
    assert usable_cores() == len(os.sched_getaffinity(0))
