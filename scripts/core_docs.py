"""Write the native core's runtime docstrings from its stub, ``python/pronet/_core.pyi``.

Usage::

    python scripts/core_docs.py          # rewrite the doc comments of rust/src/python/
    python scripts/core_docs.py --check  # exit 1 if a doc comment differs from the stub

The stub is the one source of the text: pyo3 turns the ``///`` comment of a
``#[pyclass]``, ``#[pyfunction]`` or ``#[pymethods]`` item into its ``__doc__``, so
each such comment is rewritten to be the stub's docstring of the same name (none where
the stub has none). ``tests/test_docs.py`` checks both the sources (``--check``) and the
built module (every ``__doc__`` equals the stub's). Only the standard library is used.
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUB = ROOT / "python" / "pronet" / "_core.pyi"
BINDINGS = ROOT / "rust" / "src" / "python"
CHECK_MESSAGE = (
    "rust/src/python doc comments differ from _core.pyi; run python scripts/core_docs.py"
)

FN = re.compile(r"^\s*(?:pub(?:\(\w+\))? )?fn (\w+)")
PYCLASS = re.compile(r'#\[pyclass\(name = "(\w+)"')
STRUCT = re.compile(r"^pub struct (\w+)")
IMPL = re.compile(r"^impl (\w+) \{")
PYFUNCTION = re.compile(r'#\[pyfunction(?:\(name = "(\w+)"\))?\]')


def stub_docs() -> dict[str, str]:
    """Docstring of every class, function and public member of the stub, by its name
    (``X`` or ``X.member``; ``""`` where there is none)."""
    out: dict[str, str] = {}
    for node in ast.parse(STUB.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            out[node.name] = ast.get_docstring(node) or ""
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                    out[f"{node.name}.{item.name}"] = ast.get_docstring(item) or ""
    return out


def _block_start(lines: list[str], i: int) -> int:
    """First line of the doc comments and attributes above the item at line ``i``."""
    j = i
    while j > 0:
        prev = lines[j - 1].strip()
        item_end = prev.endswith(("}", "{", ";")) and not prev.startswith(("///", "#["))
        if not prev or item_end or prev.startswith("//!"):
            break
        j -= 1
    return j


def _comment(doc: str, indent: str) -> list[str]:
    return [f"{indent}///{' ' + line if line else ''}" for line in doc.splitlines()]


def rewrite(text: str, docs: dict[str, str], found: set[str]) -> str:
    """``text`` (one binding file) with the doc comment of every item the stub names
    replaced by the stub's docstring; the names handled are added to ``found``."""
    lines = text.splitlines()
    classes = {}  # Rust struct -> Python class
    for i, line in enumerate(lines):
        m = PYCLASS.search(line)
        if m:
            k = next(k for k in range(i, len(lines)) if STRUCT.match(lines[k]))
            classes[STRUCT.match(lines[k]).group(1)] = (m.group(1), k)  # type: ignore[union-attr]
    targets: dict[int, str] = {}  # item line -> stub name
    for _struct, (name, k) in classes.items():
        targets[k] = name
    in_methods: str | None = None
    for i, line in enumerate(lines):
        m = IMPL.match(line)
        if m and i > 0 and lines[i - 1].strip() == "#[pymethods]":
            in_methods = classes[m.group(1)][0]
            continue
        if line == "}":
            in_methods = None
        fn = FN.match(line)
        if not fn:
            continue
        head = lines[_block_start(lines, i) : i]
        if in_methods is not None and line.startswith("    fn"):
            if any("#[new]" in h for h in head):
                continue
            targets[i] = f"{in_methods}.{fn.group(1)}"
        elif in_methods is None:
            py = next((PYFUNCTION.search(h) for h in head if PYFUNCTION.search(h)), None)
            if py is not None:
                targets[i] = py.group(1) or fn.group(1)
    out: list[str] = []
    done = 0
    for i in sorted(targets):
        name = targets[i]
        if name not in docs:
            continue
        found.add(name)
        start = _block_start(lines, i)
        out += lines[done:start]
        indent = lines[i][: len(lines[i]) - len(lines[i].lstrip())]
        out += _comment(docs[name], indent)
        out += [h for h in lines[start:i] if not h.strip().startswith("///")]
        done = i
    out += lines[done:]
    return "\n".join(out) + ("\n" if text.endswith("\n") else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a doc comment differs")
    args = parser.parse_args(argv)
    docs = stub_docs()
    found: set[str] = set()
    stale = []
    for path in sorted(BINDINGS.rglob("*.rs")):
        text = path.read_text(encoding="utf-8")
        new = rewrite(text, docs, found)
        if new != text:
            stale.append(path.relative_to(ROOT))
            if not args.check:
                path.write_text(new, encoding="utf-8")
    missing = sorted(set(docs) - found)
    if missing:
        print(f"stub names without a binding item: {missing}", file=sys.stderr)
        return 1
    if args.check:
        if stale:
            print(CHECK_MESSAGE, *stale, file=sys.stderr)
            return 1
        print("the bindings' doc comments are the stub's")
    else:
        print(f"rewrote {len(stale)} file(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
