#!/usr/bin/env bash
# Create/refresh .venv (python3.11) with every dependency pinned by constraints.txt, then
# install src/flex_model, src/flex_control, src/flex_planner and src/flex_twin as editable
# packages, then build tf2_msgs and control_msgs into it (step 5; needs gcc and g++).
#
# Fast path: a stamp file (.venv/.bootstrap-stamp) holds a hash of constraints.txt, the four
# setup.py files, this script, the interface generator (scripts/gen_interfaces.py and the
# definitions in scripts/interfaces) and the interpreter version; if it matches, nothing is done.
# If it does not match, .venv is rebuilt from scratch (so no unpinned leftovers survive); if
# only step 5 is missing (.venv/.bootstrap-core holds the hash: a background build failed or
# was killed), only step 5 runs.
#
# Step 5 needs only step 2's generator wheels: it runs beside steps 3-4 (one core each). With
# --interfaces-in-background (make demo: the demo needs neither package) the script returns
# after step 4 and step 5 finishes behind it, holding the lock (.venv.lock) and writing the
# stamp when done; a later bootstrap.sh waits for it. --demo (make demo) does the same, at
# the lowest priority (nice 19) for step 5, and also starts compiling the twin demo's
# in-loop kernels once step 2's wheels are in (python -m flex_twin.twin_demo_ahead from src/,
# at normal priority: the critical path of a first make demo; the demo waits for it).
# Each step logs its wall and CPU seconds.
#
# Env: PYTHON=/path/to/python3.11 to choose the interpreter; FORCE=1 to rebuild regardless.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
STAMP="$VENV/.bootstrap-stamp"
CONSTRAINTS="$ROOT/constraints.txt"
PACKAGES=(src/flex_model src/flex_control src/flex_planner src/flex_twin)
# Top-level requirements; every version (and every transitive one) comes from constraints.txt.
REQUIREMENTS=(
  "ros-jazzy-rclpy[fastrtps]"
  ros-jazzy-common-interfaces
  numpy scipy numba pyyaml matplotlib
  mcap mcap-ros2-support rosbags
  distributed
  pytest pytest-xdist  # make test runs on two workers (pytest -n)
  foxglove-sdk websockets  # live view (flex-twin view), its tests' WebSocket client
)

log() { printf '[bootstrap] %s\n' "$*" >&2; }

find_python() {
  local cand
  for cand in "${PYTHON:-}" python3.11 python3; do
    [ -n "$cand" ] || continue
    command -v "$cand" >/dev/null 2>&1 || continue
    if "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      command -v "$cand"
      return 0
    fi
  done
  log "error: Python 3.11 not found (tried \$PYTHON, python3.11, python3)"
  return 1
}

BACKGROUND=0; DEMO=0
case "${1:-}" in
  --interfaces-in-background) BACKGROUND=1 ;;
  --demo) BACKGROUND=1; DEMO=1 ;;
  "") ;;
  *) log "error: unknown option $1 (only --interfaces-in-background or --demo)"; exit 2 ;;
esac
# step 5 beside the demo takes what the demo leaves of the cores
NICE=(env)
if [ "$DEMO" = 1 ]; then NICE=(nice -n 19); fi

# CPU seconds (user+sys) of this script's finished children so far (/proc/<pid>/stat
# fields 16-17, in clock ticks)
TICKS="$(getconf CLK_TCK 2>/dev/null || echo 100)"
cpu_now() { awk -v hz="$TICKS" '{ printf "%.2f", ($16 + $17) / hz }' "/proc/$1/stat"; }
step_t0=0; step_c0=0
step_start() { local me=$BASHPID; step_t0=$(date +%s.%N); step_c0=$(cpu_now "$me"); }
step_done() {
  local me=$BASHPID c1
  c1=$(cpu_now "$me")
  log "$(awk -v t0="$step_t0" -v t1="$(date +%s.%N)" -v c0="$step_c0" -v c1="$c1" \
    -v what="$1" 'BEGIN { printf "%s: %.1f s wall, %.1f CPU-s", what, t1 - t0, c1 - c0 }')"
}

