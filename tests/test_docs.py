"""The documentation: every relative link in the Markdown pages points to a file that
exists (and to a heading that exists, when it names one), every page is reachable from
the README, the native core's docstrings are its stub's, and docs/how-to/development.md's
layer tables name every file of the Rust crate and every module of the Python package.
The site and its generated API reference: tests/test_site.py."""

from __future__ import annotations

import functools
import re
from pathlib import Path
from types import ModuleType

import pytest

from module_file import load

ROOT = Path(__file__).resolve().parents[1]
#: Every Markdown page of the project: the top-level ones and everything under docs/.
PAGES = sorted(ROOT.glob("*.md")) + sorted((ROOT / "docs").rglob("*.md"))
#: ``[text](target)`` or ``[text](target "title")``; images (``![alt](…)``) included.
LINK = re.compile(r"\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^(```|~~~).*?^\1", flags=re.S | re.M)
INLINE_CODE = re.compile(r"(`+)(?:(?!\1).)+?\1", flags=re.S)
DEVELOPMENT = ROOT / "docs" / "how-to" / "development.md"
RUST_SRC = ROOT / "rust" / "src"
PACKAGE = ROOT / "python" / "pronet"
CODE_SPAN = re.compile(r"`([^`\n]+)`")


def relative_links(text: str) -> list[str]:
    """The link targets of a Markdown text that name a file: not web or mail addresses,
    not in-page anchors, not inside code; ``#anchor`` and ``?query`` parts removed."""
    prose = INLINE_CODE.sub("", FENCE.sub("", text))
    targets = []
    for target in LINK.findall(prose):
        if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("#"):
            continue  # http:, https:, mailto:, … or an anchor on the same page
        path = re.split(r"[#?]", target, maxsplit=1)[0]
        if path:
            targets.append(path)
    return targets


def link_targets(text: str) -> list[tuple[str, str]]:
    """``(path, anchor)`` of every link of a Markdown text that is not a web or mail
    address, outside code: path "" for an anchor on the same page, anchor "" for none."""
    prose = INLINE_CODE.sub("", FENCE.sub("", text))
    targets = []
    for target in LINK.findall(prose):
        if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target):
            continue
        path, _, anchor = re.split(r"\?", target, maxsplit=1)[0].partition("#")
        targets.append((path, anchor))
    return targets


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, Markdown emphasis and code marks and
    punctuation dropped (letters, digits, ``_`` and ``-`` kept), spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link: its text
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(text: str) -> set[str]:
    """The anchors of a Markdown page's headings; a repeated one gets -1, -2, …"""
    seen: dict[str, int] = {}
    found = set()
    for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*\s*$", FENCE.sub("", text), flags=re.M):
        base = slug(m.group(1))
        n = seen.get(base, 0)
        seen[base] = n + 1
        found.add(base if n == 0 else f"{base}-{n}")
    return found


@functools.cache
def page_anchors(page: Path) -> set[str]:
    """:func:`anchors` of a page, read once."""
    return anchors(page.read_text(encoding="utf-8"))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_existing_files(page: Path) -> None:
    broken = [
        target
        for target in relative_links(page.read_text(encoding="utf-8"))
        if not (page.parent / target).exists()
    ]
    assert not broken, f"{page.relative_to(ROOT)}: broken links {broken}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_anchors_point_to_existing_headings(page: Path) -> None:
    broken = []
    for path, anchor in link_targets(page.read_text(encoding="utf-8")):
        target = page if not path else page.parent / path
        if anchor and target.suffix == ".md" and target.exists():
            if anchor not in page_anchors(target.resolve()):
                broken.append(f"{path}#{anchor}")
    assert not broken, f"{page.relative_to(ROOT)}: links to missing headings {broken}"


def test_every_page_is_reachable_from_the_readme() -> None:
    readme = ROOT / "README.md"
    reached, todo = {readme}, [readme]
    while todo:
        page = todo.pop()
        for path, _ in link_targets(page.read_text(encoding="utf-8")):
            target = (page.parent / path).resolve()
            if path and target.suffix == ".md" and target.exists() and target not in reached:
                reached.add(target)
                todo.append(target)
    unreached = [str(p.relative_to(ROOT)) for p in PAGES if p.resolve() not in reached]
    assert not unreached, f"no link path from README.md to {unreached}"


