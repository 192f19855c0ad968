#!/usr/bin/env bash
# Set up a fresh Debian/Ubuntu machine: system libraries, .venv/ with the pinned packages
# (requirements.txt) and blendlib installed editable, then render every example scene to
# out/*.png. Safe to run again (idempotent).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# EGL/Mesa for the OpenGL reference (moderngl on llvmpipe); X/GL client libraries that the bpy
# module loads even in background mode; python3.11 + venv if missing.
PACKAGES="libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libglx-mesa0 libxrender1 libxi6 libxxf86vm1 \
libxfixes3 libxkbcommon0 libsm6 libice6 libx11-6 libxext6 libxrandr2 libxinerama1 libxcursor1 libgomp1"
if command -v apt-get >/dev/null 2>&1; then
    missing=""
    for p in $PACKAGES; do
        dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
    done
    if ! command -v python3.11 >/dev/null 2>&1; then missing="$missing python3.11 python3.11-venv"; fi
    if [ -n "$missing" ]; then
        $SUDO apt-get update
        $SUDO apt-get install -y --no-install-recommends $missing
    fi
else
    echo "warning: not a Debian system; install the EGL/Mesa and X client libraries yourself" >&2
fi

PY=python3.11
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
.venv/bin/python -m pip install --upgrade pip >/dev/null
.venv/bin/python -m pip install -r requirements.txt
# The project itself, editable: scripts and tests import blendlib without path tricks. Built with
# the pinned setuptools of requirements.txt (no isolated build environment to download).
.venv/bin/python -m pip install --no-deps --no-build-isolation -e .

# The example scenes as F12 renders them (out/<file>.png), then every scene of every file and the
# gallery contact sheet (out/gallery.png; docs/gallery.png is the committed copy).
.venv/bin/python scripts/render_examples.py
.venv/bin/python -m scripts.make_gallery --sheet out/gallery.png
