"""The Python blocks of the README and the docs pages run as written: the README's
quick start as one session, and each page's blocks as one session of their own (after
the blocks of the page it continues, :data:`CONTINUES`). The examples the pages show
whole (between ``example-`` markers) are scripts, run by ``tests/test_examples.py``."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PYTHON_BLOCK = re.compile(r"```python\n(.*?)```", flags=re.S)
#: A script of examples/ shown whole in a page (scripts/example_docs.py).
EXAMPLE = re.compile(r"<!-- (example-[\w-]+):begin -->.*?<!-- \1:end -->", flags=re.S)


def python_blocks(page: Path) -> list[str]:
    """The page's Python blocks, but for the examples it shows whole."""
    return PYTHON_BLOCK.findall(EXAMPLE.sub("", page.read_text(encoding="utf-8")))


def run_blocks(page: Path, namespace: dict[str, object] | None = None) -> dict[str, object]:
    """Run every ```python block of ``page`` in order, in one namespace (``namespace``, or a
    new one), and return it."""
    blocks = python_blocks(page)
    assert blocks, f"{page.relative_to(ROOT)} has no Python block"
    namespace = {"__name__": "__docs__"} if namespace is None else namespace
    for code in blocks:
        exec(compile(code, str(page), "exec"), namespace)  # noqa: S102 - our own pages
    return namespace


def pages_with_python() -> list[Path]:
    pages = sorted((ROOT / "docs").rglob("*.md"))
    return [p for p in pages if python_blocks(p)]


@pytest.mark.slow
def test_readme_quick_start_runs() -> None:
    namespace = run_blocks(README)
    assert namespace["res"].summary()["srmse"].mean < 0.1


def test_the_docs_pages_have_python_to_run() -> None:
    # The page check below must see real pages, or it passes vacuously.
    names = {_key(p) for p in pages_with_python()}
    assert set(CHECKS) <= names


def _learning_md(ns: dict) -> None:
    assert ns["hyb"].result.summary()["srmse"].mean < 5.0


def _cli_md(ns: dict) -> None:
    assert len(ns["df"]) == 4  # 2 strategies x 2 noise levels
    assert len(ns["runs"]) == 16  # x 4 runs


def _ros_bags_md(ns: dict) -> None:
    assert ns["rec"].name == "mission" and len(ns["rec"].imu) > 0
    assert Path("mission-csv").is_dir()


def _own_vehicle_md(ns: dict) -> None:
    # the depth-and-fixes example: a GNSS/INS dive without a DVL, and the run of it
    assert len(ns["dive"].dvl) == 0 and len(ns["dive"].fixes.time) == 8
    constant = "constant (estimated q)"
    assert f"{constant}, smoothed" in ns["aided"].index
    assert ns["aided"][constant] < ns["final"]["depth-only"][constant] / 3


def _navigate_md(ns: dict) -> None:
    assert (Path("nav") / "trajectory.csv").is_file() and (Path("nav") / "report.md").is_file()
    names = {s.name for s in ns["nav"].streams}
    assert names == {"dvl", "depth", "fix", "heading"}
    # every stream told its noise: its NIS per degree of freedom near 1 (a 3-minute
    # recording's band is wide and may be left by chance; the flag says so, not this)
    assert all(0.7 < s.mean_nis / s.dof < 1.3 for s in ns["nav"].streams)


def _online_md(ns: dict) -> None:
    # the online navigator, fed the same recording, ends where the navigate pass does
    state, forward = ns["online"].state(), ns["nav"].forward
    assert state.time == forward.time[-1] and np.array_equal(state.lla, forward.lla[-1])
    assert all(t.refused == 0 and t.accepted > 0 for t in ns["online"].tally())


#: What each page's session must have produced, beyond running without an error.
CHECKS = {
    "reference/learning.md": _learning_md,
    "how-to/sweeps.md": _cli_md,
    "how-to/own-vehicle.md": _own_vehicle_md,
    "how-to/ros-bags.md": _ros_bags_md,
    "tutorials/navigate.md": _navigate_md,
    "how-to/online.md": _online_md,
}


def _dive_files() -> None:
    """how-to/own-vehicle.md's worked example reads ``dive/`` (a folder of IMU,
    ground-truth, depth and fix CSVs, no DVL), written here (the current folder is a
    temporary one) from a simulated recording."""
    from dataclasses import replace

    import numpy as np

    from pronet.recorded.recordings import write_recording

    from synthetic_recording import synthetic_recording, with_aiding

    dive = with_aiding(synthetic_recording(seed=5, duration=240.0, name="dive"), seed=5)
    write_recording("dive", replace(dive, dvl=np.empty((0, 3)), dvl_time=np.empty(0)))


def _bag_files() -> None:
    """how-to/ros-bags.md's worked example reads ``mission.bag`` (a ROS 1 bag), written
    here from a simulated recording."""
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra is not installed")
    from ros_bag import write_bag
    from synthetic_recording import synthetic_recording

    recording = synthetic_recording(seed=3, name="mission").recording
    write_bag(Path("mission.bag"), recording, "rosbag1")


def _navigate_files() -> None:
    """tutorials/navigate.md's examples (and how-to/online.md's after them) read
    ``mission/`` (a 3-minute simulated MEMS survey, no truth;
    ``tests/mission_recording.py``, its sensors where the page's vehicle file puts them)
    and ``vehicle.toml``, the tutorial's own TOML block."""
    from mission_recording import simulate_mission, write_generic

    write_generic(simulate_mission(0, minutes=3.0), Path("mission"))
    page = (ROOT / "docs" / "tutorials" / "navigate.md").read_text(encoding="utf-8")
    (toml,) = re.findall(r"```toml\n(.*?)```", page, flags=re.S)
    Path("vehicle.toml").write_text(toml)


#: What a page's blocks read, made in a temporary current folder before they run.
SETUP = {
    "how-to/own-vehicle.md": _dive_files,
    "how-to/ros-bags.md": _bag_files,
    "tutorials/navigate.md": _navigate_files,
    "how-to/online.md": _navigate_files,
}
#: A page that continues another: the other's blocks run first, in the same namespace.
CONTINUES = {"how-to/online.md": "tutorials/navigate.md"}


def _key(page: Path) -> str:
    """A page's path under docs/ (``tutorials/navigate.md``)."""
    return page.relative_to(ROOT / "docs").as_posix()


@pytest.mark.parametrize("page", pages_with_python(), ids=_key)
def test_docs_python_blocks_run(page: Path, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    key = _key(page)
    SETUP.get(key, lambda: None)()
    namespace: dict[str, object] = {"__name__": "__docs__"}
    if key in CONTINUES:
        run_blocks(ROOT / "docs" / CONTINUES[key], namespace)
    namespace = run_blocks(page, namespace)
    CHECKS.get(key, lambda ns: None)(namespace)
