#!/usr/bin/env bash
# Create (or reuse) pronet's virtual environment and build pronet into it.
# The venv lives outside the checkout so that the large wheels (torch) are installed
# once per machine; override its place with PRONET_VENV.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${PRONET_VENV:-$HOME/.cache/pronet-venv}"
if [ ! -x "$VENV/bin/python" ]; then
  echo "pronet: creating virtual environment $VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip
fi
# The build tools: maturin, and zig, auditwheel and uv for the portable wheel that
# scripts/check_wheel.sh builds, checks and installs into a fresh venv.
if ! "$VENV/bin/python" -c "import maturin, ziglang, auditwheel, uv" 2>/dev/null; then
  "$VENV/bin/python" -m pip install -q "maturin>=1.9.4,<2" "ziglang>=0.13" "auditwheel>=6" uv
fi
# Build the native core (release) and install pronet editable (the Python sources from
# the checkout, the native module built beside them) with its test and docs extras; pip
# skips what is already there. Built as the wheel is, linked by zig for manylinux2014
# (MATURIN_PEP517_ARGS, read by maturin's build backend): the tests run the module a
# wheel ships, and scripts/check_wheel.sh then finds its build done (the same cargo
# invocation in target/x86_64-unknown-linux-gnu) instead of compiling the crate again.
cd "$ROOT"
VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" MATURIN_PEP517_ARGS="--zig --compatibility manylinux2014" \
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-build-isolation \
  -e ".[test,docs]"
