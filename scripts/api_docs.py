"""Generate ``docs/api.md``, pronet's API reference, from its docstrings.

Usage::

    python scripts/api_docs.py          # write docs/api.md
    python scripts/api_docs.py --check  # exit 1 if docs/api.md is out of date

Only the standard library's ``inspect``, ``ast`` and ``pkgutil`` are used. The page
covers the top-level ``pronet`` namespace (everything in ``pronet.__all__``), then every
public module of the package, the top-level ones first, then each subpackage and its
modules (not ``cli``): its docstring, then its public classes (with their own public
methods and properties) and functions, in source order.

The documentation and typed signatures of the native classes and functions of
``pronet._core`` are read from ``python/pronet/_core.pyi`` with ``ast`` (their runtime
docstrings are the same text, written from the stub by ``scripts/core_docs.py``),
falling back to the runtime signature where the stub has none. Module-level constants
are not listed, but for the top-level namespace's tuples of names (``STATE_BLOCKS``):
their value and ``#:`` comment.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import inspect
import pkgutil
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "docs" / "api.md"
CHECK_MESSAGE = "docs/api.md is out of date; run python scripts/api_docs.py"
#: Google-style docstring sections turned into bold labels with bullet lists.
SECTIONS = ("Args", "Arguments", "Attributes", "Returns", "Raises", "Yields")
#: Signatures longer than this are written one parameter per line.
WIDTH = 88
ROLE = re.compile(r":(?:class|func|meth|data|mod|attr|exc|obj):`~?([^`]+)`")
ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")
TABLE_BORDER = re.compile(r"=+( +=+)+$")


# ---------------------------------------------------------------------------------------
# The native module's stub


@dataclass
class StubEntry:
    """One function, method, property or class of ``_core.pyi``."""

    name: str
    kind: str  # "function", "method", "staticmethod", "property", "class", "data"
    signature: str  # parameters in parentheses (or ": type" for properties and data)
    doc: str
    members: list[StubEntry] = field(default_factory=list)


def _stub_function(node: ast.FunctionDef, in_class: bool) -> StubEntry:
    decorators = {ast.unparse(d) for d in node.decorator_list}
    returns = f" -> {ast.unparse(node.returns)}" if node.returns is not None else ""
    if "property" in decorators:
        ret = ast.unparse(node.returns) if node.returns is not None else "Any"
        return StubEntry(node.name, "property", f": {ret}", ast.get_docstring(node) or "")
    kind = "function"
    if in_class:
        kind = "staticmethod" if "staticmethod" in decorators else "method"
    params = _stub_params(node.args, drop_first=kind == "method")
    return StubEntry(node.name, kind, f"({params}){returns}", _doc_of(node))


def _stub_params(args: ast.arguments, drop_first: bool) -> str:
    """The parameter list of a stub function, spaced as ``inspect`` spaces it."""

    def one(arg: ast.arg, default: ast.expr | None, prefix: str = "") -> str:
        text = prefix + arg.arg
        if arg.annotation is not None:
            text += f": {ast.unparse(arg.annotation)}"
        if default is not None:
            sep = " = " if arg.annotation is not None else "="
            text += sep + ast.unparse(default)
        return text

    positional = args.posonlyargs + args.args
    defaults: list[ast.expr | None] = [None] * (len(positional) - len(args.defaults))
    defaults += list(args.defaults)
    parts = [one(a, d) for a, d in zip(positional, defaults, strict=True)]
    if args.posonlyargs:
        parts.insert(len(args.posonlyargs), "/")
    if drop_first and positional:  # self (or cls)
        parts = parts[1:]
        if parts and parts[0] == "/":
            parts = parts[1:]
    if args.vararg is not None:
        parts.append(one(args.vararg, None, "*"))
    elif args.kwonlyargs:
        parts.append("*")
    parts += [one(a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True)]
    if args.kwarg is not None:
        parts.append(one(args.kwarg, None, "**"))
    return ", ".join(parts)


def _doc_of(node: ast.AST) -> str:
    doc = ast.get_docstring(node)  # type: ignore[arg-type]
    return doc or ""


def read_stub(path: Path) -> dict[str, StubEntry]:
    """Top-level functions, classes (with members) and annotated data of a ``.pyi``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out: dict[str, StubEntry] = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out[node.name] = _stub_function(node, in_class=False)
        elif isinstance(node, ast.ClassDef):
            members = [
                _stub_function(item, in_class=True)
                for item in node.body
                if isinstance(item, ast.FunctionDef)
            ]
            # The constructor: __init__, or __new__ (native classes, as stubtest wants).
            init = next((m for m in members if m.name in ("__init__", "__new__")), None)
            signature = init.signature.rsplit(" -> ", 1)[0] if init else ""
            public = [m for m in members if not m.name.startswith("_")]
            out[node.name] = StubEntry(node.name, "class", signature, _doc_of(node), public)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            ann = ast.unparse(node.annotation)
            out[node.target.id] = StubEntry(node.target.id, "data", f": {ann}", "")
    return out


