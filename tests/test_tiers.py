"""The fast tier, ``pytest -m "not slow"`` (docs/how-to/development.md, "Tests"), covers every
test file: each ``tests/**/test_*.py`` holds at least one test that is not marked slow,
or says why not in a module constant ``ALL_SLOW_REASON = "…"`` (and then holds no fast
test, so the statement cannot go stale).

Read from the source with ``ast``. A test (a ``test*`` function at module level, or a
``test*`` method of a ``Test*`` class) is slow when ``pytest.mark.slow`` decorates it or
its class, when a ``pytestmark`` of its module or class holds the mark, or when one of
its ``parametrize`` lists holds only ``pytest.param(…, marks=pytest.mark.slow)`` cases.
A list that is not written out (a name, a call) counts as holding a fast case; the slow
test at the end checks the reading against pytest's own collection.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
#: The module constant that says why a test file has no fast test.
REASON = "ALL_SLOW_REASON"


def _dotted(node: ast.expr) -> str:
    """``pytest.mark.slow`` for that attribute chain, ``slow`` for a name, else ""."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return f"{head}.{node.attr}" if head else ""
    return ""


def _is_slow(node: ast.expr) -> bool:
    """The slow mark (``pytest.mark.slow`` or ``mark.slow``, called or not), or a list or
    tuple of marks that holds it."""
    if isinstance(node, ast.List | ast.Tuple):
        return any(_is_slow(e) for e in node.elts)
    if isinstance(node, ast.Call):
        node = node.func
    return _dotted(node) in ("pytest.mark.slow", "mark.slow")


def _assignments(body: list[ast.stmt]) -> Iterator[tuple[str, ast.expr]]:
    """``(name, value)`` of each ``name = value`` (or ``name: T = value``) among these
    statements."""
    for stmt in body:
        if isinstance(stmt, ast.Assign):
            yield from ((t.id, stmt.value) for t in stmt.targets if isinstance(t, ast.Name))
        elif isinstance(stmt, ast.AnnAssign) and stmt.value is not None:
            if isinstance(stmt.target, ast.Name):
                yield stmt.target.id, stmt.value


def _marks_slow(body: list[ast.stmt]) -> bool:
    """A ``pytestmark = …`` among these statements holds the slow mark."""
    return any(name == "pytestmark" and _is_slow(v) for name, v in _assignments(body))


def _slow_case(value: ast.expr) -> bool:
    """``pytest.param(…, marks=…)`` with the slow mark among its marks."""
    return (
        isinstance(value, ast.Call)
        and _dotted(value.func) in ("pytest.param", "param")
        and any(k.arg == "marks" and _is_slow(k.value) for k in value.keywords)
    )


def _only_slow_cases(decorator: ast.expr) -> bool:
    """A ``parametrize`` whose written-out cases are all marked slow."""
    if not isinstance(decorator, ast.Call):
        return False
    if _dotted(decorator.func) not in ("pytest.mark.parametrize", "mark.parametrize"):
        return False
    values = decorator.args[1] if len(decorator.args) > 1 else None
    values = next((k.value for k in decorator.keywords if k.arg == "argvalues"), values)
    if not isinstance(values, ast.List | ast.Tuple):
        return False  # built by code: taken to hold a fast case
    return all(_slow_case(v) for v in values.elts)