def test_anchors() -> None:
    assert (
        slug("`pronet reproduce` and `pronet simulate`") == "pronet-reproduce-and-pronet-simulate"
    )
    assert slug("Error state (15), closed loop") == "error-state-15-closed-loop"
    assert slug("Real AUV data (Snapir)") == "real-auv-data-snapir"
    text = "# A\n## Notes\n```\n# not a heading\n```\n### Notes\n"
    assert anchors(text) == {"a", "notes", "notes-1"}
    links = "[a](x.md#part) [b](#here) [c](y.md) [d](https://e.org/#x) `[e](z.md#q)`"
    assert link_targets(links) == [("x.md", "part"), ("", "here"), ("y.md", "")]


def test_the_pages_have_relative_links_to_check() -> None:
    # The link check must see real links, or it passes vacuously.
    readme = relative_links((ROOT / "README.md").read_text(encoding="utf-8"))
    assert "docs/reference/filter.md" in readme
    concepts = relative_links((ROOT / "docs" / "reference" / "concepts.md").read_text("utf-8"))
    assert {"filter.md", "../../README.md"} <= set(concepts)
    anchored = link_targets((ROOT / "README.md").read_text(encoding="utf-8"))
    assert ("docs/reference/concepts.md", "frames-and-units") in anchored
    assert {p.name for p in PAGES} >= {"README.md", "index.md", "accuracy.md", "cli.md"}


def test_link_parser() -> None:
    text = (
        "[a](docs/x.md) [b](https://e.org/y) [c](#here) [d](../z.md#part) "
        '![img](fig.png "Title") `[code](not/a/link.md)`\n'
        "```\n[fenced](not/either.md)\n```\n[e](mailto:a@b.c)"
    )
    assert relative_links(text) == ["docs/x.md", "../z.md", "fig.png"]


def test_the_study_page_tables_are_generated_from_the_study_output() -> None:
    study_docs = _script("study_docs")
    page = study_docs.PAGE.read_text()
    assert study_docs.render(page, study_docs.tables()) == page, (
        "docs/results/study.md's tables differ from docs/results/study/study.csv; "
        "run python scripts/study_docs.py RESULT_FOLDER"
    )
    with pytest.raises(ValueError, match="no study-tables markers"):
        study_docs.render("# no markers\n", "x")


def _script(name: str) -> ModuleType:
    return load(ROOT / "scripts" / f"{name}.py")


def _runtime_doc(name: str) -> str:
    """The built module's ``__doc__`` of ``X`` or ``X.member``, cleaned."""
    import inspect

    from pronet import _core

    owner, _, member = name.partition(".")
    obj = getattr(_core, owner)
    if member:
        obj = inspect.getattr_static(obj, member)
        obj = obj.__func__ if isinstance(obj, staticmethod) else obj
    doc = obj.__doc__
    return inspect.cleandoc(doc) if isinstance(doc, str) else ""


def test_native_docstrings_at_run_time_are_the_stubs() -> None:
    """help() at the prompt shows the stub's text: one source (``_core.pyi``), written
    into the bindings' doc comments by ``scripts/core_docs.py``."""
    docs = _script("core_docs").stub_docs()
    assert len(docs) > 60 and docs["Strategy.adaptive"].startswith("q = λ·prior_q")
    differ = [name for name, doc in docs.items() if _runtime_doc(name) != doc]
    assert not differ, f"runtime docstrings differ from _core.pyi: {differ}"
    from pronet import _core

    public = {n for n in _core.__all__ if callable(getattr(_core, n))}
    assert public <= set(docs), "a native callable the stub does not describe"


def test_binding_doc_comments_are_written_from_the_stub(capsys) -> None:
    core_docs = _script("core_docs")
    assert core_docs.main(["--check"]) == 0, capsys.readouterr().err
    rust = (ROOT / "rust" / "src" / "python" / "strategy.rs").read_text(encoding="utf-8")
    stale = rust.replace("/// Constant Q^c from 6", "/// Constant Q from 6")
    assert core_docs.rewrite(stale, core_docs.stub_docs(), set()) == rust


def layer_rows(text: str) -> list[set[str]]:
    """The code spans of each row of the layer tables (a table whose first column is
    ``layer``) in the section "## Layout" of ``text``, a version of docs/how-to/development.md;
    other tables (``| before | now |``) and the prose around them are not read."""
    section = re.search(r"^## Layout[ \t]*$(.*?)(?=^## |\Z)", text, flags=re.M | re.S)
    rows: list[set[str]] = []
    header = ""
    for line in (section.group(1) if section else "").splitlines():
        if not line.startswith("|"):
            header = ""
            continue
        header = header or line
        if header.split("|")[1].strip() == "layer":
            rows.append(set(CODE_SPAN.findall(line)))
    return rows


