"""The accuracy gate catches the regressions it exists for: a mistyped physical constant
(two of them) and one flipped sign in the error-state Jacobian.

Each mutant is the real source with one edit, built as its own native module (its own
library name, so the project's build is never touched) and run through the gate in a
subprocess that imports it in place of the installed one. The gate is the script
``tests/accuracy_gate.py`` that ``test_accuracy_gate`` runs, on the rows a mutant can be
judged by quickly (``--strategies``): the at-rest row and the constant-Q row of both
simulated scenarios. The simulated rows alone cannot
see the constant (their truth is generated with it; the change there is ~1e-8
relative), which is why the at-rest row exists.
"""

from __future__ import annotations

import fcntl
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: name → (file, original text, mutated text). Each original must occur exactly once.
MUTANTS = {
    # A dropped digit in the Earth rotation rate (7.292115e-5 rad/s).
    "earth rate typo": (
        "rust/src/earth.rs",
        "pub const OMEGA_IE: f64 = 7.292_115e-5;",
        "pub const OMEGA_IE: f64 = 7.292_15e-5;",
    ),
    # Two digits swapped in normal gravity at the equator (9.7803253359 m/s²).
    "gravity typo": (
        "rust/src/earth.rs",
        "pub const GAMMA_EQUATOR: f64 = 9.780_325_335_9;",
        "pub const GAMMA_EQUATOR: f64 = 9.780_352_335_9;",
    ),
    # The Coriolis block of ∂δv̇/∂δv with its sign flipped.
    "Jacobian sign (Coriolis)": (
        "rust/src/ekf/dynamics.rs",
        "vel_vel: -skew(&(2.0 * rates.earth + rates.transport)),",
        "vel_vel: skew(&(2.0 * rates.earth + rates.transport)),",
    ),
}

#: The gate script, on the rows a mutant can be judged by quickly.
GATE = [str(ROOT / "tests" / "accuracy_gate.py"), "--strategies", "constant (true q)"]
#: The gate's last line: ``N departures from FILE (T s)``.
SUMMARY = re.compile(r"^(\d+) departures from ")


def mutant_source(src: Path) -> None:
    """A copy of the project's sources at ``src`` whose library is named
    ``pronet_mutant``, every mutation site as in the project."""
    shutil.copytree(ROOT / "rust", src / "rust")
    shutil.copytree(ROOT / "benches", src / "benches")  # the manifest names its benchmark
    shutil.copytree(
        ROOT / "python", src / "python", ignore=shutil.ignore_patterns("_core*.so", "__pycache__")
    )
    for kept in ("Cargo.lock", "pyproject.toml", "README.md"):
        shutil.copy(ROOT / kept, src)
    manifest = (ROOT / "Cargo.toml").read_text()
    lib = 'name = "pronet"\npath'
    assert manifest.count(lib) == 1, "Cargo.toml: the [lib] name moved"
    (src / "Cargo.toml").write_text(manifest.replace(lib, 'name = "pronet_mutant"\npath'))


def build_mutant(name: str, src: Path, tmp: Path) -> Path:
    """The package, its native module built from the sources at ``src``
    (:func:`mutant_source`) with the one edit of mutant ``name``, unpacked under ``tmp``."""
    for file in {f for f, _, _ in MUTANTS.values()}:  # every other mutant's edit undone
        shutil.copy(ROOT / file, src / file)
    file, original, mutated = MUTANTS[name]
    text = (src / file).read_text()
    assert text.count(original) == 1, f"{file}: the mutation site moved; update MUTANTS[{name!r}]"
    (src / file).write_text(text.replace(original, mutated))

    # Built as scripts/bootstrap.sh builds the installed module (maturin, zig for
    # manylinux2014) into the project's target folder: the dependencies are that build's,
    # not compiled again. The mutant's own code at opt-level 1: the same arithmetic (Rust
    # does not reorder floating point at any level), built in 21 s of CPU instead of 29 s,
    # and the gate's few rows run as fast. Incrementally, in 64 codegen units, from the one
    # source folder every mutant is built in: the second and third build again only what
    # their edit reaches (the file's three mutants: 81 s of CPU, against 103 s each built
    # afresh in one unit).
    # maturin finds zig as `python -m ziglang` of the first python on PATH: this one's.
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    cmd = [sys.executable, "-m", "maturin", "build", "--quiet", "--release", "--zig"]
    cmd += ["--compatibility", "manylinux2014", "--interpreter", sys.executable]
    cmd += ["--config", "profile.release.package.pronet.opt-level=1"]
    cmd += ["--config", "profile.release.package.pronet.incremental=true"]
    cmd += ["--config", "profile.release.package.pronet.codegen-units=64"]
    cmd += ["--manifest-path", str(src / "Cargo.toml"), "--target-dir", str(ROOT / "target")]
    cmd += ["--out", str(tmp / "dist")]
    subprocess.run(cmd, check=True, env=env)
    (wheel,) = (tmp / "dist").glob("*.whl")
    site = tmp / "site"
    with zipfile.ZipFile(wheel) as z:
        z.extractall(site)
    return site


@pytest.fixture(scope="module")
def source() -> Iterator[Path]:
    """The one source folder the mutants are built in, one after another. It is always
    the same folder, under the project's target folder: a session's builds start from
    the last session's incremental state instead of leaving 134 MB more of it behind.
    Locked, so that another session's mutants wait for these."""
    root = ROOT / "target" / "mutant"
    root.mkdir(parents=True, exist_ok=True)
    with open(root / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        src = root / "src"
        shutil.rmtree(src, ignore_errors=True)
        mutant_source(src)
        yield src


def test_each_mutation_site_is_in_the_source_once() -> None:
    """The fast half: each mutant's original text occurs exactly once in its file, and
    the edit changes it, so a moved site shows without building anything."""
    for name, (file, original, mutated) in MUTANTS.items():
        text = (ROOT / file).read_text()
        assert text.count(original) == 1, f"{file}: the mutation site moved; update {name!r}"
        assert mutated != original, name


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("cargo") is None
    or importlib.util.find_spec("maturin") is None
    or importlib.util.find_spec("ziglang") is None,
    reason="needs cargo, maturin and ziglang (scripts/bootstrap.sh) to build the mutants",
)
@pytest.mark.parametrize("name", list(MUTANTS))
def test_the_gate_fails_on_a_mutant(name, source, tmp_path):
    site = build_mutant(name, source, tmp_path)
    env = {**os.environ, "PYTHONPATH": str(site)}
    out = subprocess.run(
        [sys.executable, *GATE], capture_output=True, text=True, env=env, cwd=tmp_path
    )
    lines = out.stdout.splitlines()
    assert out.returncode == 1, f"{name}: exit {out.returncode}: {out.stdout}{out.stderr}"
    core = lines[0].removeprefix("native core: ")
    assert Path(core).is_relative_to(site), "the mutant was not the module imported"
    summary = SUMMARY.match(lines[-1])
    assert summary, out.stdout
    problems = lines[1:-1]
    assert len(problems) == int(summary.group(1)) > 0, f"{name}: the gate passed a mutant"
    assert all("worse" in p or "improved" in p for p in problems)
    print(f"{name}: {len(problems)} departures, e.g. {problems[0]}")
