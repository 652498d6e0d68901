"""scripts/setup.sh, run in a scratch copy of the repository with stand-ins for ldconfig,
apt-get and the virtual environment's python: it decides from what is installed, it
keeps setuptools' "Editable installation" warning off the screen, and the plain set-up
(the README's first command) installs what classifying needs and nothing more: the
browser, the test extras and Blender come with ``--test``."""

from __future__ import annotations

import hashlib
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASH = shutil.which("bash")

# setuptools' warning, as pip passes it on from the build backend
_EDITABLE_WARNING = '''\
import sys, warnings
if "install" in sys.argv and "-e" in sys.argv:
    warnings.warn("Editable installation.\\n!!\\n  Please be careful with folders")
    print("ERROR: a real pip error", file=sys.stderr)
'''


def _executable(path: Path, text: str) -> None:
    path.write_text(text)
    path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)


def _scratch(tmp_path: Path, *, stamp_matches: bool) -> tuple[Path, dict[str, str]]:
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "setup.sh", repo / "scripts" / "setup.sh")
    shutil.copy(ROOT / "pyproject.toml", repo / "pyproject.toml")
    venv_bin = repo / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    _executable(venv_bin / "python", f"#!{sys.executable}\n{_EDITABLE_WARNING}")
    if stamp_matches:
        digest = hashlib.sha256((repo / "pyproject.toml").read_bytes()).hexdigest()
        (repo / ".venv" / ".dgli-setup-stamp").write_text(digest + "\n")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    # an ldconfig cache far larger than a pipe's buffer, libusb on its first line: a grep
    # that stops there leaves ldconfig writing into a closed pipe
    lines = "\tlibusb-1.0.so.0 (libc6,x86-64) => /lib/x86_64-linux-gnu/libusb-1.0.so.0\n"
    lines += "".join(f"\tlibfiller{i}.so (libc6,x86-64) => /lib/libfiller{i}.so\n"
                     for i in range(20000))
    (tmp_path / "cache.txt").write_text(lines)
    _executable(bin_dir / "ldconfig", f"#!/bin/sh\nexec cat {tmp_path / 'cache.txt'}\n")
    for tool in ("apt-get", "sudo"):
        _executable(bin_dir / tool, f"#!/bin/sh\necho {tool} \"$@\" >> {tmp_path / 'apt.log'}\n")
    _executable(bin_dir / "chromium", "#!/bin/sh\nexit 0\n")
    for tool in ("dirname", "id", "cat", "sha256sum", "cut", "grep", "sh", "rm"):
        (bin_dir / tool).symlink_to(shutil.which(tool))
    # nothing else on the PATH: what this machine has installed does not count
    env = {**os.environ, "PATH": str(bin_dir)}
    env.pop("PYTHONWARNINGS", None)
    return repo, env


def test_an_installed_library_is_not_installed_again(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=True)
    for _ in range(5):  # SIGPIPE needed grep to win a race: it used to, nearly always
        run = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                             capture_output=True, text=True, timeout=60)
        assert run.returncode == 0, run.stderr
        assert not (tmp_path / "apt.log").exists(), (tmp_path / "apt.log").read_text()
        assert run.stderr == ""


