#!/usr/bin/env bash
# Install what is missing and run every check and test: Rust (fmt, clippy, unit tests, doc),
# Python (ruff check and format, stubtest, mypy), the documentation site (mkdocs, strict),
# the wheel (scripts/check_wheel.sh: manylinux2014, the light install) and pytest. Exits
# non-zero on the first failure.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${PRONET_VENV:-$HOME/.cache/pronet-venv}"
bash "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
echo "== cargo fmt --check"
cargo fmt --all -- --check
# One clippy run over every target with every feature: the core's code is the same with
# or without the bindings (only `mod python` is gated), and `cargo test` below builds
# the core without them.
echo "== cargo clippy (core, bindings, tests, benchmarks)"
cargo clippy --quiet --all-targets --features python,bench -- -D warnings
echo "== cargo test"
cargo test --quiet
# A unit in a doc comment is escaped, \[m/s\], or rustdoc reads it as a link.
echo "== cargo doc (no warnings)"
RUSTDOCFLAGS="-D warnings" cargo doc --quiet --no-deps --features python,bench
echo "== ruff"
"$VENV/bin/ruff" check python tests benches examples scripts
"$VENV/bin/ruff" format --check --quiet python tests benches examples scripts
echo "== stubtest (python/pronet/_core.pyi against the built module)"
"$VENV/bin/python" -m mypy.stubtest pronet._core
echo "== mypy (the package's, the benchmarks' and the scripts' types)"
# Its cache lives beside the venv, outside the checkout: a fresh clone does not redo
# the third-party modules (mypy re-checks every file whose contents changed). The
# scripts apart: two of them share a module name with a benchmark.
MYPY_CACHE="${PRONET_MYPY_CACHE:-$HOME/.cache/pronet-mypy}"
"$VENV/bin/python" -m mypy --cache-dir "$MYPY_CACHE"
"$VENV/bin/python" -m mypy --cache-dir "$MYPY_CACHE" scripts
# Strict: a broken link or anchor, a link out of docs/ to a missing file, a reference
# mkdocstrings cannot resolve or a docstring griffe cannot parse fails the build. Into a
# temporary folder: the site is never kept. Not --quiet, which hides the warnings from
# --strict too (the build then passes whatever they say): the log is shown on failure.
echo "== the documentation site (mkdocs build --strict)"
SITE="$(mktemp -d)"
if ! DISABLE_MKDOCS_2_WARNING=true NO_MKDOCS_2_WARNING=1 \
  "$VENV/bin/mkdocs" build --strict --site-dir "$SITE/html" >"$SITE/log" 2>&1; then
  grep -E "WARNING|ERROR|Error|Aborted" "$SITE/log" || cat "$SITE/log"
  rm -rf "$SITE"
  exit 1
fi
rm -rf "$SITE"
echo "== the wheel: manylinux2014, installed without extras into a fresh venv"
bash "$ROOT/scripts/check_wheel.sh"
# Files are handed out in the collection's order (tests/conftest.py puts the longest
# first), not xdist's default of the files with most tests first, which left the
# longest (a few tests each) to one worker at the end.
echo "== pytest (a worker per core, up to 4; each test file in one worker)"
"$VENV/bin/python" -m pytest -q -n auto --maxprocesses 4 --dist loadfile --no-loadscope-reorder tests
