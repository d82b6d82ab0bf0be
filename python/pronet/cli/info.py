"""``pronet info``: versions, cores and threads, where the weights live, trajectories."""

from __future__ import annotations

import argparse
import json
import os
import sys

import pronet
from pronet import _core
from pronet._util.cores import usable_cores
from pronet.cli._common import Subparsers


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "info", help="versions, cores and threads, where the weights live, trajectories"
    )
    parser.add_argument("--json", action="store_true", help="print it as JSON, for scripts")
    parser.set_defaults(func=run)


def _version_of(package: str) -> str | None:
    """The installed version of ``package``, or None; without importing it."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return None


def run(args: argparse.Namespace) -> int:
    import numpy

    from pronet.learn import frozen, modelfile

    torch_version, torch_threads = None, None
    try:
        import torch

        torch_version, torch_threads = str(torch.__version__), torch.get_num_threads()
    except ImportError:  # the light install: everything but training and torch nets
        pass
    info: dict[str, object] = {
        "pronet": pronet.__version__,
        "native_core": _core.__version__,
        "python": sys.version.split()[0],
        "numpy": numpy.__version__,
        "torch": torch_version,
        "cores": usable_cores(),
        "threads": _core.check_threads(None),  # RAYON_NUM_THREADS if set (checked)
        "max_threads": _core.max_threads(),
        "torch_threads": torch_threads,
        "ray": _version_of("ray"),
        "weights": str(modelfile.SHIPPED_DIR),
        "shipped_models": list(frozen.SHIPPED),
        "trajectories": list(_core.builtin_trajectory_names()),
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    no_torch = "not installed (training needs it: pip install 'pronet[torch]')"
    print(f"pronet {info['pronet']} (native core {info['native_core']})")
    print(f"python {info['python']}, numpy {info['numpy']}, torch {info['torch'] or no_torch}")
    threads = f"; torch uses {torch_threads}" if torch_threads is not None else ""
    source = _core.THREADS_ENV if _core.THREADS_ENV in os.environ else "one per core"
    print(
        f"cores: {info['cores']}  (threads: {info['threads']} by default, from {source}; "
        f"at most {info['max_threads']}{threads})"
    )
    print(f"ray: {info['ray'] or 'not installed (pronet sweep --engine ray needs it)'}")
    print(f"shipped models: {', '.join(frozen.SHIPPED)} in {info['weights']}")
    print(f"built-in trajectories: {', '.join(_core.builtin_trajectory_names())}")
    return 0
