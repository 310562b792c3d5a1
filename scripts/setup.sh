#!/usr/bin/env bash
# Sets up a fresh Debian/Ubuntu machine for mpcde: system packages, a virtual
# environment in .venv, the CPU build of torch first, then the package itself with
# every dependency at the version in requirements-lock.txt.
# Idempotent: a second run only checks.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${VENV:-.venv}"
PYTHON="${PYTHON:-python3.11}"
command -v "$PYTHON" >/dev/null 2>&1 || PYTHON=python3

# open3d's wheel links libusb-1.0; ffmpeg comes with imageio-ffmpeg's wheel.
if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    echo "[setup] installing system package libusb-1.0-0"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
    echo "[setup] creating virtual environment $VENV"
    "$PYTHON" -m venv "$VENV"
fi
PIP="$VENV/bin/python -m pip"
# Not --no-compile: it shortens setup, but where PYTHONDONTWRITEBYTECODE is set (this machine, and
# multiprocessing's spawned children run with -B) no .pyc is ever written, and every process then compiles
# torch's modules from source on every import, so the tests run far slower (docs/results/ci_time.md).
pip_install() {  # quiet pip install; on failure print pip's output and stop
    local out
    if ! out=$($PIP install -q "$@" 2>&1); then
        echo "$out" >&2
        echo "[setup] pip install $* failed" >&2
        exit 1
    fi
    echo "$out" | grep -v -e '^WARNING: Location' -e '^$' || true
}
stamp="$VENV/.mpcde-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ requirements-lock.txt -nt "$stamp" ]; then
    pip_install --upgrade pip setuptools wheel
    # torch pinned first, so that no dependency pulls another build. Which build the pin gets is pip's configuration's
    # choice: the CPU one on this project's machines; from plain PyPI on Linux, set PIP_EXTRA_INDEX_URL to PyTorch's
    # CPU index (README).
    pip_install "torch==2.13.0"
    # Every other dependency at the version in requirements-lock.txt (why: that file's header).
    pip_install -c requirements-lock.txt -e ".[dev,ray,env,nlp]"
    "$VENV/bin/python" -c "import torch, pybullet, open3d, osqp, filterpy, cv2, imageio_ffmpeg, ray, hypothesis, pettingzoo, gymnasium, casadi; print('[setup] torch', torch.__version__, '| pybullet ok | open3d', open3d.__version__)"
    touch "$stamp"
fi