# ---------------------------------------------------------------------------------------
# Rendering helpers


class _Shown:
    """A default value whose repr is safe to print: no memory address."""

    def __init__(self, value: Any) -> None:
        self.value = value

    def __repr__(self) -> str:
        if inspect.isclass(self.value):
            return _qualname(self.value)
        text = repr(self.value)
        if " at 0x" not in text:
            return text
        if callable(self.value) and hasattr(self.value, "__qualname__"):
            return self.value.__qualname__
        return type(self.value).__name__


def _annotation(ann: Any) -> str:
    if isinstance(ann, str):
        return ann
    return inspect.formatannotation(ann)


def format_signature(sig: inspect.Signature, drop_first: bool = False) -> str:
    """``(params) -> return`` with string annotations unquoted and safe defaults."""
    params = list(sig.parameters.values())
    if drop_first and params:
        params = params[1:]
    parts: list[str] = []
    kinds = [p.kind for p in params]
    star_done = inspect.Parameter.VAR_POSITIONAL in kinds
    for i, p in enumerate(params):
        if p.kind is inspect.Parameter.KEYWORD_ONLY and not star_done:
            parts.append("*")
            star_done = True
        text = p.name
        if p.kind is inspect.Parameter.VAR_POSITIONAL:
            text = "*" + text
        elif p.kind is inspect.Parameter.VAR_KEYWORD:
            text = "**" + text
        if p.annotation is not inspect.Parameter.empty:
            text += f": {_annotation(p.annotation)}"
            if p.default is not inspect.Parameter.empty:
                text += f" = {_Shown(p.default)!r}"
        elif p.default is not inspect.Parameter.empty:
            text += f"={_Shown(p.default)!r}"
        parts.append(text)
        last_posonly = p.kind is inspect.Parameter.POSITIONAL_ONLY and (
            i + 1 == len(params) or params[i + 1].kind is not inspect.Parameter.POSITIONAL_ONLY
        )
        if last_posonly:
            parts.append("/")
    out = "(" + ", ".join(parts) + ")"
    if sig.return_annotation is not inspect.Signature.empty:
        out += f" -> {_annotation(sig.return_annotation)}"
    return ADDRESS.sub("", out)


def _wrap(head: str, signature: str) -> str:
    """``head + signature``, one parameter per line when it is long."""
    line = head + signature
    if len(line) <= WIDTH or not signature.startswith("("):
        return line
    params, close = _split_params(signature)
    if params is None:
        return line
    body = "".join(f"    {p},\n" for p in params)
    return f"{head}(\n{body}{close}"


def _split_params(signature: str) -> tuple[list[str] | None, str]:
    """Split ``(a, b[c, d], e) -> r`` at top-level commas: ``([a, b[c, d], e], ') -> r'``."""
    depth, start, params = 0, 1, []
    quote: str | None = None
    for i, ch in enumerate(signature):
        if quote:
            if ch == quote:
                quote = None
            continue
        if ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
            if depth == 0:
                last = signature[start:i].strip()
                if last:
                    params.append(last)
                return params, signature[i:]
        elif ch == "," and depth == 1:
            params.append(signature[start:i].strip())
            start = i + 1
    return None, ""


def markdown_doc(doc: str) -> str:
    """A docstring as Markdown: reST roles as code, Google sections as bullet lists,
    ``::`` literal blocks and reST simple tables as fenced text blocks."""
    lines = ROLE.sub(r"``\1``", doc.strip()).splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.rstrip(":") in SECTIONS and stripped.endswith(":") and line == stripped:
            i = _section(lines, i + 1, stripped.rstrip(":"), out)
        elif TABLE_BORDER.match(stripped):
            i = _table(lines, i, out)
        elif stripped.endswith("::"):
            out.append(line.rstrip()[:-1].rstrip(" :") + ":" if stripped != "::" else "")
            i = _literal(lines, i + 1, out)
        else:
            # Prose indented by four or more spaces would become a code block in Markdown.
            out.append(line.strip() if line.startswith("    ") else line)
            i += 1
    while out and not out[-1]:
        out.pop()
    return "\n".join(out)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _section(lines: list[str], i: int, header: str, out: list[str]) -> int:
    """A Google-style section from line ``i`` on, as a bullet list; returns the next line."""
    if out and out[-1]:
        out.append("")
    out += [f"**{header}:**", ""]
    base: int | None = None
    while i < len(lines) and (lines[i].startswith(" ") or not lines[i].strip()):
        text = lines[i].strip()
        if not text:
            i += 1
            if i < len(lines) and not lines[i].startswith(" "):
                break
            continue
        if base is None:
            base = _indent(lines[i])
        entry = re.match(r"([^:`]+?):(?:\s+|$)(.*)", text)
        if _indent(lines[i]) > base and out[-1].startswith("- "):
            out[-1] += " " + text
        elif entry:
            out.append(f"- `{entry.group(1)}`: {entry.group(2)}".rstrip())
        else:
            out.append(f"- {text}")
        i += 1
    out.append("")
    return i


