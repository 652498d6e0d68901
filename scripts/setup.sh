#!/usr/bin/env bash
# Idempotent set-up: system library for Open3D, a virtual environment in .venv/, the
# package (editable) with its test extras, the recordings extra (ROS bags), the dask
# extra (dgli label --dask) and the realsense extra (the RealSense SDK).
# Safe to run again; fast when nothing changed.
set -euo pipefail
cd "$(dirname "$0")/.."

# Open3D's wheel links against libusb-1.0 (Azure Kinect support).
if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1\.0\.so'; then
    echo "setup: installing libusb-1.0-0 (needed by Open3D)" >&2
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    if ! "$PY" -m venv .venv 2>/dev/null; then
        # Debian's own python3 ships venv separately.
        rm -rf .venv
        echo "setup: installing python3-venv" >&2
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null
        "$PY" -m venv .venv
    fi
fi

stamp=.venv/.dgli-setup-stamp
want=$(cat pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
    .venv/bin/python -m pip install -q --disable-pip-version-check -e '.[test,recordings,dask,realsense]'
    echo "$want" > "$stamp"
fi

# photoreal: Blender as a Python module, for `dgli render --engine cycles`. Its bpy needs
# numpy < 2 (and so OpenCV 4.11), which the main environment is not moved to: the extra
# gets a virtual environment of its own, .venv-photoreal/ (Python 3.11 only, as bpy;
# about 20 s from a package cache, 1.5 GB). DGLI_NO_PHOTOREAL=1 skips it.
if [ "${DGLI_NO_PHOTOREAL:-0}" != "1" ] \
    && "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
    if [ ! -x .venv-photoreal/bin/python ]; then
        "$PY" -m venv .venv-photoreal
    fi
    stamp=.venv-photoreal/.dgli-setup-stamp
    if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
        if .venv-photoreal/bin/python -m pip install -q --disable-pip-version-check --upgrade pip \
            && .venv-photoreal/bin/python -m pip install -q --disable-pip-version-check \
                -e '.[photoreal]'; then
            echo "$want" > "$stamp"
        else
            echo "setup: the photoreal extra (bpy) did not install; its tests will skip" >&2
        fi
    fi
fi
