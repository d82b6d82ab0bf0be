#!/usr/bin/env bash
# Check that the release wheel is portable, complete and works on its own: build it with
# `maturin build --release --zig` for manylinux2014 (glibc >= 2.17), or take one with
# --wheel PATH; build the sdist and look for the sources in it; check the wheel's
# platform tag with `auditwheel show`; install that one file into a brand-new virtual
# environment (dependencies from PyPI) and, from a folder outside the checkout, import
# it, look for the files it must ship (py.typed, _core.pyi, the native module, the
# shipped weights) and run the CLI.
#
#   bash scripts/check_wheel.sh                  # the light install (no torch): pronet info,
#                                                # simulate (native strategies and shipped
#                                                # models), sweep; train names the extra
#   bash scripts/check_wheel.sh --full           # then the torch extra and reproduce --quick
#   bash scripts/check_wheel.sh --wheel FILE.whl # check a wheel built before
#   KEEP=1 bash scripts/check_wheel.sh           # keep the temporary folder to look into
#
# `.ci/run` runs the light check (about 2 minutes, most of it the build, which
# scripts/bootstrap.sh has already done the same way in `.ci/run`). maturin, ziglang,
# auditwheel and uv come from pronet's venv (PRONET_VENV, default ~/.cache/pronet-venv) when
# they are there, otherwise they are installed into a temporary venv. Nothing is
# installed into pronet's venv and nothing in the checkout is changed (the wheel goes to
# the temp folder; the build to target/x86_64-unknown-linux-gnu).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${PRONET_VENV:-$HOME/.cache/pronet-venv}"
PYTHON="${PYTHON:-python3}"

