"""The Rust crate's layout (docs/how-to/development.md, "Layout"; the design's "In Rust the same
rule"): no import circle between the files of ``rust/src``, each top-level module placed
in one layer and importing only its own layer and the layers below, no file over 600 lines.

The imports are read from the source text, without a Rust toolchain. Comments and the
insides of string and char literals are blanked first (a lifetime ``'a`` is not a char),
then everything under ``#[cfg(test)]``: files declared only as test modules, inline
``mod tests { ... }`` blocks and single test items, since test code may reach anywhere.
What is left counts, inside functions too: every ``use`` declaration at any visibility
and every path in the code (``crate::sensors::DvlDropout``,
``super::super::FilterConfig::default()``). A path is resolved much as rustc does, segment by
segment through the module tree (``mod x;`` with ``#[path]``, inline ``mod x { ... }``),
following ``use`` and ``pub use`` bindings and globs to the file that *defines* the name
(struct, enum, fn, trait, type, const, static, union, macro_rules), so a facade that only
declares modules and re-exports ties no circle. A path that names a module leads to that
module's file. Declaring a child (``mod x;``) is containment, not an import.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from import_graph import import_circles

SRC = Path(__file__).resolve().parents[1] / "rust" / "src"
#: The crate's top-level modules (each ``mod`` of ``lib.rs``), lowest layer first. A file
#: belongs to its top-level module's layer (``smoother/steps.rs``: ``smoother``) and
#: imports only files of its own layer or of the layers before it; ``lib.rs`` is exempt.
#: The order (docs/how-to/development.md, "The Rust crate, room by room"): utilities, the Earth
#: and attitude → ``mechanization`` → ``trajectory`` → the filter ``ekf`` → the
#: measurements and the noise strategies → the simulated ``sensors`` (readings as the
#: filter reads them) → the one epoch loop ``pass`` → the ``smoother`` → the drivers
#: (``recorded``, ``scenario``, ``run``) → ``montecarlo``/``ensemble`` → ``python``. A
#: new module goes in here; a module that moves, moves here too.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("error", "cancel", "threads", "memory", "pages"),
    ("attitude", "earth", "clocks", "regressors"),
    ("mechanization",),
    ("trajectory",),
    ("ekf",),
    ("measurement", "noise"),
    ("sensors",),
    ("pass",),
    ("smoother",),
    ("recorded", "scenario", "run"),
    ("montecarlo", "ensemble"),
    ("online",),
    ("python",),
)
MAX_LINES = 600

SPECIAL = re.compile(r"""//|/\*|(?<!\w)b?r(#*)"|"|'""")
STRING_BODY = re.compile(r'(?:[^"\\]|\\.)*', re.S)
CHAR = re.compile(r"'(?:\\(?:u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\\n])'")
BLOCK_COMMENT = re.compile(r"/\*|\*/")
CFG_TEST = re.compile(r"#\s*\[\s*cfg\s*\(\s*test\s*\)\s*\]")
BRACKET = re.compile(r"[(\[{)\]};]")
SPACE = re.compile(r"\s*")
PUB_IN = re.compile(r"pub\s*\(\s*in\s+[^)]*\)")
INLINE_MOD = re.compile(r"\bmod\s+(\w+)\s*\{")
MOD_DECL = re.compile(r"((?:#\[[^\]]*\]\s*)*)(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;")
ITEM = re.compile(
    r"\s*(?:pub(?:\([^)]*\))?\s+)?(?:(?:const|async|unsafe|extern)\s+)*"
    r"(?:(?:struct|enum|fn|trait|type|const|static|union)\s+(?:mut\s+)?|macro_rules!\s*)(\w+)"
)
MACRO = re.compile(r"macro_rules!\s*\w+\s*(?=[({\[])")
INVOCATION = re.compile(r"\s*(?!macro_rules!)\w+!\s*[({\[]")
USE = re.compile(r"\buse\s+([^;]*);")
PATH = re.compile(r"(?<![\w:])[A-Za-z_]\w*(?:::[A-Za-z_]\w*)+")


def _blank(code: str, start: int, end: int) -> str:
    """``code`` with ``[start, end)`` turned to spaces, its newlines kept."""
    return code[:start] + re.sub(r"[^\n]", " ", code[start:end]) + code[end:]


