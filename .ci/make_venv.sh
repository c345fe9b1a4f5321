#!/bin/sh
# Create the virtual environment with a CPython the ROS 2 Jazzy wheels support (3.10-3.13).
# On Debian/Ubuntu the venv module may lack ensurepip (package python3-venv): install it
# when we are root, otherwise say exactly what to install.
set -eu
VENV=${1:-.venv}
if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c 'import pip' 2>/dev/null; then exit 0; fi

PY=""
for cand in ${PYTHON:-} python3.12 python3.11 python3.13 python3.10 python3; do
  # 2>/dev/null: a pyenv shim exists for versions it has not installed, and says so
  if command -v "$cand" >/dev/null 2>&1 && "$cand" 2>/dev/null -c 'import sys; sys.exit(not ((3,10) <= sys.version_info[:2] <= (3,13)))'; then
    PY=$cand; break
  fi
done
if [ -z "$PY" ]; then
  echo "error: need CPython 3.10-3.13 (ROS 2 Jazzy wheels); set PYTHON=/path/to/python3.X" >&2
  exit 1
fi

rm -rf "$VENV"
if ! "$PY" -m venv "$VENV" 2>/dev/null; then
  ver=$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "python venv support missing: installing python$ver-venv with apt-get" >&2
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "python$ver-venv" || \
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
  else
    echo "error: '$PY -m venv' failed; install it with: sudo apt-get install python$ver-venv" >&2
    exit 1
  fi
fi
"$VENV/bin/python" -m pip install --disable-pip-version-check -q --upgrade pip setuptools wheel