def _fast(test: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    return not any(_is_slow(d) or _only_slow_cases(d) for d in test.decorator_list)


def _tests(body: list[ast.stmt]) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    return [
        s
        for s in body
        if isinstance(s, ast.FunctionDef | ast.AsyncFunctionDef) and s.name.startswith("test")
    ]


def fast_tests(source: str) -> list[str]:
    """The tests of a test module's source that ``-m "not slow"`` keeps (a parametrized
    one once, by its function's name)."""
    tree = ast.parse(source)
    if _marks_slow(tree.body):
        return []
    fast = [t.name for t in _tests(tree.body) if _fast(t)]
    for cls in tree.body:
        if not isinstance(cls, ast.ClassDef) or not cls.name.startswith("Test"):
            continue
        if any(_is_slow(d) for d in cls.decorator_list) or _marks_slow(cls.body):
            continue
        fast += [f"{cls.name}.{t.name}" for t in _tests(cls.body) if _fast(t)]
    return fast


def all_slow_reason(source: str) -> str | None:
    """The module's ``ALL_SLOW_REASON``, None without one ("" when it is not a string
    literal)."""
    for name, value in _assignments(ast.parse(source).body):
        if name == REASON:
            if isinstance(value, ast.Constant) and isinstance(value.value, str):
                return value.value
            return ""  # not a string literal
    return None


def suite_files(folder: Path) -> list[Path]:
    return sorted(folder.rglob("test_*.py"))


def problems(folder: Path) -> list[str]:
    """What breaks the rule in the test files under ``folder``, one line each."""
    found = []
    for path in suite_files(folder):
        name = path.relative_to(folder).as_posix()
        source = path.read_text()
        fast, reason = fast_tests(source), all_slow_reason(source)
        if reason is not None and not reason.strip():
            found.append(f"{name}: {REASON} must say why, in a string literal")
        elif fast and reason is not None:
            found.append(f"{name}: has fast tests ({fast[0]}, …) and says {REASON}; drop it")
        elif not fast and reason is None:
            found.append(
                f"{name}: every test is marked slow; keep one fast (not slow) test, or say "
                f'why not: {REASON} = "…"'
            )
    return found


def test_every_test_file_has_a_fast_test_or_says_why_not() -> None:
    assert len(suite_files(TESTS)) > 50  # the walk sees the suite
    assert problems(TESTS) == []


def test_the_reading_sees_each_way_of_marking_a_test_slow() -> None:
    test = "def test_a(): pass\n"
    assert fast_tests(test) == ["test_a"]
    assert fast_tests("@pytest.mark.slow\n" + test) == []
    assert fast_tests("@pytest.mark.slow()\n" + test + "def test_b(): pass\n") == ["test_b"]
    assert fast_tests("pytestmark = pytest.mark.slow\n" + test) == []
    assert fast_tests("pytestmark = [pytest.mark.x, pytest.mark.slow]\n" + test) == []
    assert fast_tests("pytestmark: list = [pytest.mark.x]\n" + test) == ["test_a"]
    method = "class TestA:\n    def test_a(self): pass\n"
    assert fast_tests(method) == ["TestA.test_a"]
    assert fast_tests("@pytest.mark.slow\n" + method) == []
    assert fast_tests(method.replace(":\n", ":\n    pytestmark = pytest.mark.slow\n", 1)) == []
    assert fast_tests(method.replace("TestA", "Helper")) == []  # not collected
    cases = (
        '@pytest.mark.parametrize("x", [pytest.param(1, marks=pytest.mark.slow), {}])\n'
        "def test_a(x): pass\n"
    )
    assert fast_tests(cases.format("2")) == ["test_a"]
    assert fast_tests(cases.format("pytest.param(2, marks=[pytest.mark.slow])")) == []
    assert fast_tests(cases.format("pytest.param(2, marks=pytest.mark.skip)")) == ["test_a"]
    two = '@pytest.mark.parametrize("y", [pytest.param(3, marks=pytest.mark.slow)])\n'
    assert fast_tests(two + cases.format("2")) == []  # every case has a slow y
    assert fast_tests('@pytest.mark.parametrize("x", CASES)\ndef test_a(x): pass\n') == ["test_a"]


def test_the_rule_fails_on_an_all_slow_file_that_does_not_say_why(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    file = tmp_path / "sub" / "test_x.py"
    file.write_text("import pytest\n\n\n@pytest.mark.slow\ndef test_long(): pass\n")
    (tmp_path / "helpers.py").write_text("def test_not_a_test_file(): pass\n")
    assert problems(tmp_path) == [
        "sub/test_x.py: every test is marked slow; keep one fast (not slow) test, or say why "
        'not: ALL_SLOW_REASON = "…"'
    ]
    file.write_text(f'{REASON} = "builds a crate"\n' + file.read_text())
    assert problems(tmp_path) == []
    file.write_text(file.read_text() + "\n\ndef test_quick(): pass\n")
    assert problems(tmp_path) == [
        f"sub/test_x.py: has fast tests (test_quick, …) and says {REASON}; drop it"
    ]
    file.write_text(f'{REASON} = ""\n@pytest.mark.slow\ndef test_long(): pass\n')
    assert problems(tmp_path) == [f"sub/test_x.py: {REASON} must say why, in a string literal"]


@pytest.mark.slow
def test_the_reading_agrees_with_pytest_s_collection() -> None:
    """The files the reading finds a fast test in are those in which pytest collects a
    test under ``-m "not slow"`` (a collection of the whole suite: some ten seconds)."""
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "not slow",
         "-p", "no:cacheprovider", str(TESTS)],
        capture_output=True, text=True, cwd=ROOT, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    collected = {line.split("::")[0] for line in done.stdout.splitlines() if "::" in line}
    read = {
        path.relative_to(ROOT).as_posix()
        for path in suite_files(TESTS)
        if fast_tests(path.read_text())
    }
    assert collected == read


def test_the_files_collected_first_exist() -> None:
    """conftest's ``LONGEST_FIRST`` names test files that exist: a renamed file would
    otherwise fall back to the end of the collection without a word."""
    from conftest import LONGEST_FIRST

    missing = [name for name in LONGEST_FIRST if not (TESTS / name).is_file()]
    assert not missing, f"conftest.LONGEST_FIRST names files that are gone: {missing}"
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
