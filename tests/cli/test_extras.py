"""The light install: without torch and scikit-learn (``pip install pronet`` without the
``torch`` extra) every native strategy, the shipped models (frozen in the core), sweeps
and ``pronet info`` work; training and evaluating the nets is one line naming the extra.

The commands run in a subprocess in which ``import torch`` and ``import sklearn`` fail
as they do when the packages are not installed (the wheel check in ``.ci/run`` does the
same in a fresh venv that never had them)."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: Runs ``pronet ARGS`` with torch and scikit-learn unimportable, then says on stderr
#: whether either was imported after all.
WITHOUT = """
import sys
from importlib.abc import MetaPathFinder

class Absent(MetaPathFinder):  # what an import finds when the packages are not installed
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in ("torch", "sklearn"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, Absent())
from pronet.cli import main
code = main(sys.argv[1:])
print("imported:", [m for m in ("torch", "sklearn") if m in sys.modules], file=sys.stderr)
sys.exit(code)
"""

SHORT = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0], [20, 0, 3, 0]]
"""


def without_torch(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", WITHOUT, *args], capture_output=True, text=True, cwd=cwd
    )


@pytest.mark.slow
def test_native_strategies_shipped_models_and_sweeps_need_no_torch(tmp_path) -> None:
    (tmp_path / "short.toml").write_text(SHORT)
    info = without_torch("info", cwd=tmp_path)
    assert info.returncode == 0 and "torch not installed" in info.stdout, info.stderr
    # learned:detvar is detvar (the two together are refused as one strategy twice)
    strategies = "constant,mehra:5,adaptive:20,oracle,learned:detvar,learned:hcf,"
    strategies += "learned:detrend"
    args = ["simulate", "--scenario", "short.toml", "--runs", "2", "--strategies", strategies]
    done = without_torch(*args, "--out", "sim", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr.endswith("imported: []\n"), done.stderr
    table = (tmp_path / "sim" / "table.md").read_text()
    assert all(f"| {s} |" in table for s in strategies.split(","))
    (tmp_path / "grid.toml").write_text(
        'scenarios = ["short.toml"]\nstrategies = ["constant", "learned:detrend"]\nruns = 2\n'
    )
    done = without_torch("sweep", "grid.toml", "--out", "swp", "--quiet", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr.endswith("imported: []\n"), done.stderr


@pytest.mark.parametrize(
    "args", [["train", "--model", "detrend"], ["train", "--model", "hcf"], ["evaluate"]]
)
def test_training_without_torch_is_one_line_naming_the_extra(tmp_path, args) -> None:
    done = without_torch(*args, "--quiet", cwd=tmp_path)
    lines = done.stderr.splitlines()
    assert done.returncode == 2 and len(lines) == 2, done.stderr  # the error, then our probe
    assert lines[0].startswith("pronet: ") and "pip install 'pronet[torch]'" in lines[0]
    assert list(tmp_path.iterdir()) == []  # refused before any work


def test_the_light_install_leaves_torch_and_scikit_learn_to_the_extra() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {d.split(">")[0].split("=")[0].strip() for d in project["dependencies"]}
    assert not names & {"torch", "scikit-learn"}
    extra = project["optional-dependencies"]["torch"]
    assert {d.split(">")[0] for d in extra} == {"torch", "scikit-learn"}
