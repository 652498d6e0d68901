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
