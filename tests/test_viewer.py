"""The live viewer (issue 51): ``dgli watch --bag REC --rerun out.rrd`` and ``dgli track
--rerun`` write Rerun recordings, read back here with Rerun's own API (``RrdReader``):
the entities logged, the confidence of each frame as the JSON lines give it, the plan's
grasp point as ``dgli_vision.plan`` gives it."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from guards import require_extra

from dgli_vision.cli import main

require_extra("rerun", "viewer")


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """Sequence I (flat, corner A over, then corner C), 4 frames."""
    out = tmp_path_factory.mktemp("viewer") / "I"
    r = CliRunner().invoke(
        main, ["render", str(out), "--sequence", "I", "--frames", "4", "--seed", "3"]
    )
    assert r.exit_code == 0, r.output
    return out


def _columns(path: Path) -> dict[str, dict[str, dict[int, list]]]:
    """entity -> component column -> frame -> values, from the file's chunks."""
    from rerun.chunk import RrdReader

    out: dict[str, dict[str, dict[int, list]]] = defaultdict(lambda: defaultdict(dict))
    for chunk in RrdReader(path).store().stream().to_chunks():
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "frame" not in names:
            continue
        frames = batch.column("frame").to_pylist()
        for name in names:
            if ":" in name:
                for f, v in zip(frames, batch.column(name).to_pylist()):
                    out[chunk.entity_path][name][f] = v
    return out


@pytest.fixture(scope="module")
def watched(recording, tmp_path_factory) -> tuple[Path, list[dict]]:
    rrd = tmp_path_factory.mktemp("rrd") / "out.rrd"
    r = CliRunner().invoke(
        main,
        ["watch", "--bag", str(recording), "--fast", "--jsonl", "--rerun", str(rrd),
         "--goal", "08"],
    )
    assert r.exit_code == 0, r.output
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    return rrd, [line for line in lines if "frame" in line]


def test_watch_writes_the_frames_entities(watched) -> None:
    rrd, _ = watched
    from rerun.chunk import RrdReader

    paths = set(RrdReader(rrd).store().schema().entity_paths())
    for entity in (
        "/world/camera/image", "/world/camera/image/found", "/world/camera/image/missing",
        "/world/camera/stickers", "/world/camera/segments", "/world/camera/table",
        "/world/camera/corners", "/world/camera/plan/grasp", "/world/camera/plan/place",
        "/state/confidence", "/state/class", "/state/smoothed", "/state/log",
    ):
        assert entity in paths, (entity, sorted(paths))


def test_the_state_and_confidence_over_time_are_the_json_lines(watched) -> None:
    rrd, lines = watched
    cols = _columns(rrd)
    conf = cols["/state/confidence"]["Scalars:scalars"]
    assert sorted(conf) == [line["frame"] for line in lines] == [0, 1, 2, 3]
    for line in lines:
        assert conf[line["frame"]][0] == pytest.approx(line["confidence"], abs=1e-4)
        assert cols["/state/class"]["Scalars:scalars"][line["frame"]][0] == int(
            line["state"]["class"]
        )
        text = cols["/state/log"]["TextLog:text"][line["frame"]][0]
        assert text.startswith(f"frame {line['frame']}: {line['state']['class']} ")


def test_the_stickers_found_are_labelled_by_id_in_2d_and_3d(watched) -> None:
    rrd, _ = watched
    cols = _columns(rrd)
    found = cols["/world/camera/image/found"]
    stickers = cols["/world/camera/stickers"]
    for f in range(4):
        ids = found["Points2D:labels"][f]
        assert len(ids) == len(found["Points2D:positions"][f]) >= 8
        assert all(0 <= int(i) < 16 for i in ids)
        assert set(stickers["Points3D:labels"][f]) <= set(ids)
        z = np.array(stickers["Points3D:positions"][f])[:, 2]
        assert ((z > 0.2) & (z < 3.0)).all()  # metres in front of the camera


def test_the_grasp_logged_is_the_plan_s(watched, recording) -> None:
    import dgli_vision

    rrd, _ = watched
    grasp = _columns(rrd)["/world/camera/plan/grasp"]["Points3D:positions"]
    plan = dgli_vision.plan(
        recording / "I_000_color.png", recording / "I_000_depth.png", goal="08",
        intrinsics=recording / "intrinsics.json",
    )
    assert np.allclose(grasp[0][0], plan.steps[0].grasp_point, atol=1e-6)


def test_an_existing_rrd_is_kept_without_overwrite(watched, recording) -> None:
    from cli_runs import one_error_line

    rrd, _ = watched
    before = rrd.stat().st_mtime_ns
    r = CliRunner().invoke(main, ["watch", "--bag", str(recording), "--fast",
                                  "--rerun", str(rrd)])
    assert r.exit_code == 2
    assert "exists" in one_error_line(r) and str(rrd) in one_error_line(r)
    assert rrd.stat().st_mtime_ns == before


def test_track_logs_the_timeline(recording, tmp_path) -> None:
    rrd = tmp_path / "track.rrd"
    r = CliRunner().invoke(main, ["track", str(recording), "-j", "1", "--json",
                                  "--rerun", str(rrd)])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    cols = _columns(rrd)
    smoothed = cols["/state/smoothed"]["Scalars:scalars"]
    assert [smoothed[f["index"]][0] for f in data["frames"]] == [
        int(f["smoothed_class"]) for f in data["frames"]
    ]
    assert sorted(cols["/world/camera/image"]["EncodedImage:blob"]) == [0, 1, 2, 3]
    assert sorted(cols["/world/camera/corners"]["Points3D:positions"]) == [0, 1, 2, 3]
    assert all(len(v) >= 8 for v in cols["/world/camera/image/found"]["Points2D:labels"].values())