def _code(raw: str) -> str:
    """``raw`` with comments and the insides of string and char literals blanked; the
    same length and lines, so an offset in one is the same place in the other."""
    out, i = raw, 0
    while m := SPECIAL.search(raw, i):
        start, token = m.start(), m.group()
        if token == "//":
            end = len(raw) if (newline := raw.find("\n", start)) < 0 else newline
            out = _blank(out, start, end)
        elif token == "/*":
            depth, end = 0, len(raw)
            for c in BLOCK_COMMENT.finditer(raw, start):
                depth += 1 if c.group() == "/*" else -1
                if depth == 0:
                    end = c.end()
                    break
            out = _blank(out, start, end)
        elif token == "'":  # a char literal; else a lifetime or a label, kept
            char = CHAR.match(raw, start)
            end = char.end() if char else start + 1
            if char:
                out = _blank(out, start + 1, end - 1)
        elif token == '"':
            close = STRING_BODY.match(raw, start + 1).end()  # type: ignore[union-attr]
            out, end = _blank(out, start + 1, close), close + 1
        else:  # a raw string, r"..." or r#"..."#
            close = raw.find('"' + m.group(1), m.end())
            out, end = _blank(out, m.end(), close), close + 1 + len(m.group(1))
        i = end
    return out


def _end(code: str, i: int) -> int:
    """Where the attribute, block or item starting at ``i`` ends: after its matching
    ``]`` or ``}``, or after the ``;`` that ends it."""
    depth = 0
    for m in BRACKET.finditer(code, i):
        if m.group() in "([{":
            depth += 1
        elif m.group() in ")]}":
            depth -= 1
            if depth == 0 and (m.group() == "}" or code[i] == "#"):
                return m.end()
        elif depth == 0:
            return m.end()
    return len(code)


def _without_tests(code: str) -> str:
    """``code`` with each ``#[cfg(test)]`` item blanked, with its other attributes."""
    while m := CFG_TEST.search(code):
        i = m.end()
        while code.startswith("#", i := SPACE.match(code, i).end()):  # type: ignore[union-attr]
            i = _end(code, i)
        code = _blank(code, m.start(), _end(code, i))
    return code


def _depth(code: str, i: int) -> int:
    return code.count("{", 0, i) - code.count("}", 0, i)


def _use_tree(text: str) -> list[tuple[list[str], str]]:
    """The leaves of a use tree with the name each binds: ``a::{b, c::{self, d as e},
    f::*}`` gives ``[a, b]`` b, ``[a, c]`` c, ``[a, c, d]`` e, ``[a, f, *]`` *."""
    tokens = re.findall(r"\w+|[{},*]", text)
    leaves: list[tuple[list[str], str]] = []

    def walk(prefix: list[str], k: int) -> int:
        path, alias = list(prefix), ""
        while k < len(tokens) and tokens[k] not in ",}":
            if tokens[k] == "{":
                k += 1
                while tokens[k] != "}":
                    k = walk(path, k)
                    k += tokens[k] == ","
                return k + 1
            if tokens[k] == "as":
                alias, k = tokens[k + 1], k + 2
                break
            path.append(tokens[k])
            k += 1
        if path[-1] == "self":
            path.pop()
        leaves.append((path, alias or path[-1]))
        return k

    walk([], 0)
    return leaves


@dataclass
class Module:
    file: str  # relative to rust/src
    parent: str
    children: dict[str, str] = field(default_factory=dict)  # name -> module key
    items: set[str] = field(default_factory=set)  # names defined in it
    uses: list[tuple[list[str], str]] = field(default_factory=list)  # its own bindings
    paths: list[list[str]] = field(default_factory=list)  # every path it names
    expands: bool = False  # invokes a macro at module level, which may define names


MODULES: dict[str, Module] = {}  # by key: crate, crate::ekf, crate::ekf::smoother ...


