"""How many cores this process may use: what sizes its thread and process pools.

``os.cpu_count()`` counts the machine's cores, not the ones this process may run on:
under ``taskset``, a container's cpuset or a batch scheduler's affinity mask it
overcounts, and pools sized by it queue their threads on fewer cores. rayon (the
core's Monte Carlo and inference threads) already sizes itself by the affinity mask.
"""

from __future__ import annotations

import os


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform has one,
    else the machine's count), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on this platform
        return max(1, os.cpu_count() or 1)
