"""Installable: a wheel built from the repository carries the reference set and its
``dgli-classify`` works outside the source tree without ``--references``."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_images"
SOURCES = ["pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "dgli_vision", "references"]


def _run(*args: str | Path, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, **kw)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """A fresh venv holding only the wheel; the dependencies come from this test's own
    environment through a path file (so that nothing is downloaded)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy2(ROOT / name, src / name)
    built = _run(
        sys.executable,
        "-m",
        "pip",
        "wheel",
        "-q",
        "--no-deps",
        "--no-build-isolation",
        "-w",
        tmp / "dist",
        src,
        cwd=tmp,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = (tmp / "dist").glob("dgli_vision-*.whl")
    venv = tmp / "venv"
    made = _run(sys.executable, "-m", "venv", venv)
    assert made.returncode == 0, made.stderr
    py = venv / "bin" / "python"
    site = _run(py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])")
    (Path(site.stdout.strip()) / "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    inst = _run(py, "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel)
    assert inst.returncode == 0, inst.stderr
    return venv


def test_the_wheel_carries_the_shipped_reference_set(installed):
    py = installed / "bin" / "python"
    r = _run(
        py,
        "-c",
        "import dgli_vision.classifier.references as r; print(r.default_references_path())",
        cwd=installed,
        env={"PATH": "/usr/bin:/bin"},
    )
    packaged = Path(r.stdout.strip())
    assert packaged.is_relative_to(installed), packaged
    assert packaged.read_bytes() == (ROOT / "references" / "default.json").read_bytes()


@pytest.mark.parametrize("sample", ["05_000", "11_000"])
def test_an_installed_dgli_classify_classifies_a_sample(installed, sample):
    r = _run(
        installed / "bin" / "dgli-classify",
        SAMPLES / f"{sample}_color.png",
        SAMPLES / f"{sample}_depth.png",
        "--intrinsics",
        SAMPLES / "intrinsics.json",
        "--json",
        cwd=installed,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["class"] == sample[:2]
