#!/bin/sh
# Build the ROS 2 interface packages in interfaces/ (tf2_msgs, simulation_interfaces) into
# the venv, which is also an ament prefix. PyPI has no wheels for them, but it has the
# rosidl generators (pinned in requirements.txt), so they are generated and compiled here:
# C code, the C typesupports rmw_fastrtps loads, and the Python modules, installed into the
# venv's lib/, lib/pythonX.Y/site-packages/ and share/ like the ros-jazzy wheels' own
# interface packages. The ros_wheels_bootstrapper already puts <venv>/lib on
# LD_LIBRARY_PATH for every venv Python process, so nothing needs sourcing.
#
# Cached: skipped when the venv already holds a build of the same inputs (interface files,
# this script, the CMake helpers, the ROS/CMake pins and the Python version).
#
# Usage: sh .ci/build_interfaces.sh [VENV]     (make venv runs it)
set -eu

VENV=${1:-.venv}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
[ -x "$VENV/bin/python" ] || { echo "error: no venv at $VENV (run make venv)" >&2; exit 1; }
VENV=$(cd "$VENV" && pwd)
PY=$VENV/bin/python
PKGS="tf2_msgs simulation_interfaces"
STAMP=$VENV/.rigid_body_sim-interfaces
BUILD=$VENV/.interfaces-build
LOG=$VENV/interfaces-build.log

# Build and check against the venv alone: a sourced ROS install (PYTHONPATH, LD_LIBRARY_PATH,
# AMENT_PREFIX_PATH, CMAKE_PREFIX_PATH) must neither feed the build nor pass the checks.
# The bootstrapper's guard goes too, so the venv's Python sets its LD_LIBRARY_PATH again.
unset PYTHONPATH LD_LIBRARY_PATH _ROS_WHEELS_BOOTSTRAP_COMPLETE
export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH"

say() { echo "interfaces: $*"; }
die() { echo "error: $*" >&2; exit 1; }

imports_ok() {
  "$PY" -c 'import tf2_msgs.msg, simulation_interfaces.msg, simulation_interfaces.srv' \
    >/dev/null 2>&1
}

# Everything the build depends on; a change in any of it rebuilds.
inputs_key() {
  (
    cd "$ROOT"
    find interfaces .ci/build_interfaces.sh .ci/wheel_cmake_paths.cmake -type f ! -name README.md \
      | LC_ALL=C sort | xargs sha256sum
    grep -E '^(ros-jazzy-|cmake==|ninja==|numpy==)' requirements.txt
    "$PY" -c 'import sys; print(sys.version)'
  ) | sha256sum | cut -d' ' -f1
}

KEY=$(inputs_key)
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$KEY" ] && imports_ok; then
  say "tf2_msgs, simulation_interfaces up to date"
  exit 0
fi

# --- tools: say which one is missing before a long build fails on it ---
CMAKE=$VENV/bin/cmake
NINJA=$VENV/bin/ninja
[ -x "$CMAKE" ] && [ -x "$NINJA" ] || \
  die "cmake/ninja missing from $VENV (pinned in requirements.txt): $VENV/bin/pip install -r requirements.txt"
[ -f "$VENV/share/rosidl_default_generators/cmake/rosidl_default_generatorsConfig.cmake" ] || \
  die "ROS 2 rosidl generator wheels missing from $VENV: $VENV/bin/pip install -r requirements.txt"
CC_BIN=${CC:-cc}
CXX_BIN=${CXX:-c++}
command -v "$CC_BIN" >/dev/null 2>&1 || \
  die "no C compiler ('$CC_BIN'): install gcc (Debian/Ubuntu: sudo apt-get install gcc), or set CC"
command -v "$CXX_BIN" >/dev/null 2>&1 || \
  die "no C++ compiler ('$CXX_BIN'): install g++ (Debian/Ubuntu: sudo apt-get install g++), or set CXX"
PYINC=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
PYVER=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
[ -f "$PYINC/Python.h" ] || \
  die "Python headers missing ($PYINC/Python.h): install python$PYVER-dev (Debian/Ubuntu: sudo apt-get install python$PYVER-dev)"
"$PY" -c 'import numpy' 2>/dev/null || die "numpy missing from $VENV: $VENV/bin/pip install -r requirements.txt"

JOBS=$(nproc 2>/dev/null || echo 2)
: >"$LOG"
# run STAGE CMD...: the command's output goes to the log; on failure, show its tail.
run() {
  stage=$1; shift
  echo "== $stage: $*" >>"$LOG"
  if ! "$@" >>"$LOG" 2>&1; then
    echo "error: interfaces: $stage failed; last lines of $LOG:" >&2
    tail -n 25 "$LOG" >&2
    exit 1
  fi
}

say "building tf2_msgs, simulation_interfaces into $VENV (once; log: $LOG)"
start=$(date +%s)
rm -rf "$BUILD"
for pkg in $PKGS; do
  # A rebuild replaces the previous install, so files of renamed or removed types go.
  manifest=$VENV/share/$pkg/install_manifest.txt
  if [ -f "$manifest" ]; then
    xargs rm -f <"$manifest"
  fi
  t0=$(date +%s)
  say "$pkg: configure"
  # Default build type (no optimisation flags): these are small marshalling routines, and
  # -O2 would lengthen the one-off build more than it would ever save.
  run "$pkg: configure" "$CMAKE" -S "$ROOT/interfaces/$pkg" -B "$BUILD/$pkg" -G Ninja \
    -DCMAKE_MAKE_PROGRAM="$NINJA" \
    -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DCMAKE_PROJECT_INCLUDE="$ROOT/.ci/wheel_cmake_paths.cmake" \
    -DPython3_EXECUTABLE="$PY" -DPYTHON_EXECUTABLE="$PY" \
    -DBUILD_TESTING=OFF
  say "$pkg: compile (C, C typesupports, Python)"
  run "$pkg: compile" "$CMAKE" --build "$BUILD/$pkg" -j "$JOBS"
  say "$pkg: install"
  run "$pkg: install" "$CMAKE" --install "$BUILD/$pkg"
  cp "$BUILD/$pkg/install_manifest.txt" "$manifest"
  echo "   $pkg: $(( $(date +%s) - t0 )) s" >>"$LOG"
done

imports_ok || die "interfaces: built, but 'import tf2_msgs.msg, simulation_interfaces.srv' fails in $PY (see $LOG)"
rm -rf "$BUILD"
echo "$KEY" >"$STAMP"
say "done in $(( $(date +%s) - start )) s"