def _table(lines: list[str], i: int, out: list[str]) -> int:
    """A reST simple table (three ``=== ===`` borders) as a fenced text block."""
    indent = _indent(lines[i])
    block, borders = [], 0
    while i < len(lines) and borders < 3:
        if TABLE_BORDER.match(lines[i].strip()):
            borders += 1
        block.append(lines[i][indent:].replace("``", "").rstrip())
        i += 1
    if out and out[-1]:
        out.append("")
    out += ["```text", *block, "```", ""]
    while i < len(lines) and not lines[i].strip():
        i += 1
    return i


def _literal(lines: list[str], i: int, out: list[str]) -> int:
    """The indented block after a ``::`` line as a fenced text block."""
    while i < len(lines) and not lines[i].strip():
        i += 1
    if i >= len(lines) or not lines[i].startswith(" "):
        return i
    indent = _indent(lines[i])
    block: list[str] = []
    while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) >= indent):
        block.append(lines[i][indent:].rstrip())
        i += 1
    while block and not block[-1]:
        block.pop()
    if out and out[-1]:
        out.append("")
    out += ["```text", *block, "```", ""]
    return i


def slug(title: str, seen: dict[str, int]) -> str:
    """GitHub's heading anchor for ``title`` (unique within the page)."""
    base = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
    n = seen.get(base, 0)
    seen[base] = n + 1
    return base if n == 0 else f"{base}-{n}"


def _line(obj: Any) -> int:
    """Source line of ``obj`` (for ordering), or a large number when unknown."""
    target = obj
    if isinstance(obj, property):
        target = obj.fget
    elif isinstance(obj, (classmethod, staticmethod)):
        target = obj.__func__
    try:
        return inspect.getsourcelines(inspect.unwrap(target))[1]
    except (OSError, TypeError):
        return sys.maxsize


def _own_doc(obj: Any) -> str:
    """``obj``'s own docstring, cleaned (not one inherited from a base class)."""
    if inspect.isclass(obj):
        doc = obj.__dict__.get("__doc__")
    elif isinstance(obj, property):
        doc = obj.fget.__doc__ if obj.fget is not None else None
    elif isinstance(obj, (classmethod, staticmethod)):
        doc = obj.__func__.__doc__
    else:
        doc = getattr(obj, "__doc__", None)
    return inspect.cleandoc(doc) if isinstance(doc, str) else ""


# ---------------------------------------------------------------------------------------
# The page