PY="$(find_python)"
# From inside an active .venv, python3.11 is the venv's own, which the rebuild deletes: use the
# base interpreter it was made from.
PY="$("$PY" -c 'import os, sys; b = os.path.join(sys.base_prefix, "bin", "python3"); print(b if os.path.exists(b) else sys.executable)')"
PYVER="$("$PY" -c 'import sys; print(sys.version.split()[0])')"

stamp_value() {
  {
    echo "python=$PYVER"
    cat "$CONSTRAINTS" "$ROOT/scripts/bootstrap.sh"
    cat "$ROOT/scripts/gen_interfaces.py" "$ROOT"/scripts/interfaces/*/*/*  # step 5's inputs
    local p
    for p in "${PACKAGES[@]}"; do cat "$ROOT/$p/setup.py"; done
  } | sha256sum | cut -d' ' -f1
}

# One bootstrap at a time (e.g. `make -j test demo`).
exec 9>"$ROOT/.venv.lock"
if command -v flock >/dev/null 2>&1; then flock 9; fi

WANT="$(stamp_value)"
CORE_STAMP="$VENV/.bootstrap-core"
if [ "${FORCE:-0}" != 1 ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ] \
   && "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
  log ".venv is up to date ($VENV)"
  exit 0
fi

# 5) tf2_msgs and control_msgs, which no PyPI wheel carries (issue 46): generated from the
#    definitions in scripts/interfaces by the rosidl generator wheels of step 2, compiled
#    with gcc/g++ (on every machine of this project; installed here if missing and apt-get can),
#    installed into .venv only (lib/, site-packages/, share/; build files in build-interfaces/).
need_compilers() {
  command -v gcc >/dev/null 2>&1 && command -v g++ >/dev/null 2>&1 && return 0
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    log "installing gcc g++ (apt-get) for the interface build"
    apt-get install -y -q gcc g++ >/dev/null || { apt-get update -q >/dev/null && apt-get install -y -q gcc g++ >/dev/null; }
  else
    log "error: gcc and g++ are needed to build tf2_msgs/control_msgs (apt-get install gcc g++)"
    return 1
  fi
}
interfaces() {  # returns non-zero on failure also where set -e does not apply (a && b)
  step_start
  "${NICE[@]}" "$VENV/bin/python" "$ROOT/scripts/gen_interfaces.py" --venv "$VENV" \
    || { log "error: step 5 (interfaces) failed; bootstrap.sh tries it again"; return 1; }
  step_done "5) interfaces (tf2_msgs, control_msgs)"
}
finish() {
  echo "$WANT" > "$STAMP"
  log "done in $(( $(date +%s) - start )) s"
}

start=$(date +%s)
if [ "${FORCE:-0}" != 1 ] && [ -f "$CORE_STAMP" ] && [ "$(cat "$CORE_STAMP")" = "$WANT" ]; then
  log "steps 1-4 are up to date; step 5 again (an earlier build of it did not finish)"
  need_compilers
  interfaces
  finish
  exit 0
fi
if [ -e "$VENV" ]; then
  log "rebuilding stale .venv"
  rm -rf "$VENV"
fi
need_compilers
log "creating .venv with $PY ($PYVER)"
export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_INPUT=1
[ "${CI:-}" = "true" ] && export PIP_PROGRESS_BAR=off
# The ros-* wheels ship a .pth hook (ros_wheels_bootstrapper) that re-execs every Python
# started from this venv with LD_LIBRARY_PATH extended; harmless here, just noted.
pip_install() { "$VENV/bin/python" -m pip install -c "$CONSTRAINTS" "$@"; }
# uv installs the same pinned set as pip, in parallel: the ~125 wheels in about 5 s instead
# of about a minute (2026-12-07, docs/development.md). It comes (pinned) from the base
# interpreter's pip into .venv/uv-tool, so the venv starts without ensurepip's old pip;
# where that is not to be had, the venv gets pip and pip installs everything.
UV="$VENV/uv-tool/bin/uv"
step_start
"$PY" -m venv --without-pip "$VENV"
if ! "$PY" -m pip install -q -c "$CONSTRAINTS" --target "$VENV/uv-tool" uv >/dev/null \
    || ! "$UV" --version >/dev/null 2>&1; then
  log "uv not to be had; pip installs everything (slower)"
  UV=""
  "$VENV/bin/python" -m ensurepip --upgrade >/dev/null
