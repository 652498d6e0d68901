"""One parameters tree: every perception stage's parameters, from code and --params."""

from __future__ import annotations

import json
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from cli_runs import one_error_line
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.errors import InvalidInputError
from dgli_vision.perception import params as P

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@pytest.fixture(scope="module")
def refs():  # type: ignore[no-untyped-def]
    from dgli_vision.classifier.references import load_references

    return load_references(None)


@pytest.fixture(scope="module")
def frame():  # type: ignore[no-untyped-def]
    from dgli_vision.sources.frames import read_frame

    return read_frame(SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png")


def test_the_tree_holds_every_stage_and_reads_back_what_it_writes(tmp_path: Path) -> None:
    tree = P.PipelineParams()
    stages = {f.name: type(getattr(tree, f.name)).__name__ for f in fields(tree)}
    assert set(stages.values()) == {
        "NapkinParams", "RegionParams", "DetectorParams", "EvidenceParams", "PartialParams",
        "FlapParams", "ShadeParams", "FootprintParams", "TipParams",
    }
    # the stage modules' classes are the tree's (one definition each)
    from dgli_vision.perception import detect, evidence, footprint, napkin, tips

    assert detect.DetectorParams is P.DetectorParams and napkin.NapkinParams is P.NapkinParams
    assert evidence.EvidenceParams is P.EvidenceParams and tips.TipParams is P.TipParams
    assert footprint.FootprintParams is P.FootprintParams
    changed = tree.with_overrides({"detector": {"min_saturation": 100}, "tips": {"leg_mm": 50}})
    path = tmp_path / "p.json"
    path.write_text(json.dumps(changed.to_json()))
    assert P.read_params(path) == changed != tree
    assert changed.detector.min_saturation == 100 and changed.tips.leg_mm == 50.0
    assert changed.napkin == tree.napkin


@pytest.mark.parametrize(
    ("overrides", "said"),
    [
        ({"detectr": {}}, "unknown stage 'detectr' (known: napkin, regions, detector"),
        ({"detector": {"min_sat": 1}}, "detector: unknown field 'min_sat' (known: "),
        ({"napkin": {"stride": 8.5}}, "napkin.stride: expected int like 8, got 8.5"),
        ({"napkin": {"stride": "8"}}, "napkin.stride: expected int like 8, got '8'"),
        ([1, 2], "expected a JSON object of stages, got list"),
    ],
)
def test_a_wrong_key_or_value_is_one_line_naming_the_file_and_the_key(
    tmp_path: Path, overrides: object, said: str
) -> None:
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(overrides))
    with pytest.raises(InvalidInputError) as err:
        P.read_params(path)
    line = str(err.value)
    assert line.startswith(f"{path}: ") and said in line and "\n" not in line
    res = CliRunner().invoke(main, [
        "classify", str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png"),
        "--params", str(path),
    ])
    assert said in one_error_line(res)


def test_each_stage_reads_its_own_parameters(frame, refs) -> None:  # type: ignore[no-untyped-def]
    """Parameters of stage 1 (the napkin's sampling), 2 (the detector's size band) and 5
    (the footprint's largest share of the napkin) reach their stage from
    ``classify_frame``; a DetectorParams alone still works as before."""
    from dgli_vision.classifier.pipeline import classify_frame

    base = classify_frame(frame, refs)
    assert base.prediction is not None and base.observation.footprint is not None
    assert base.observation.objects_stride == 8
    seen = int(base.detections.found.sum())
    tree = P.PipelineParams()
    coarse = classify_frame(frame, refs, params=replace(tree, napkin=P.NapkinParams(stride=16)))
    assert coarse.observation.objects_stride == 16
    strict = P.DetectorParams(min_area_ratio=1.9)
    fewer = classify_frame(frame, refs, params=replace(tree, detector=strict))
    assert fewer.detections.found.sum() < seen
    assert np.array_equal(classify_frame(frame, refs, params=strict).detections.found,
                          fewer.detections.found)
    tiny = replace(tree, footprint=P.FootprintParams(max_fraction=0.01))
    assert classify_frame(frame, refs, params=tiny).observation.footprint is None


def test_classify_pair_and_the_command_line_take_a_file(
    tmp_path: Path, frame, refs  # type: ignore[no-untyped-def]
) -> None:
    import dgli_vision

    path = tmp_path / "strict.json"
    path.write_text(json.dumps({"detector": {"min_area_ratio": 1.9}}))
    p = dgli_vision.classify_pair(frame.color, frame.depth_mm, frame.intrinsics, params=path)
    assert len(p.stickers.found) < 14  # (of the 14 seen with the defaults)
    res = CliRunner().invoke(main, [
        "classify", str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png"),
        "--params", str(path), "--json",
    ])
    assert json.loads(res.output)["stickers"]["found"] == len(p.stickers.found)


def test_where_colours_are_read_follows_the_layout() -> None:
    """The disc's band and the dot's centre are the layout's (its dot and disc
    diameters), for the detector and the colour calibration alike."""
    from dgli_vision.core.layout import default_layout

    layout = default_layout()
    bands = P.disc_bands(layout)
    assert bands.dot == pytest.approx(0.28) and bands.centre == pytest.approx(0.2)
    assert bands.band == pytest.approx((0.6, 0.95))
    wider = P.disc_bands(replace(layout, dot_diameter_mm=15.0))
    assert wider.dot == pytest.approx(0.35) and wider.band[0] == pytest.approx(2 / 3)