class Page:
    """Accumulates the Markdown of ``docs/api.md`` and its table of contents."""

    def __init__(self, stub: dict[str, StubEntry]) -> None:
        self.stub = stub
        self.body: list[str] = []
        self.toc: list[str] = []
        self.seen: dict[str, int] = {}
        self.anchors: dict[str, str] = {}  # qualified name -> anchor

    def heading(self, level: int, title: str, toc_level: int | None = None) -> str:
        text = f"`{title}`"
        anchor = slug(text, self.seen)
        self.body += [f"{'#' * level} {text}", ""]
        if toc_level is not None:
            self.toc.append(f"{'  ' * toc_level}- [{text}](#{anchor})")
        return anchor

    def code(self, text: str) -> None:
        self.body += ["```python", text, "```", ""]

    def text(self, doc: str) -> None:
        doc = markdown_doc(doc)
        if doc:
            self.body += [doc, ""]

    # -- native objects ------------------------------------------------------------

    def native(self, name: str, obj: Any, qualified: str, level: int) -> None:
        entry = self.stub.get(name)
        self.anchors[qualified] = self.heading(level, qualified, toc_level=1)
        if inspect.isclass(obj):
            # no __init__ in the stub: made by factories, not called directly
            sig = entry.signature if entry else _runtime_sig(obj)
            self.code(_wrap(f"class {name}", sig))
            self.text(_native_doc(entry, obj))
            members = entry.members if entry else []
            names = {m.name for m in members}
            extra = [  # runtime members the stub does not list
                StubEntry(k, "property" if _is_getset(v) else "method", "", "")
                for k, v in vars(obj).items()
                if not k.startswith("_") and k not in names
            ]
            for member in members + sorted(extra, key=lambda m: m.name):
                self.native_member(name, obj, member, level + 1)
        elif callable(obj):
            sig = entry.signature if entry else _runtime_sig(obj)
            self.code(_wrap(name, sig))
            self.text(_native_doc(entry, obj))
        elif entry is None and isinstance(obj, tuple) and all(isinstance(x, str) for x in obj):
            self.code(f"{name} = {obj!r}")
            self.text(_comment_doc(name) or "Module attribute.")
        else:
            ann = entry.signature if entry else f": {type(obj).__name__}"
            self.code(f"{name}{ann}")
            self.text("Module attribute (its value is not reproduced here).")

    def native_member(self, owner: str, cls: type, member: StubEntry, level: int) -> None:
        runtime = getattr(cls, member.name, None)
        doc = member.doc or _runtime_member_doc(cls, member.name)
        title = f"{owner}.{member.name}"
        self.heading(level, title)
        if member.kind == "property":
            self.code(f"{title}{member.signature or ''}  # property")
        else:
            sig = member.signature or _runtime_sig(runtime, drop_first=True)
            prefix = "@staticmethod\n" if member.kind == "staticmethod" else ""
            self.code(prefix + _wrap(title, sig))
        self.text(doc)

    # -- Python objects ------------------------------------------------------------

    def python_object(self, obj: Any, qualified: str, level: int, toc_level: int) -> None:
        self.anchors[qualified] = self.heading(level, qualified, toc_level=toc_level)
        name = qualified.rsplit(".", 1)[-1]
        if inspect.isclass(obj):
            self.code(_wrap(f"class {name}", _class_sig(obj)))
            bases = [b for b in obj.__bases__ if b is not object]
            if bases:
                self.body += ["Bases: " + ", ".join(f"`{_qualname(b)}`" for b in bases), ""]
            self.text(_own_doc(obj))
            members = [
                (k, v)
                for k, v in vars(obj).items()
                if not k.startswith("_")
                and (inspect.isfunction(v) or isinstance(v, (property, classmethod, staticmethod)))
            ]
            members.sort(key=lambda kv: _line(kv[1]))
            for k, v in members:
                self.python_member(name, obj, k, v, level + 1)
        else:
            self.code(_wrap(name, format_signature(inspect.signature(obj))))
            self.text(_own_doc(obj))

    def python_member(self, owner: str, cls: type, name: str, raw: Any, level: int) -> None:
        title = f"{owner}.{name}"
        self.heading(level, title)
        if isinstance(raw, property):
            ret = ""
            if raw.fget is not None:
                ann = inspect.signature(raw.fget).return_annotation
                if ann is not inspect.Signature.empty:
                    ret = f": {_annotation(ann)}"
            self.code(f"{title}{ret}  # property")
        else:
            func = raw.__func__ if isinstance(raw, (classmethod, staticmethod)) else raw
            sig = format_signature(inspect.signature(func), not isinstance(raw, staticmethod))
            prefix = ""
            if isinstance(raw, classmethod):
                prefix = "@classmethod\n"
            elif isinstance(raw, staticmethod):
                prefix = "@staticmethod\n"
            self.code(prefix + _wrap(title, sig))
        self.text(_own_doc(raw))

    def render(self) -> str:
        head = [
            "# pronet API reference",
            "",
            "<!-- Generated by scripts/api_docs.py from the docstrings; do not edit by hand."
            " Run `python scripts/api_docs.py` after changing a docstring. -->",
            "",
            "Every public name of the `pronet` package with its signature and docstring. "
            "Conventions (frames, units, the meaning of q) are in "
            "[concepts](reference/concepts.md); every formula of the filter is in "
            "[the filter](reference/filter.md).",
            "",
            "## Contents",
            "",
            *self.toc,
            "",
        ]
        return "\n".join(head + self.body).rstrip("\n") + "\n"


def _comment_doc(name: str) -> str:
    """The ``#:`` comment above ``name = ...`` in the package module it is imported from
    into ``pronet`` (how the package documents its constants), or ``""``."""
    import pronet

    package = Path(pronet.__file__).resolve().parent
    for node in ast.parse((package / "__init__.py").read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ImportFrom) and any(a.name == name for a in node.names):
            module = (node.module or "").removeprefix("pronet.").replace(".", "/")
            lines = (package / f"{module}.py").read_text(encoding="utf-8").splitlines()
            for i, line in enumerate(lines):
                if re.match(rf"{name}\b.*=", line):
                    j = i
                    while j > 0 and lines[j - 1].startswith("#:"):
                        j -= 1
                    return "\n".join(x.removeprefix("#:").strip() for x in lines[j:i])
    return ""