fi
step_done "0) venv and uv"
fast_install() {
  if [ -n "$UV" ]; then
    "$UV" pip install --python "$VENV/bin/python" -c "$CONSTRAINTS" "$@" && return 0
    log "uv failed; installing with pip"
    "$VENV/bin/python" -m pip --version >/dev/null 2>&1 \
      || "$VENV/bin/python" -m ensurepip --upgrade >/dev/null
  fi
  pip_install "$@"
}
# Keep colcon (run from the repo root by mistake) from discovering the ROS packages that the
# ros-* wheels put under .venv/share.
touch "$VENV/COLCON_IGNORE"

cd "$ROOT"
step_start
# 1) build tooling at the pinned versions (pip for `pip check` and users, setuptools for the
#    editable installs and the one sdist).
fast_install pip setuptools wheel
# 2) pinned runtime deps. --no-build-isolation: the one sdist (empy) builds with the pinned
#    setuptools above instead of whatever an isolated build env would download. --demo:
#    first what the demo's compile needs, which then starts (not holding the lock, fd 9;
#    its output in .venv/twin-demo-ahead.log), beside the rest
if [ "$DEMO" = 1 ]; then
  fast_install numpy scipy numba pyyaml
  PYTHONPATH="$ROOT/src/flex_model:$ROOT/src/flex_control:$ROOT/src/flex_twin" \
    "$VENV/bin/python" -m flex_twin.twin_demo_ahead </dev/null \
    >"$VENV/twin-demo-ahead.log" 2>&1 9>&- &
  log "the twin demo's kernels compile from here on (pid $!)"
fi
fast_install --no-build-isolation "${REQUIREMENTS[@]}"
step_done "1-2) pinned wheels"
# 5) from here on, beside steps 3-4 (it needs only step 2's wheels); in the background
#    mode it also writes the stamp when it is done, holding the lock (fd 9) until then
if [ "$BACKGROUND" = 1 ]; then
  ( interfaces && finish ) &
else
  interfaces &
fi
gen_pid=$!
step_start
# 3) the project's packages, editable (PEP 660 via setuptools; no deps to resolve beyond the
#    pinned set above). flex_model first: the others import it;
#    flex_twin last: it imports all three.
editable=()
for p in "${PACKAGES[@]}"; do editable+=(-e "$p"); done
fast_install --no-build-isolation --no-deps "${editable[@]}"
if [ -n "$UV" ]; then "$UV" pip check --python "$VENV/bin/python"
else "$VENV/bin/python" -m pip check; fi
# 4) setuptools' editable (PEP 660) wheels do not install data_files, so register the packages
#    in the venv's ament index by hand (symlinks into src/, like colcon --symlink-install).
#    With AMENT_PREFIX_PATH=$VIRTUAL_ENV (scripts/env.sh), get_package_share_directory() works.
for p in "${PACKAGES[@]}"; do
  name="$(basename "$p")"
  mkdir -p "$VENV/share/ament_index/resource_index/packages" "$VENV/share/$name"
  : > "$VENV/share/ament_index/resource_index/packages/$name"
  ln -sfn "$ROOT/$p/package.xml" "$VENV/share/$name/package.xml"
done
# flex_model's presets (linked even before the directory exists, so it goes live when it does)
ln -sfn "$ROOT/src/flex_model/flex_model/presets" "$VENV/share/flex_model/presets"
step_done "3-4) editable packages, check, ament index"
echo "$WANT" > "$CORE_STAMP"

if [ "$BACKGROUND" = 1 ]; then
  log "step 5 goes on in the background (pid $gen_pid); a later bootstrap.sh waits for it"
  exit 0
fi
wait "$gen_pid"
finish
