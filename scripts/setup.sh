#!/usr/bin/env bash
# Creates .venv with dloroute and everything it needs (CPU torch, headless GL). Idempotent and quick
# when nothing changed. Usage: bash scripts/setup.sh
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

# Headless rendering: Mesa EGL (default) and OSMesa (fallback, MUJOCO_GL=osmesa).
GL_PKGS="libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6"
missing=$(for p in $GL_PKGS; do dpkg -s "$p" >/dev/null 2>&1 || echo "$p"; done)
if [ -n "$missing" ]; then
  if [ "$(id -u)" = 0 ]; then
    echo "installing headless GL packages: $missing"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >/dev/null
  else
    echo "warning: missing Debian packages for headless rendering ($missing); run: sudo apt-get install $missing" >&2
  fi
fi

stamp="$VENV/.dloroute-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  [ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip
  # The CPU build of torch first, so that stable-baselines3 does not pull a CUDA build.
  "$VENV/bin/pip" install -q torch==2.13.0
  "$VENV/bin/pip" install -q -e ".[rl,dev]"
  touch "$stamp"
fi
