#!/usr/bin/env bash
# Install what usv_mj needs on a fresh Debian machine: the Mesa GL stack for headless rendering
# (EGL, with OSMesa as the fallback; no GPU needed), a virtual X display (xvfb, and xauth for
# xvfb-run) on which the tests open `usv-mj view`'s window, and the Python package with its test extras.
# Idempotent: a second run only checks.
set -euo pipefail
cd "$(dirname "$0")/.."

SYSTEM_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libosmesa6 xvfb xauth)
missing=()
for pkg in "${SYSTEM_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PYTHON=${PYTHON:-python3}
if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  echo "setup: usv_mj needs Python 3.11 or newer ($PYTHON is $("$PYTHON" --version 2>&1))" >&2
  exit 1
fi
echo "setup: installing usv_mj and its Python dependencies"
# stable-baselines3 (the tests' RL client) needs torch: the CPU build, not a CUDA build of several GB
if ! "$PYTHON" -c 'import torch' 2>/dev/null; then
  echo "setup: installing torch (CPU build) for the RL client test"
  "$PYTHON" -m pip install --disable-pip-version-check -q "torch==2.13.0" 2>&1 | grep -v "Running pip as the 'root' user" || true
fi
"$PYTHON" -m pip install --disable-pip-version-check -q -e ".[test,gym,hpc,rl,live]" 2>&1 | grep -v "Running pip as the 'root' user" || true
# the KVLCC2 oracle (pyproject's "oracles" extra) without its pins: Pillow < 11 and scikit-learn,
# neither of which its simulate_mmg_3dof imports (it needs numpy, scipy and matplotlib, all present)
if ! "$PYTHON" -c 'import shipmmg.mmg_3dof' 2>/dev/null; then
  "$PYTHON" -m pip install --disable-pip-version-check -q --no-deps "shipmmg==0.0.11" 2>&1 | grep -v "Running pip as the 'root' user" || true
fi
"$PYTHON" -c "import usv_mj, mujoco; print(f'setup: usv_mj {usv_mj.__version__} with mujoco {mujoco.__version__} ready')"
# numba compiles the kernels and the main job's loop combinations once per checkout (about 15 s on
# a fresh machine): done here, with a stamp per source fingerprint, so that the main job starts warm
warm_stamp=$("$PYTHON" -c "from usv_mj.loop.generate import _source_fingerprint, cache_dir; print(cache_dir() / ('warm-' + _source_fingerprint()))")
if [ ! -e "$warm_stamp" ]; then
  echo "setup: compiling the simulation kernels (once per checkout)"
  warm_dir=$(mktemp -d)
  "$PYTHON" -m usv_mj.cli run --duration 0.05 --no-video -q --out "$warm_dir/warm" >/dev/null
  rm -rf "$warm_dir"
  touch "$warm_stamp"
fi