def _is_getset(value: Any) -> bool:
    return type(value).__name__ in ("getset_descriptor", "member_descriptor") or isinstance(
        value, property
    )


def _runtime_sig(obj: Any, drop_first: bool = False) -> str:
    try:
        return format_signature(inspect.signature(obj), drop_first)
    except (TypeError, ValueError):
        return "(...)"


def _runtime_member_doc(cls: type, name: str) -> str:
    raw = inspect.getattr_static(cls, name, None)
    if isinstance(raw, staticmethod):  # its own __doc__ is staticmethod's
        raw = raw.__func__
    doc = getattr(raw, "__doc__", None)
    return inspect.cleandoc(doc) if isinstance(doc, str) else ""


def _native_doc(entry: StubEntry | None, obj: Any) -> str:
    if entry is not None and entry.doc:
        return entry.doc
    return _own_doc(obj)


def _class_sig(cls: type) -> str:
    if getattr(cls, "_is_protocol", False):
        return ""
    try:
        return format_signature(inspect.signature(cls)).removesuffix(" -> None")
    except (TypeError, ValueError):
        return ""


def _qualname(cls: type) -> str:
    module = cls.__module__
    if module == "builtins":
        return cls.__qualname__
    return f"{module}.{cls.__qualname__}"


def public_modules(package: ModuleType) -> list[str]:
    """``package``'s public modules and subpackages, dotted below it, in the order of
    its layout: the top-level modules, then each subpackage followed by its modules
    (``cli`` is documented by ``--help``; private ones, ``_`` first, are left out)."""
    names = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: (i.ispkg, i.name)):
        if info.name.startswith("_") or info.name == "cli":
            continue
        names.append(info.name)
        if info.ispkg:
            sub = importlib.import_module(f"{package.__name__}.{info.name}")
            names += [f"{info.name}.{name}" for name in public_modules(sub)]
    return names


def generate() -> str:
    """The Markdown of ``docs/api.md``."""
    import pronet

    stub = read_stub(Path(pronet.__file__).resolve().parent / "_core.pyi")
    page = Page(stub)
    core_name = "pronet._core"

    # The top-level namespace: classes, then functions, then data, in __all__ order.
    page.heading(2, "pronet", toc_level=0)
    page.text(_own_doc(pronet))
    exported = [(name, getattr(pronet, name)) for name in pronet.__all__]

    def group(item: tuple[str, Any]) -> int:
        obj = item[1]
        return 0 if inspect.isclass(obj) else 1 if callable(obj) else 2

    for name, obj in sorted(exported, key=group):  # sorted() is stable
        qualified = f"pronet.{name}"
        if getattr(obj, "__module__", None) == core_name or not callable(obj):
            page.native(name, obj, qualified, level=3)
        else:
            page.python_object(obj, qualified, level=3, toc_level=1)
    documented = {id(obj): f"pronet.{name}" for name, obj in exported if callable(obj)}

    for mod_name in public_modules(pronet):
        module = importlib.import_module(f"pronet.{mod_name}")
        title = module.__name__
        page.heading(2, title, toc_level=0)
        page.text(_own_doc(module))
        objects = [
            (name, obj)
            for name, obj in vars(module).items()
            if not name.startswith("_")
            and (inspect.isclass(obj) or inspect.isfunction(obj))
            and getattr(obj, "__module__", None) == module.__name__
        ]
        objects.sort(key=lambda kv: _line(kv[1]))
        elsewhere = [
            f"- `{title}.{name}`: see [`{documented[id(obj)]}`]"
            f"(#{page.anchors[documented[id(obj)]]})."
            for name, obj in objects
            if id(obj) in documented
        ]
        if elsewhere:
            page.body += ["Documented with the top-level namespace:", "", *elsewhere, ""]
        for name, obj in objects:
            if id(obj) not in documented:
                page.python_object(obj, f"{title}.{name}", level=3, toc_level=1)
    return page.render()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="exit 1 if docs/api.md differs from the docstrings"
    )
    args = parser.parse_args(argv)
    text = generate()
    if args.check:
        current = OUTPUT.read_text(encoding="utf-8") if OUTPUT.exists() else None
        if current != text:
            print(CHECK_MESSAGE, file=sys.stderr)
            return 1
        print("docs/api.md is up to date")
        return 0
    OUTPUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUTPUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
