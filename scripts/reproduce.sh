#!/usr/bin/env bash
# Install what is missing and run the main job: the paper's Monte Carlo experiment.
# Extra arguments go to `pronet reproduce` (try --quick, --runs N, --out DIR).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${PRONET_VENV:-$HOME/.cache/pronet-venv}"
bash "$ROOT/scripts/bootstrap.sh"
exec "$VENV/bin/pronet" reproduce "$@"