def test_a_missing_library_is_installed_quietly_for_the_tests_only(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=True)
    (tmp_path / "cache.txt").write_text("\tlibc.so.6 (libc6,x86-64) => /lib/libc.so.6\n")
    run = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert not (tmp_path / "apt.log").exists()  # classifying needs no Open3D, no libusb
    (repo / ".venv" / ".dgli-test-stamp").write_text(
        (repo / ".venv" / ".dgli-setup-stamp").read_text())
    run = subprocess.run([BASH, "scripts/setup.sh", "--test"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    log = (tmp_path / "apt.log").read_text()
    assert "install" in log and "libusb-1.0-0" in log
    assert log.count("update") == 1


def test_a_missing_browser_is_installed_for_the_tests(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=True)
    (tmp_path / "bin" / "chromium").unlink()
    run = subprocess.run([BASH, "scripts/setup.sh", "--test"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    log = (tmp_path / "apt.log").read_text()
    assert "install" in log and "chromium" in log


def test_the_editable_install_warning_is_silenced_but_errors_show(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=False)
    run = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert "Editable installation" not in run.stderr
    assert "ERROR: a real pip error" in run.stderr


def test_the_photoreal_environment_is_installed_without_the_warning_too(tmp_path):
    """The first set-up also makes .venv-photoreal/: its editable install printed the
    dozen lines of "Editable installation" the main one no longer did."""
    repo, env = _scratch(tmp_path, stamp_matches=True)
    stub = tmp_path / "venv_python"
    _executable(stub, f"#!{sys.executable}\n{_EDITABLE_WARNING}")
    # a python3 of version 3.11 whose venv is the stub above
    _executable(tmp_path / "bin" / "python3", f"""#!/bin/sh
[ "$1" = "-c" ] && exit 0
if [ "$1" = "-m" ] && [ "$2" = "venv" ]; then
    mkdir -p "$3/bin" && cp {stub} "$3/bin/python"; exit 0
fi
exit 1
""")
    for tool in ("mkdir", "cp"):
        (tmp_path / "bin" / tool).symlink_to(shutil.which(tool))
    run = subprocess.run([BASH, "scripts/setup.sh", "--test"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert (repo / ".venv-photoreal" / "bin" / "python").is_file()
    assert "Editable installation" not in run.stderr
    assert "ERROR: a real pip error" in run.stderr  # the stub's error still shows


def _logging_python(tmp_path: Path, repo: Path) -> Path:
    """The virtual environment's python as a stand-in that logs each pip install."""
    log = tmp_path / "pip.log"
    _executable(repo / ".venv" / "bin" / "python", f"""#!{sys.executable}
import sys
if "install" in sys.argv:
    with open({str(log)!r}, "a") as f:
        f.write(" ".join(sys.argv[1:]) + "\\n")
""")
    return log


def _python3_311(tmp_path: Path) -> None:
    """A python3 of version 3.11 (so the photoreal environment could be made) whose
    venv makes a stand-in python."""
    _executable(tmp_path / "bin" / "python3", """#!/bin/sh
[ "$1" = "-c" ] && exit 0
if [ "$1" = "-m" ] && [ "$2" = "venv" ]; then
    mkdir -p "$3/bin" && printf '#!/bin/sh\\nexit 0\\n' > "$3/bin/python" \\
        && chmod +x "$3/bin/python"; exit 0
fi
exit 1
""")
    for tool in ("mkdir", "chmod"):
        (tmp_path / "bin" / tool).symlink_to(shutil.which(tool))


def test_the_first_command_sets_up_what_classifying_needs_and_nothing_more(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=False)
    (tmp_path / "bin" / "chromium").unlink()
    _python3_311(tmp_path)
    log = _logging_python(tmp_path, repo)
    run = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert not (tmp_path / "apt.log").exists()  # no browser, no libusb
    assert not (repo / ".venv-photoreal").exists()  # no Blender
    installs = log.read_text().splitlines()
    assert installs[-1].endswith("-e .")  # the package alone, no extras
    again = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                           capture_output=True, text=True, timeout=60)
    assert again.returncode == 0 and log.read_text().splitlines() == installs


def test_the_test_set_up_adds_the_extras_the_browser_and_blender(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=True)  # the first command has run
    (tmp_path / "bin" / "chromium").unlink()
    _python3_311(tmp_path)
    log = _logging_python(tmp_path, repo)
    run = subprocess.run([BASH, "scripts/setup.sh", "--test"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert "chromium" in (tmp_path / "apt.log").read_text()
    assert (repo / ".venv-photoreal" / "bin" / "python").is_file()
    last = log.read_text().splitlines()[-1]
    assert "-e .[" in last and last.endswith("]")
    extras = set(last.rsplit("-e .[", 1)[1].rstrip("]").split(","))
    assert {"test", "sim", "recordings", "dask", "realsense", "docs", "viewer"} <= extras
    first = log.read_text()
    plain = subprocess.run([BASH, "scripts/setup.sh"], cwd=repo, env=env,
                           capture_output=True, text=True, timeout=60)
    assert plain.returncode == 0 and log.read_text() == first  # nothing more to do


def test_an_unknown_option_is_a_usage_error(tmp_path):
    repo, env = _scratch(tmp_path, stamp_matches=True)
    run = subprocess.run([BASH, "scripts/setup.sh", "--tests"], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and run.stderr == "usage: scripts/setup.sh [--test]\n"


def test_ci_runs_exactly_the_readmes_test_command():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("```bash\n", 1)[1].split("```", 1)[0].strip().splitlines()
    assert len(block) == 2 and block[0].startswith("bash scripts/setup.sh && ")
    assert "dgli-classify sample_images/" in block[0]
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1] == block[1] == "bash scripts/setup.sh --test && .venv/bin/python -m pytest"


def test_classifying_needs_no_open3d(tmp_path):
    """Open3D (0.9 GB with what it brings) is the sim extra: the package's own
    dependencies, which the first command installs, are what classifying needs."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert not any(d.startswith("open3d") for d in project["dependencies"])
    assert any(d.startswith("open3d") for d in project["optional-dependencies"]["sim"])
    code = (
        "import sys\n"
        "class NoOpen3D:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] == 'open3d':\n"
        "            raise ImportError('no open3d')\n"
        "sys.meta_path.insert(0, NoOpen3D())\n"
        "from dgli_vision.cli import main\n"
        "main(['classify', 'sample_images/05_000_color.png', "
        "'sample_images/05_000_depth.png', '--json'])\n"
    )
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert '"class": "05"' in run.stdout
    code = code.replace("main(['classify', 'sample_images/05_000_color.png', "
                        "'sample_images/05_000_depth.png', '--json'])",
                        f"main(['render', {str(tmp_path / 'out')!r}, '--per-class', '1'])")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert "the 'sim' extra: pip install 'dgli_vision[sim]'" in run.stderr
    assert "Traceback" not in run.stderr