usage() { sed -n '2,/^set -euo/{/^set -euo/d;p}' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
WHEEL=""
FULL=0
while [ $# -gt 0 ]; do
  case "$1" in
    --full) FULL=1; shift ;;
    --wheel) [ $# -ge 2 ] || { echo "check_wheel: --wheel needs a path" >&2; exit 2; }
             [ -f "$2" ] || { echo "check_wheel: no wheel file at $2" >&2; exit 2; }
             WHEEL="$(realpath "$2")"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "check_wheel: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

TMP="$(mktemp -d "${TMPDIR:-/tmp}/pronet-wheel.XXXXXX")"
cleanup() {
  local rc=$?
  if [ "${KEEP:-0}" = 1 ]; then
    echo "check_wheel: KEEP=1, leaving $TMP"
  else
    rm -rf "$TMP"
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

fail() { echo "check_wheel: FAIL: $*" >&2; exit 1; }
now() { date +%s; }
declare -A TIME=()

# --- build ---------------------------------------------------------------------------
TOOLS="$VENV/bin"
if ! { [ -x "$TOOLS/maturin" ] && [ -x "$TOOLS/auditwheel" ] \
       && "$TOOLS/python" -c "import ziglang" 2>/dev/null; }; then
  echo "check_wheel: no maturin, ziglang and auditwheel in $VENV; installing them into a temporary venv"
  "$PYTHON" -m venv "$TMP/tools"
  "$TMP/tools/bin/python" -m pip install -q "maturin>=1.9.4,<2" "ziglang>=0.13" "auditwheel>=6" uv
  TOOLS="$TMP/tools/bin"
fi
if [ -z "$WHEEL" ]; then
  echo "== build: $("$TOOLS/maturin" --version) build --release --zig --compatibility manylinux2014 (log: $TMP/build.log)"
  t=$(now)
  # maturin finds zig as `python -m ziglang` of the first python on PATH: the tools'.
  if ! (cd "$ROOT" && PATH="$TOOLS:$PATH" "$TOOLS/maturin" build --release --zig \
          --compatibility manylinux2014 --interpreter "$PYTHON" --out "$TMP/dist") \
          >"$TMP/build.log" 2>&1; then
    tail -n 40 "$TMP/build.log" >&2
    fail "maturin build failed (KEEP=1 keeps the whole log)"
  fi
  TIME[build]=$(( $(now) - t ))
  shopt -s nullglob
  wheels=("$TMP"/dist/*.whl)
  shopt -u nullglob
  [ "${#wheels[@]}" -eq 1 ] || fail "expected one wheel in $TMP/dist, found ${#wheels[@]}"
  WHEEL="${wheels[0]}"
fi
[ -f "$WHEEL" ] || fail "no wheel at $WHEEL"
WHEEL_NAME="$(basename "$WHEEL")"
WHEEL_SIZE="$(du -h "$WHEEL" | cut -f1)"
echo "   wheel: $WHEEL_NAME ($WHEEL_SIZE)"

# --- the sdist: the sources a wheel is built from ---------------------------------------
echo "== sdist"
(cd "$ROOT" && "$TOOLS/maturin" sdist --out "$TMP/sdist") >"$TMP/sdist.log" 2>&1 \
  || { tail -n 20 "$TMP/sdist.log" >&2; fail "maturin sdist failed"; }
SDIST="$(ls "$TMP"/sdist/pronet-*.tar.gz)"
tar tzf "$SDIST" >"$TMP/sdist.files"
for f in pyproject.toml Cargo.toml Cargo.lock rust/src/lib.rs python/pronet/__init__.py \
         python/pronet/_core.pyi python/pronet/learn/weights/detrend.safetensors; do
  grep -qx "pronet-[^/]*/$f" "$TMP/sdist.files" || fail "the sdist has no $f"
done
echo "   $(basename "$SDIST"): the crate, the package and the weights"

# --- portable: manylinux2014 (glibc 2.17) or older, by auditwheel ----------------------
echo "== auditwheel show"
"$TOOLS/auditwheel" show "$WHEEL" >"$TMP/auditwheel.log" 2>&1 \
  || { cat "$TMP/auditwheel.log" >&2; fail "auditwheel show failed"; }
tag="$(grep -oE 'manylinux_2_[0-9]+_x86_64' "$TMP/auditwheel.log" | head -n 1)"
[ -n "$tag" ] || { cat "$TMP/auditwheel.log" >&2; fail "auditwheel found no manylinux tag"; }
minor="${tag#manylinux_2_}"; minor="${minor%%_*}"
[ "$minor" -le 17 ] || fail "the wheel needs $tag; manylinux2014 (manylinux_2_17) or older expected"
echo "   $tag (manylinux2014 or older)"

# --- install into a brand-new venv -----------------------------------------------------
NEW="$TMP/venv"
echo "== install: fresh venv $NEW, $WHEEL_NAME without extras (dependencies from PyPI)"
t=$(now)
# Only the wheel file is named: pronet comes from it and its dependencies from PyPI.
# The light install: no extra. uv (when the tools have it) does what pip does, faster.
if [ -x "$TOOLS/uv" ]; then
  install() { "$TOOLS/uv" pip install -q --python "$NEW/bin/python" "$@"; }
  "$TOOLS/uv" venv -q --python "$PYTHON" "$NEW" >"$TMP/venv.log" 2>&1 \
    || { cat "$TMP/venv.log" >&2; fail "uv venv failed"; }
else
  install() { "$NEW/bin/python" -m pip install -q --disable-pip-version-check "$@"; }
  "$PYTHON" -m venv "$NEW"
fi
install "$WHEEL" >"$TMP/install.log" 2>&1 \
  || { tail -n 40 "$TMP/install.log" >&2; fail "installing the wheel failed"; }
TIME[install]=$(( $(now) - t ))

# Everything below runs from a folder outside the checkout, with no PYTHONPATH and no
# other venv active, so that only the installed package can be imported.
OUTSIDE="$TMP/outside"
mkdir -p "$OUTSIDE"
cd "$OUTSIDE"
run() { env -u PYTHONPATH -u VIRTUAL_ENV -u PYTHONHOME -u PYTHONSTARTUP \
          PATH="$NEW/bin:/usr/local/bin:/usr/bin:/bin" "$@"; }

# --- the installed package -------------------------------------------------------------
echo "== import"
SITE="$(run "$NEW/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
PKG_INIT="$(run "$NEW/bin/python" -c 'import pronet, pronet._core; print(pronet.__file__)')" \
  || fail "import pronet, pronet._core failed in the new venv"
echo "   pronet.__file__ = $PKG_INIT"
SITE="$(realpath "$SITE")"
PKG="$(dirname "$(realpath "$PKG_INIT")")"
case "$PKG/" in
  "$SITE"/*) ;;
  *) fail "pronet was imported from $PKG, not from the new venv's $SITE" ;;
esac
CORE="$(run "$NEW/bin/python" -c 'import pronet._core as c; print(c.__file__)')"
case "$(realpath "$CORE")" in
  "$SITE"/*) ;;
  *) fail "pronet._core was imported from $CORE, not from $SITE" ;;
esac

echo "== files in the installed package ($PKG)"
missing=()
for f in py.typed _core.pyi; do
  [ -f "$PKG/$f" ] || missing+=("pronet/$f")
done
shopt -s nullglob
so=("$PKG"/_core*.so)
[ "${#so[@]}" -ge 1 ] || missing+=("pronet/_core*.so")
# The shipped weights: every .safetensors and .json that the source tree has, byte for
# byte, and at least one of each kind.
src_weights=("$ROOT"/python/pronet/learn/weights/*.safetensors "$ROOT"/python/pronet/learn/weights/*.json)
inst_st=("$PKG"/learn/weights/*.safetensors)
inst_js=("$PKG"/learn/weights/*.json)
shopt -u nullglob
[ "${#inst_st[@]}" -ge 1 ] || missing+=("pronet/learn/weights/*.safetensors")
[ "${#inst_js[@]}" -ge 1 ] || missing+=("pronet/learn/weights/*.json")
for src in "${src_weights[@]}"; do
  name="learn/weights/$(basename "$src")"
  if [ ! -f "$PKG/$name" ]; then
    missing+=("pronet/$name")
  elif ! cmp -s "$src" "$PKG/$name"; then
    missing+=("pronet/$name (differs from the source tree's)")
  fi
done
[ "${#missing[@]}" -eq 0 ] || fail "missing from the installed package: ${missing[*]}"
echo "   py.typed, _core.pyi, $(basename "${so[0]}"), ${#inst_st[@]} .safetensors + ${#inst_js[@]} .json weights"
# Nothing the wheel should not carry: byte code or a second native module.
stray="$(run "$NEW/bin/python" - "$WHEEL" <<'EOF'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
bad = [n for n in names if "__pycache__" in n or n.endswith((".pyc", ".pyo"))]
so = [n for n in names if n.startswith("pronet/") and n.endswith((".so", ".pyd"))]
if len(so) != 1:
    bad += so
print(" ".join(bad))
EOF
)"
[ -z "$stray" ] || fail "the wheel carries files it should not: $stray"

# --- the command line ------------------------------------------------------------------
echo "== pronet info"
[ -x "$NEW/bin/pronet" ] || fail "the wheel installed no 'pronet' command"
run "$NEW/bin/pronet" info || fail "pronet info failed"

# --- the light install ------------------------------------------------------------------
echo "== the light install: no torch, no scikit-learn"
run "$NEW/bin/python" -c "
import importlib.util, sys
found = [m for m in ('torch', 'sklearn') if importlib.util.find_spec(m)]
sys.exit(f'installed without the extra: {found}' if found else 0)" \
  || fail "the plain install pulled in torch or scikit-learn"
cat > short.toml <<'TOML'
name = "short"
[trajectory]
segments = [[20, 0, 0, 0], [20, 0, 3, 0]]
TOML
cat > grid.toml <<'TOML'
scenarios = ["short.toml"]
strategies = ["constant", "mehra:5", "learned:detrend"]
noise_levels = [1, 4]
runs = 4
shard_runs = 2
TOML
STRATEGIES="constant,mehra:5,adaptive:20,oracle,detvar,learned:hcf,learned:detrend"
t=$(now)
echo "== pronet simulate --strategies $STRATEGIES"
run "$NEW/bin/pronet" simulate --scenario short.toml --runs 2 --strategies "$STRATEGIES" \
  --out sim --quiet >"$TMP/simulate.log" 2>&1 \
  || { tail -n 20 "$TMP/simulate.log" >&2; fail "pronet simulate failed"; }
for f in table.md metrics.csv config.json q.png; do
  [ -s "sim/$f" ] || fail "simulate wrote no $f"
done
echo "== pronet sweep (2 noise levels x 3 strategies, shards of 2 runs)"
run "$NEW/bin/pronet" sweep grid.toml --out swp --quiet >"$TMP/sweep.log" 2>&1 \
  || { tail -n 20 "$TMP/sweep.log" >&2; fail "pronet sweep failed"; }
[ -s swp/metrics.csv ] || fail "sweep wrote no metrics.csv"
echo "== pronet train without torch: one line naming the extra"
set +e
run "$NEW/bin/pronet" train --model detrend --quiet >"$TMP/train.log" 2>&1
rc=$?
set -e
[ "$rc" -eq 2 ] && [ "$(wc -l <"$TMP/train.log")" -eq 1 ] \
  && grep -q "pip install 'pronet\[torch\]'" "$TMP/train.log" \
  || { cat "$TMP/train.log" >&2; fail "pronet train without torch: exit $rc, expected one line naming the extra"; }
TIME[light]=$(( $(now) - t ))

if [ "$FULL" = 1 ]; then
  echo "== the torch extra: pip install '$WHEEL_NAME[torch]'"
  t=$(now)
  install "$WHEEL[torch]" >"$TMP/install-torch.log" 2>&1 \
    || { tail -n 40 "$TMP/install-torch.log" >&2; fail "installing the torch extra failed"; }
  TIME[torch]=$(( $(now) - t ))
  echo "== pronet reproduce --quick"
  RESULTS="$TMP/results"
  t=$(now)
  run "$NEW/bin/pronet" reproduce --quick --out "$RESULTS" --quiet >"$TMP/reproduce.log" 2>&1 \
    || { tail -n 40 "$TMP/reproduce.log" >&2; fail "pronet reproduce --quick failed"; }
  TIME[reproduce]=$(( $(now) - t ))
  for f in table.md metrics.json metrics.csv config.json; do
    [ -s "$RESULTS/$f" ] || fail "reproduce wrote no $f in $RESULTS"
  done
  shopt -s nullglob
  pngs=("$RESULTS"/*.png)
  shopt -u nullglob
  [ "${#pngs[@]}" -ge 1 ] || fail "reproduce wrote no .png in $RESULTS"
  echo "   $RESULTS: table.md metrics.json metrics.csv config.json and ${#pngs[@]} PNGs"
fi

times="install ${TIME[install]}s, light commands ${TIME[light]}s"
[ -n "${TIME[build]:-}" ] && times="build ${TIME[build]}s, $times"
[ -n "${TIME[reproduce]:-}" ] && times="$times, torch extra ${TIME[torch]}s, reproduce ${TIME[reproduce]}s"
echo "check_wheel: PASS $WHEEL_NAME ($WHEEL_SIZE, $tag; $times)"
