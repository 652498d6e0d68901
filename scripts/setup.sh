#!/usr/bin/env bash
# Idempotent set-up: system library for Open3D, a virtual environment in .venv/, the
# package (editable) with its test extras, the recordings extra (ROS bags), the dask
# extra (dgli label --dask) and the realsense extra (the RealSense SDK).
# Safe to run again; fast when nothing changed.
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
apt_updated=""
apt_install() {
    # apt_install PACKAGE...: quietly, with one `apt-get update` per run at most
    if [ -z "$apt_updated" ]; then
        $SUDO apt-get update -qq
        apt_updated=1
    fi
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "$@" \
        >/dev/null
}

# Open3D's wheel links against libusb-1.0 (Azure Kinect support). The cache is read whole
# before grep: `ldconfig -p | grep -q` under pipefail fails when grep stops at the first
# match and ldconfig dies of SIGPIPE, and apt-get would run again for nothing.
libs=$(ldconfig -p 2>/dev/null || true)
if ! grep -q 'libusb-1\.0\.so' <<<"$libs"; then
    echo "setup: installing libusb-1.0-0 (needed by Open3D)" >&2
    apt_install libusb-1.0-0
fi

# Headless Chromium: tests/test_html_pages.py opens every HTML report in it.
if ! command -v chromium >/dev/null 2>&1; then
    echo "setup: installing chromium (the HTML report tests open pages in it)" >&2
    apt_install chromium || echo "setup: chromium not installed; the browser tests skip" >&2
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    if ! "$PY" -m venv .venv 2>/dev/null; then
        # Debian's own python3 ships venv separately.
        rm -rf .venv
        echo "setup: installing python3-venv" >&2
        apt_install python3-venv
        "$PY" -m venv .venv
    fi
fi

stamp=.venv/.dgli-setup-stamp
want=$(cat pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
    # setuptools warns "Editable installation" (a dozen lines) on every editable install
    # (here and in .venv-photoreal/ below); only that warning is silenced, errors show
    PYTHONWARNINGS="ignore:Editable installation" \
        .venv/bin/python -m pip install -q --disable-pip-version-check \
        -e '.[test,recordings,dask,realsense]'
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
            && PYTHONWARNINGS="ignore:Editable installation" \
                .venv-photoreal/bin/python -m pip install -q --disable-pip-version-check \
                -e '.[photoreal]'; then
            echo "$want" > "$stamp"
        else
            echo "setup: the photoreal extra (bpy) did not install; its tests will skip" >&2
        fi
    fi
fi
