"""The house's conventions (docs/architecture.md): one error hierarchy, one JSON method,
results that mirror their JSON, tables instead of if-chains."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from dgli_vision.core import errors


def test_every_error_class_lives_in_core_errors() -> None:
    import dgli_vision.core.run_lock as run_lock

    for name in ("RunBusyError", "ResumeMismatchError", "ReferenceSetError", "InvalidValueError"):
        assert issubclass(getattr(errors, name), errors.DgliError)
        assert name in errors.__all__
    assert "RunBusyError" not in run_lock.__all__
    assert run_lock.RunBusyError is errors.RunBusyError  # used there, defined here


def test_the_old_reference_error_name_still_catches_with_a_warning() -> None:
    with pytest.warns(DeprecationWarning, match="ReferenceSetError"):
        old = errors.ReferenceError_
    assert old is errors.ReferenceSetError
    assert errors.ReferenceSetError.exit_code == 2


@pytest.mark.parametrize(
    "call",
    [
        lambda: __import__("dgli_vision.planning.plan", fromlist=["x"]).parse_state("99"),
        lambda: __import__("dgli_vision.planning.verify", fromlist=["x"]).parse_legs("AC=1"),
        lambda: __import__("dgli_vision.sim.cloth.sequences", fromlist=["x"]).sequence_progress(
            "nope", 1
        ),
        lambda: __import__("dgli_vision.core.layout", fromlist=["x"]).parse_size("big"),
        lambda: __import__("dgli_vision.core.fold_graph", fromlist=["x"]).folds_of("99", None),
        lambda: __import__("dgli_vision.core.parallel", fromlist=["x"]).ordered_map(
            abs, [1], jobs=0
        ).__next__(),
    ],
)
def test_a_bad_value_from_a_user_is_a_dgli_error_and_still_a_value_error(call) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(errors.InvalidValueError) as info:
            call()
    assert isinstance(info.value, ValueError)
    assert info.value.exit_code == 2


def test_a_predictions_corners_are_keyed_by_name_as_in_the_json() -> None:
    """Issue 41 item 8: ``p.corners["A"]`` works, and holds what the JSON holds."""
    import pickle
    from pathlib import Path

    from click.testing import CliRunner

    import dgli_vision
    from dgli_vision.cli import main

    samples = Path(__file__).resolve().parents[1] / "sample_images"
    color, depth = samples / "05_000_color.png", samples / "05_000_depth.png"
    p = dgli_vision.classify_pair(color, depth)
    res = CliRunner().invoke(main, ["classify", str(color), str(depth), "--json"])
    shown = json.loads(res.stdout)
    assert list(p.corners) == list(shown["corners"]) == ["A", "B", "C", "D"]
    for name, c in p.corners.items():
        assert c.to_json() == shown["corners"][name]
    assert p.corners["A"].state == shown["corners"]["A"]["state"]
    assert pickle.loads(pickle.dumps(p)).corners == p.corners  # results cross processes
    with pytest.raises(KeyError):
        p.corners["E"]


def test_a_recording_format_is_one_row_of_the_reader_table(monkeypatch, tmp_path) -> None:
    """docs/architecture.md's recipe: a new format is a row of RECORDING_READERS."""
    from dgli_vision.sources import recording
    from dgli_vision.sources.recording import RecordingReader, open_recording

    text = tmp_path / "notes.txt"
    text.write_text("not frames")
    with pytest.raises(errors.UnreadableInputError, match="expected a folder of PNG pairs, "
                       r"a ROS 1 .bag, a ROS 2 bag \(.db3, .mcap or its folder\) or a "
                       "RealSense .db3/.bag"):
        open_recording(text)
    samples = Path(__file__).resolve().parents[1] / "sample_images"

    def read_list(path, options):  # a text file naming a folder of pairs
        return recording.read_recording(path.read_text().strip())

    row = RecordingReader("pair list", "a .pairs file", lambda p: p.suffix == ".pairs",
                          read_list)
    monkeypatch.setattr(recording, "RECORDING_READERS", (row, *recording.RECORDING_READERS))
    listed = tmp_path / "sample.pairs"
    listed.write_text(str(samples))
    rec = open_recording(listed)
    assert rec.count == len(list(samples.glob("*_color.png")))
    with pytest.raises(errors.UnreadableInputError, match=r"or a \.pairs file$"):
        open_recording(text)


def test_a_capture_condition_is_a_name_a_drawer_and_a_row_of_effects(monkeypatch) -> None:
    """docs/architecture.md's recipe: a condition's image effect is a row of
    CONDITION_EFFECTS, which the renderer walks (here a made-up one, 'negative')."""
    import numpy as np

    from dgli_vision.core.camera import Intrinsics
    from dgli_vision.sim import conditions, render
    from dgli_vision.sim.dataset import render_sample

    def negative(stage):
        color, depth = stage.value
        return 255 - color, depth

    row = render.ConditionEffect("negative", "camera", lambda c: "negative" in c.names, negative)
    monkeypatch.setattr(render, "CONDITION_EFFECTS", (*render.CONDITION_EFFECTS, row))
    monkeypatch.setitem(conditions._DRAWERS, "negative", lambda c, rng: c)
    monkeypatch.setattr(conditions, "CONDITION_NAMES", (*conditions.CONDITION_NAMES, "negative"))
    small = Intrinsics(160, 90, 75.6, 75.6, 79.5, 44.5)
    plain = render_sample("02", 0, 3, intrinsics=small, conditions=("cast",)).result
    neg = render_sample("02", 0, 3, intrinsics=small, conditions=("cast", "negative")).result
    assert "negative" in neg.info["conditions"]
    assert np.array_equal(neg.color, 255 - plain.color)
    assert np.array_equal(neg.depth_mm, plain.depth_mm)


def test_label_takes_the_shared_options(tmp_path) -> None:
    """cli/label.py's --size, -j and --format are cli/options.py's and the library's."""
    from click.testing import CliRunner

    from dgli_vision.cli import main
    from dgli_vision.cli.label import label_cmd
    from dgli_vision.labelling.episodes import FORMATS

    res = CliRunner().invoke(main, ["label", str(tmp_path / "x.npz"), "--size", "5000"])
    assert res.exit_code == 2 and "out of range" in res.stderr and "Traceback" not in res.output
    params = {p.name: p for p in label_cmd.params}
    assert tuple(params["fmt"].type.choices) == FORMATS
    assert params["jobs"].help == "Worker processes (the same results as one)."
