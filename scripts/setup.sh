#!/usr/bin/env bash
# Idempotent set-up. Safe to run again; fast when nothing changed.
#
#   scripts/setup.sh          what classifying needs: a virtual environment in .venv/
#                             and the package (editable), nothing more
#   scripts/setup.sh --test   that, and what the tests need: the test extras, the sim
#                             extra (Open3D: the renderer and meshes) with the system
#                             library it links against (libusb-1.0), the
#                             recordings extra (ROS bags), the dask extra (dgli label
#                             --dask), the realsense extra (the RealSense SDK), the docs
#                             extra (Sphinx: the site's build is a test), the viewer
#                             extra (the Rerun SDK: dgli watch --rerun), Debian's
#                             chromium (the HTML report tests) and, in .venv-photoreal/,
#                             Blender as a Python module (the photoreal extra)
set -euo pipefail
cd "$(dirname "$0")/.."

mode=classify
case "${1:-}" in
    "") ;;
    --test) mode=test ;;
    *) echo "usage: scripts/setup.sh [--test]" >&2; exit 2 ;;
esac

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

# Open3D's wheel (the sim extra, --test) links against libusb-1.0 (Azure Kinect support).
# The cache is read whole before grep: `ldconfig -p | grep -q` under pipefail fails when
# grep stops at the first match and ldconfig dies of SIGPIPE, and apt-get would run
# again for nothing.
libs=$(ldconfig -p 2>/dev/null || true)
if [ "$mode" = test ] && ! grep -q 'libusb-1\.0\.so' <<<"$libs"; then
    echo "setup: installing libusb-1.0-0 (needed by Open3D)" >&2
    apt_install libusb-1.0-0
fi

# Headless Chromium: tests/test_html_pages.py opens every HTML report in it.
if [ "$mode" = test ] && ! command -v chromium >/dev/null 2>&1; then
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

# .dgli-setup-stamp: the package installed for this pyproject.toml; .dgli-test-stamp:
# the test extras too (a --test set-up writes both, so the plain one then does nothing)
want=$(cat pyproject.toml | sha256sum | cut -d' ' -f1)
stamp=.venv/.dgli-setup-stamp
extras=""
if [ "$mode" = test ]; then
    stamp=.venv/.dgli-test-stamp
    # one extra a line (pyproject.toml says what each is for)
    test_extras=(
        test
        sim
        recordings
        dask
        realsense
        docs
        viewer
        physics
    )
    extras="[$(IFS=,; echo "${test_extras[*]}")]"
fi
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
    # setuptools warns "Editable installation" (a dozen lines) on every editable install
    # (here and in .venv-photoreal/ below); only that warning is silenced, errors show
    PYTHONWARNINGS="ignore:Editable installation" \
        .venv/bin/python -m pip install -q --disable-pip-version-check \
        -e ".$extras"
    echo "$want" > "$stamp"
    echo "$want" > .venv/.dgli-setup-stamp
fi

# photoreal (--test): Blender as a Python module (and Open3D, the sim extra, which the
# renderer reads meshes with), for `dgli render --engine cycles`. Its
# bpy needs numpy < 2 (and so OpenCV 4.11), which the main environment is not moved to: the extra
# gets a virtual environment of its own, .venv-photoreal/ (Python 3.11 only, as bpy;
# about 20 s from a package cache, 1.5 GB). DGLI_NO_PHOTOREAL=1 skips it.
if [ "$mode" = test ] && [ "${DGLI_NO_PHOTOREAL:-0}" != "1" ] \
    && "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
    if [ ! -x .venv-photoreal/bin/python ]; then
        "$PY" -m venv .venv-photoreal
    fi
    stamp=.venv-photoreal/.dgli-setup-stamp
    if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
        if .venv-photoreal/bin/python -m pip install -q --disable-pip-version-check --upgrade pip \
            && PYTHONWARNINGS="ignore:Editable installation" \
                .venv-photoreal/bin/python -m pip install -q --disable-pip-version-check \
                -e '.[photoreal,sim]'; then
            echo "$want" > "$stamp"
        else
            echo "setup: the photoreal extra (bpy) did not install; its tests will skip" >&2
        fi
    fi
fi
