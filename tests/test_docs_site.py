"""The documentation site (docs/conf.py, Sphinx with numpydoc and the PyData theme):
its configuration loads, every page of its tables of contents exists and every page of
docs/ is in one, and it builds with warnings as errors (links and anchors between the
pages, the API reference's docstrings), where the `docs` extra is installed."""

from __future__ import annotations

import os
import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _toctree_entries() -> list[str]:
    """The pages the toctrees of index.rst name."""
    text = (DOCS / "index.rst").read_text(encoding="utf-8")
    entries = []
    for block in re.findall(r"\.\. toctree::\n((?:   .*\n|\n)+)", text):
        entries += [line.strip() for line in block.splitlines()
                    if line.strip() and not line.strip().startswith(":")]
    return entries


def test_the_configuration_loads_and_names_the_docs_extras_packages():
    conf = runpy.run_path(str(DOCS / "conf.py"))
    assert conf["html_theme"] == "pydata_sphinx_theme"
    assert {"sphinx.ext.autodoc", "numpydoc", "myst_parser"} <= set(conf["extensions"])
    import tomllib

    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]["docs"]
    names = {re.split(r"[<>=]", d)[0] for d in extra}
    assert names == {"sphinx", "numpydoc", "pydata-sphinx-theme", "myst-parser"}


def test_every_page_in_the_tables_of_contents_exists_and_every_page_is_in_one():
    entries = _toctree_entries()
    assert "api" in entries and len(entries) == len(set(entries))
    missing = [e for e in entries
               if not any((DOCS / f"{e}{x}").is_file() for x in (".md", ".rst"))]
    assert missing == []
    pages = {p.stem for p in DOCS.glob("*.md")} | {p.stem for p in DOCS.glob("*.rst")}
    assert pages - {"index"} == set(entries)


def test_the_site_builds_with_warnings_as_errors(tmp_path):
    for module in ("sphinx", "numpydoc", "pydata_sphinx_theme", "myst_parser"):
        try:
            __import__(module)
        except ImportError:
            if os.environ.get("CI") == "true":
                pytest.fail(f"CI=true and no {module}: scripts/setup.sh --test installs "
                            "the docs extra")
            pytest.skip(f"the docs extra is not installed (no {module})")
    run = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-E", "-b", "html",
         str(DOCS), str(tmp_path / "site")],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
        env={**os.environ, "PYTHONWARNINGS": ""},
    )
    assert run.returncode == 0, run.stderr[-3000:]
    html = (tmp_path / "site" / "api.html").read_text(encoding="utf-8")
    for name in ("classify_pair", "plan", "verify", "classifier.classify.Prediction",
                 "dgli.gli", "dgli.dgli", "dgli.cloth_coordinates",
                 "distance.spearman_distance", "core.extrinsics.Extrinsics",
                 "planning.verify.FoldCheck"):
        assert f'id="dgli_vision.{name}"' in html, name  # documented from its docstring
    assert (tmp_path / "site" / "planning.html").is_file()
