"""Every HTML page the tool writes (evaluate, track, robustness, compare, label), opened
in headless Chromium: it loads with no missing picture, no failed load and no console error, its
summary is on the first screen (1200 x 900), and its charts are Matplotlib's with axes.

Skips where no browser is installed (``scripts/setup.sh --test`` installs Debian's ``chromium``),
except under CI=true, where that is a failure. ``DGLI_SCREENSHOTS=docs/screenshots``
writes each page's first screen there, 600 pixels wide (the pictures of docs/reports.md).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from browser import Browser, file_url, find_browser
from click.testing import CliRunner

from dgli_vision.analysis import robustness
from dgli_vision.cli import main

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"

#: Evaluated in each page once it has loaded.
_PROBE = """(() => {
  const broken = [...document.images]
      .filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.getAttribute('src'));
  const first = document.querySelector('h1').nextElementSibling;
  const parts = [first];
  if (first.tagName === 'UL' && first.nextElementSibling.tagName === 'TABLE') {
    parts.push(first.nextElementSibling);  // the outcomes table under the summary
  }
  return {broken, images: document.images.length, height: innerHeight,
          summary: Math.max(...parts.map(p => p.getBoundingClientRect().bottom)),
          text: document.body.innerText.slice(0, 400)};
})()"""


def _run(args: list[str]) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code in (0, 1), result.output  # 1: some answers wrong, by design


def _fake_outcome(args):
    """Robustness without rendering: class 01 right, 03 wrong, the rest "cannot tell",
    each not right with a small overlay (as the real worker keeps them)."""
    condition, _, k, class_id = args
    given = {"01": "01", "03": "04"}.get(class_id)
    out = (f"{class_id}_{k:03d}", f"{class_id}/x", given, "x", (condition,),
           (given or "01", 0.5))
    if not robustness._OVERLAYS:
        return out
    extra = None if given == class_id else {
        "reason": None if given else f"too few stickers in {class_id}",
        "overlay": np.full((60, 80, 3), 40 * int(class_id) % 255, np.uint8),
    }
    return (*out, extra)


def _compare_page(out: Path) -> None:
    from dgli_vision.analysis.compare import REPRESENTATIONS, CompareTable, paper_columns
    from dgli_vision.analysis.compare_report import compare_report
    from dgli_vision.core.io import write_outputs

    names = tuple(REPRESENTATIONS)
    table = CompareTable(("database", "I"), {n: [1.5, 0.5] for n in names}, paper_columns(names))
    classes = ["01", "01", "02", "02", "03", "03"]
    rng = np.random.default_rng(7)
    matrices = {}
    for n in names:
        m = rng.random((6, 6))
        matrices[n] = (m + m.T) * (1 - np.eye(6))
    files = compare_report(table, matrices, classes, command="dgli compare db --report r")
    write_outputs({out / k: v for k, v in files.items()}, overwrite=False, command="dgli compare")


@pytest.fixture(scope="module")
def browser():
    path = find_browser()
    if path is None:
        if os.environ.get("CI") == "true":
            pytest.fail("CI=true and no chromium installed: scripts/setup.sh --test installs it")
        pytest.skip("no headless browser installed (scripts/setup.sh --test installs Debian's "
                    "chromium); the HTML pages were not opened")
    b = Browser(path)
    yield b
    b.close()


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> dict[str, Path]:
    """One small report of each kind."""
    root = tmp_path_factory.mktemp("pages")
    # evaluate: three pairs, one labelled wrong (a "wrong" gallery), one mirrored
    folder = root / "set"
    folder.mkdir()
    shutil.copy(SAMPLES / "intrinsics.json", folder)
    for name in ("01_000", "02_000", "09_000"):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", folder / f"{name}_{kind}.png")
    for kind in ("color", "depth"):  # a mirror image: "cannot tell"
        img = cv2.imread(str(SAMPLES / f"02_000_{kind}.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(folder / f"m02_000_{kind}.png"), cv2.flip(img, 1))
    (folder / "labels.csv").write_text(
        "color,depth,label,variant\n01_000_color.png,01_000_depth.png,01,\n"
        "02_000_color.png,02_000_depth.png,03,C\n09_000_color.png,09_000_depth.png,09,\n"
        "m02_000_color.png,m02_000_depth.png,02,C\n"
    )
    out = {"evaluate": root / "evaluate"}
    _run(["evaluate", str(folder), "-j", "1", "--report", str(out["evaluate"])])
    # track: four frames of a folder, by name
    frames = root / "frames"
    frames.mkdir()
    shutil.copy(SAMPLES / "intrinsics.json", frames)
    for t, name in enumerate(("01_000", "01_000", "02_000", "02_000")):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", frames / f"f{t:03d}_{kind}.png")
    out["track"] = root / "track"
    _run(["track", str(frames), "-j", "1", "--report", str(out["track"])])
    # robustness: one condition, its outcomes made up (no rendering)
    out["robustness"] = root / "robustness"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(robustness, "_one", _fake_outcome)
        _run(["robustness", "--per-class", "1", "--conditions", "sheen", "-j", "1",
              "--report", str(out["robustness"])])
    # compare: its report writer on made-up distances (simulating a database takes 5 s)
    out["compare"] = root / "compare"
    _compare_page(out["compare"])
    # label: an episode of four frames (flat, a corner folded, two corners folded)
    from dgli_vision.core.layout import default_layout
    from dgli_vision.sim.cloth.mesh import flat_mesh
    from dgli_vision.sim.cloth.states import sample_state

    rng = np.random.default_rng(5)
    meshes = [flat_mesh(default_layout()), sample_state("02", "A", rng).mesh,
              sample_state("02", "A", rng).mesh, sample_state("04", "AB", rng).mesh]
    episode = root / "episode.npz"
    np.savez(episode, positions=np.stack([m.xyz for m in meshes]) * 1000,
             grid=np.array(meshes[0].shape))
    out["label"] = root / "label"
    _run(["label", str(episode), "--units", "mm", "--no-geometry", "-o", str(out["label"])])
    return {kind: folder / "report.html" for kind, folder in out.items()}


@pytest.mark.parametrize("kind", ["evaluate", "track", "robustness", "compare", "label"])
def test_the_page_loads_whole_with_its_summary_on_the_first_screen(browser, pages, kind):
    check = browser.check(file_url(pages[kind]), _PROBE)
    assert check.errors == []  # no failed load, no console error
    probe = check.result
    assert probe["broken"] == [] and probe["images"] > 0
    assert probe["summary"] <= probe["height"], probe["text"]
    shot = cv2.imdecode(np.frombuffer(check.screenshot, np.uint8), cv2.IMREAD_COLOR)
    assert shot.shape[:2] == (900, 1200) and shot.std() > 10  # a page, not a blank
    target = os.environ.get("DGLI_SCREENSHOTS")
    if target:
        Path(target).mkdir(parents=True, exist_ok=True)
        small = cv2.resize(shot, (600, 450), interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(Path(target) / f"{kind}.png"), small,
                    [cv2.IMWRITE_PNG_COMPRESSION, 9])


def test_a_missing_picture_is_found(browser, pages, tmp_path):
    """The check itself: a page whose chart is gone fails it."""
    shutil.copytree(pages["evaluate"].parent, tmp_path / "report")
    (tmp_path / "report" / "confusion.svg").unlink()
    page = tmp_path / "report" / "report.html"
    check = browser.check(file_url(page), _PROBE)
    assert check.result["broken"] == ["confusion.svg"]
    assert any("confusion.svg" in e for e in check.errors)


@pytest.mark.parametrize("kind", ["evaluate", "track", "robustness", "compare", "label"])
def test_the_charts_have_axes_and_ticks(pages, kind):
    charts = sorted(pages[kind].parent.glob("*.svg"))
    assert charts
    for svg in charts:
        text = svg.read_text()
        assert "Matplotlib" in text and 'id="axes_1"' in text and 'id="xtick_1"' in text
        assert svg.with_suffix(".png").is_file()  # the same chart as a picture, linked
        assert f'href="{svg.with_suffix(".png").name}"' in pages[kind].read_text()


def test_a_count_of_one_is_in_the_singular(pages):
    assert "over 1 condition (seed" in pages["robustness"].read_text()
    assert "1 of 1 episode labelled, 4 frames" in pages["label"].read_text()