def _add(key: str, parent: str, file: Path, code: str, raw: str, folder: Path) -> None:
    """Module ``key``, whose code is ``code`` (the rest of ``file`` blank), and, inside
    it, its inline modules and the files of its ``mod x;`` (found in ``folder``)."""
    module = MODULES[key] = Module(file.relative_to(SRC).as_posix(), parent)
    for m in list(INLINE_MOD.finditer(code)):
        if _depth(code, m.start()) == 0:
            start, end = m.end(), _end(code, m.end() - 1) - 1
            inner = " " * start + code[start:end] + " " * (len(code) - end)
            module.children[m.group(1)] = f"{key}::{m.group(1)}"
            _add(f"{key}::{m.group(1)}", key, file, inner, raw, folder / m.group(1))
            code = _blank(code, start, end)
    for m in MOD_DECL.finditer(code):
        given = re.search(r'path\s*=\s*"([^"]*)"', raw[m.start(1) : m.end(1)])
        child = file.parent / given.group(1) if given else folder / f"{m.group(2)}.rs"
        if not child.exists():
            child = folder / m.group(2) / "mod.rs"
        module.children[m.group(2)] = f"{key}::{m.group(2)}"
        inside = child.parent if child.name == "mod.rs" or given else child.with_suffix("")
        text = child.read_text()
        _add(f"{key}::{m.group(2)}", key, child, _file_code(text), text, inside)
    depth = 0
    for line in code.split("\n"):
        if depth == 0 and (item := ITEM.match(line)):
            module.items.add(item.group(1))
        elif depth == 0 and INVOCATION.match(line):
            module.expands = True
        depth += line.count("{") - line.count("}")
    for m in USE.finditer(code):
        leaves = _use_tree(m.group(1))
        module.paths += [path for path, _ in leaves]
        if _depth(code, m.start()) == 0:
            module.uses += leaves
        code = _blank(code, m.start(), m.end())
    module.paths += [m.group().split("::") for m in PATH.finditer(code)]


def _file_code(raw: str) -> str:
    """The code ``_add`` reads: no comments, literals, tests, ``pub(in path)`` or bodies
    of ``macro_rules!`` (templates, whose paths mean something only where expanded)."""
    code = PUB_IN.sub(lambda m: " " * len(m.group()), _without_tests(_code(raw)))
    for m in MACRO.finditer(code):
        code = _blank(code, m.end(), _end(code, m.end()))
    return code


LIB = (SRC / "lib.rs").read_text()
_add("crate", "crate", SRC / "lib.rs", _file_code(LIB), LIB, SRC)
UNRESOLVED: set[str] = set()
Place = tuple[str, str | None]  # a module and the item defined in it, None: the module


def _lookup(key: str, name: str, seen: frozenset[tuple[str, str]]) -> Place | None:
    """Where ``name``, seen from module ``key``, is defined: a child module, an item of
    its own, or where a ``use`` in it (a glob too) binds the name to."""
    module = MODULES[key]
    if name in module.children:
        return module.children[name], None
    if name in module.items:
        return key, name
    if (key, name) in seen:
        return None
    seen |= {(key, name)}
    for path, bound in module.uses:
        if bound == name:
            return _resolve(path, key, seen)
    for path, bound in module.uses:
        if bound == "*" and (glob := _resolve(path, key, seen)) and glob[1] is None:
            if found := _lookup(glob[0], name, seen):
                return found
    return None


def _resolve(
    path: list[str], key: str, seen: frozenset[tuple[str, str]] = frozenset()
) -> Place | None:
    """Where ``path``, written in module ``key``, leads; None outside the crate. A name
    not found stops the walk at the deepest module reached, as if it were defined there
    (it is noted, unless that module invokes a macro at its top, which may define it)."""
    head = path[0]
    at: Place | None
    if head in ("crate", "super", "self"):
        at = ("crate" if head == "crate" else MODULES[key].parent if head == "super" else key, None)
    else:
        at = _lookup(key, head, seen)
    for segment in path[1:]:
        if at is None or at[1] is not None or segment == "*":
            break
        if segment == "super":
            at = (MODULES[at[0]].parent, None)
        elif found := _lookup(at[0], segment, seen):
            at = found
        else:
            if not MODULES[at[0]].expands:
                UNRESOLVED.add(f"{MODULES[key].file}: {'::'.join(path)}")
            at = (at[0], segment)
    return at


def _graph() -> dict[str, dict[str, set[str]]]:
    """file -> file it imports -> the names that tie them."""
    graph: dict[str, dict[str, set[str]]] = {m.file: {} for m in MODULES.values()}
    for key, module in MODULES.items():
        for path in module.paths:
            if (at := _resolve(path, key)) is None:
                continue
            target = MODULES[at[0]].file
            name = at[1] or at[0].rsplit("::", 1)[-1] + ("::*" if path[-1] == "*" else "")
            if target != module.file:
                graph[module.file].setdefault(target, set()).add(name)
    return graph


GRAPH = _graph()


def _edge(source: str, target: str) -> str:
    return f"{source} -> {target}: {', '.join(sorted(GRAPH[source][target]))}"