def rust_files() -> list[str]:
    """The crate's files relative to rust/src, but ``lib.rs`` and the test files
    (``tests.rs``, ``*_tests.rs``)."""
    return sorted(
        p.relative_to(RUST_SRC).as_posix()
        for p in RUST_SRC.rglob("*.rs")
        if p.name != "lib.rs" and not p.name.endswith("tests.rs")
    )


def python_modules() -> list[str]:
    """Every module of the package by dotted name, private ones too; a package by its
    own name (its ``__init__``), the stub ``_core.pyi`` as ``pronet._core``."""
    names = []
    for path in [*PACKAGE.rglob("*.py"), PACKAGE / "_core.pyi"]:
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        names.append(".".join(parts))
    return sorted(names)


def unnamed_in_layout(text: str) -> list[str]:
    """The Rust files and Python modules that the layer tables of ``text`` (a version of
    docs/how-to/development.md) do not name. A name counts in code marks, inside one row:

    - a Rust file by its path from rust/src (``smoother/backward.rs``, ``run.rs``), or
      by its folder with a slash and its file name in the same row (``smoother/`` and
      ``backward.rs``; ``python/streams/`` and ``dvl.rs``);
    - a Python module by its dotted name (``pronet.strategies``), or by its package and
      its last part in the same row (``pronet.learn`` and ``models``; ``pronet`` and
      ``filter``).

    A bare file name or last part counts only beside its folder or package: the crate
    has three ``filter.rs`` and the package two ``figures``, so one mention must not
    stand for the others.
    """
    rows = layer_rows(text)

    def named(name: str, parent: str, leaf: str) -> bool:
        return any(name in row or {parent, leaf} <= row for row in rows)

    missing = []
    for path in rust_files():
        folder, _, name = path.rpartition("/")
        if not named(path, f"{folder}/", name):
            missing.append(f"rust/src/{path}")
    for module in python_modules():
        package, _, last = module.rpartition(".")
        if not named(module, package, last):
            missing.append(module)
    return missing


def test_the_layout_names_every_module() -> None:
    """A new file or module goes into its layer's row of docs/how-to/development.md, "Layout"
    (the Rust layers: tests/test_rust_layout.py; the Python ones: tests/test_layout.py)."""
    missing = unnamed_in_layout(DEVELOPMENT.read_text(encoding="utf-8"))
    assert missing == [], f"docs/how-to/development.md, Layout: no layer table names {missing}"


def test_the_layout_check_sees_what_is_missing() -> None:
    # It must see the files and modules, or it passes vacuously; a name counts in a
    # layer table's row only, beside its folder or package.
    assert {"ekf/update.rs", "python/streams/dvl.rs", "run.rs"} <= set(rust_files())
    assert not [f for f in rust_files() if f.endswith("tests.rs") or f == "lib.rs"]
    assert {"pronet", "pronet._core", "pronet.cli.__main__"} <= set(python_modules())
    assert {"pronet.learn.torchfilter", "pronet.learn.torchfilter.loop"} <= set(python_modules())
    text = (
        "## Layout\n\n`pass/`: `epoch.rs`, `pronet.learn` (`models`)\n\n"
        "| layer | modules |\n|---|---|\n"
        "| a | `ekf/`: `filter.rs`; `run.rs`; `smoother/backward.rs` |\n"
        "| b | `pronet.learn` (`hybrid`); `pronet.strategies`; `pronet` |\n\n"
        "| before | now |\n|---|---|\n| `sim/`: `paper.rs` | `pronet.sim.paper` |\n\n"
        "## Build\n\n| layer | x |\n|---|---|\n| c | `trajectory.rs` |\n"
    )
    missing = set(unnamed_in_layout(text))
    named = {"ekf/filter.rs", "run.rs", "smoother/backward.rs"}
    assert not {f"rust/src/{f}" for f in named} & missing
    assert not {"pronet.learn.hybrid", "pronet.strategies", "pronet"} & missing
    assert "rust/src/recorded/filter.rs" in missing  # filter.rs names ekf's only
    assert "rust/src/pass/epoch.rs" in missing  # outside a layer table
    assert "rust/src/trajectory.rs" in missing  # after the section
    assert {"pronet.learn.models", "pronet.sim.paper", "pronet.learn.akit"} <= missing