def _circle(files: list[str]) -> str:
    """The edges that tie ``files``, the pairs that import each other first."""
    pairs = [
        f"  {a} <-> {b}" for a in files for b in sorted(GRAPH[a]) if a < b and a in GRAPH.get(b, {})
    ]
    edges = [f"    {_edge(a, b)}" for a in files for b in sorted(GRAPH[a]) if b in files]
    return "\n".join([f"circle of {len(files)} files:", *pairs, "  through:", *edges])


def _layer(file: str) -> str:
    return file.split("/")[0].removesuffix(".rs")


def test_no_import_circle() -> None:
    """Tarjan's strongly connected components over every import: each is one file."""
    circles = import_circles(GRAPH)
    ties = "\n".join(_circle(c) for c in sorted(circles))
    assert circles == [], f"import circles (cut an edge of each):\n{ties}"


def test_every_top_level_module_is_in_one_layer() -> None:
    placed = [name for layer in LAYERS for name in layer]
    top = sorted(MODULES["crate"].children)
    twice = sorted({name for name in placed if placed.count(name) > 1})
    assert twice == [], f"in LAYERS more than once: {twice}"
    new = sorted(set(top) - set(placed))
    assert new == [], f"new top-level modules, put each in a layer of LAYERS: {new}"
    gone = sorted(set(placed) - set(top))
    assert gone == [], f"in LAYERS but no longer a module of lib.rs: {gone}"


def test_modules_import_only_the_layers_below() -> None:
    order = {name: i for i, layer in enumerate(LAYERS) for name in layer}
    upward = [
        f"{_edge(source, target)} ({_layer(source)} imports {_layer(target)})"
        for source, targets in sorted(GRAPH.items())
        for target in sorted(targets)
        if _layer(source) in order and _layer(target) in order
        if order[_layer(target)] > order[_layer(source)]
    ]
    assert upward == [], "imports of a higher layer:\n" + "\n".join(upward)


def test_no_file_over_600_lines() -> None:
    lines = {
        p.relative_to(SRC).as_posix(): len(p.read_text().splitlines()) for p in SRC.rglob("*.rs")
    }
    long = {name: n for name, n in sorted(lines.items()) if n > MAX_LINES}
    assert long == {}


def test_the_walk_sees_real_imports() -> None:
    """The graph is not empty by accident: known edges are in it, re-exports are followed
    to the defining file (nothing imports ``lib.rs``), test-only files are not in it."""
    assert "earth.rs" in GRAPH["mechanization.rs"]  # use crate::earth;
    assert "Cancel" in GRAPH["mechanization.rs"]["cancel.rs"]
    assert "Result" in GRAPH["python/call.rs"]["error.rs"]  # crate::Result, from lib.rs
    assert "MAX_THREADS" in GRAPH["python/mod.rs"]["threads.rs"]  # a path in the code
    # The drivers run the one epoch loop; the filter's re-exports lead to their files.
    assert "Pass" in GRAPH["recorded/filter.rs"]["pass/epoch.rs"]
    assert "Pass" in GRAPH["run.rs"]["pass/epoch.rs"]
    assert "Ekf" in GRAPH["pass/epoch.rs"]["ekf/filter.rs"]
    python_to_ekf = [
        _edge(s, t) for s in GRAPH if _layer(s) == "python" for t in GRAPH[s] if _layer(t) == "ekf"
    ]
    assert python_to_ekf
    assert all("lib.rs" not in targets for targets in GRAPH.values())
    assert not [f for f in GRAPH if f.endswith(("/tests.rs", "_tests.rs"))]
    if UNRESOLVED:  # the resolver's blind spots (none today): worth a look, not a failure
        warnings.warn("unresolved: " + "; ".join(sorted(UNRESOLVED)), stacklevel=1)


def test_the_reader_on_tricky_rust() -> None:
    """Comments and literals go, lifetimes stay, test items go, use trees unfold."""
    code = _code("""let s = r#"crate::a"#; // crate::b\nfn f<'a>(c: char) { '{'; "}" }/* x */""")
    assert "crate" not in code and "'a>" in code and code.count("{") == code.count("}") == 1
    code = _without_tests('#[cfg(test)]\n#[path = "t.rs"]\nmod tests;\nmod kept;\n')
    assert code.split() == ["mod", "kept;"]
    assert _use_tree("crate::a::{self, b::{c as d, *}, e}") == [
        (["crate", "a"], "a"),
        (["crate", "a", "b", "c"], "d"),
        (["crate", "a", "b", "*"], "*"),
        (["crate", "a", "e"], "e"),
    ]
