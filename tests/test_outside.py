"""States outside the twelve (issue 49): the nearest state's folds fitted to the stickers
(classifier/state_fit.py), crumpled cloth and the other checks that need no verdict
(classifier/known_states.py), the generator of such states (sim/cloth/outside.py), and
the label ``none`` through render, evaluate, track, verify and label."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner
from render_cache import rendered

from dgli_vision.analysis.evaluate import PairOutcome, summarise
from dgli_vision.analysis.track import track_outcomes
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.classifier.state_fit import fit_state, moving_flaps
from dgli_vision.cli import main
from dgli_vision.core.classes import CLASS_IDS, LIFTED_MM, OUTSIDE, VARIANTS
from dgli_vision.core.layout import default_layout
from dgli_vision.core.why import WhyKind
from dgli_vision.sim.cloth.outside import OUTSIDE_KINDS, sample_outside
from dgli_vision.sim.cloth.states import sample_state
from dgli_vision.sources.labelled import LabelledPair, find_labelled_pairs

REFS = load_references()
LAYOUT = default_layout()
SEED = 4949


def _seen_from_above(state):
    """The observation a camera straight above makes of a simulated state: every
    sticker it sees at its true place (z up, metres), heights over the table."""
    heights = state.sticker_points[:, 2] * 1e3
    visible = state.visible
    return SimpleNamespace(
        points_m=np.where(visible[:, None], state.sticker_points, np.nan),
        visible=visible,
        heights_mm=np.where(visible, heights, np.nan),
        up=np.array([0.0, 0.0, 1.0]),
        lifted=np.where(visible, (heights > LIFTED_MM).astype(float), np.nan),
    )


@pytest.mark.parametrize("class_id", CLASS_IDS)
def test_every_state_of_the_twelve_fits_its_own_folds(class_id):
    """The twelve states' stickers, at their true places, are what their folds predict:
    full confidence (factor 1) for every variant, with wrinkles and any placement."""
    for k, variant in enumerate(VARIANTS[class_id]):
        state = sample_state(class_id, variant, np.random.default_rng([SEED, k]))
        fit = fit_state(_seen_from_above(state), class_id, variant, LAYOUT)
        assert fit.factor == 1.0, (class_id, variant, fit.describe())
        assert np.nanmax(fit.residual_mm, initial=0.0) < 5.0


def test_a_state_in_another_states_clothes_does_not_fit():
    """A strip folded over (09) is not a corner folded over (02), nor 09 on another side."""
    state = sample_state("09", "AB", np.random.default_rng(SEED))
    obs = _seen_from_above(state)
    assert fit_state(obs, "09", "AB", LAYOUT).fits
    for other in (("09", "CD"), ("02", "A"), ("11", "AB")):
        fit = fit_state(obs, *other, LAYOUT)
        assert not fit.fits, other
        assert fit.describe()  # says what it leaves unexplained


@pytest.mark.parametrize("kind", [k for k in OUTSIDE_KINDS if k != "crumpled"])
def test_no_state_of_the_twelve_explains_a_fold_none_of_them_has(kind):
    """Each kind outside the twelve, at its true sticker places, against every state
    of the twelve: none explains it fully (the nearest one included, whatever it is)."""
    for k in range(2):
        state = sample_outside(kind, np.random.default_rng([SEED, k]))
        obs = _seen_from_above(state)
        if obs.visible.sum() < 6:  # folded in quarters: too few stickers for any verdict
            continue
        for class_id in CLASS_IDS:
            for variant in VARIANTS[class_id]:
                fit = fit_state(obs, class_id, variant, LAYOUT)
                assert fit.factor < 1.0, (kind, k, class_id, variant)


def test_a_flap_in_the_air_must_be_one_the_state_can_be_folding():
    """A corner held up over a flat napkin is 01 folding towards 02; the same corner
    held up while the state is 09 (strip over on the opposite side) is not."""
    flaps = moving_flaps("01", None, LAYOUT)
    corner_a = frozenset({14, 15, 0, 1})
    assert any(corner_a == on for on, _ in flaps)
    state = sample_state("02", "A", np.random.default_rng(SEED), last_fold_deg=70)
    obs = _seen_from_above(state)
    assert fit_state(obs, "01", None, LAYOUT).fits
    assert not fit_state(obs, "09", "CD", LAYOUT).fits


@pytest.fixture(scope="module")
def outside_results(request):
    """Rendered states outside the twelve, one of each kind, classified."""
    out = {}
    for k, kind in enumerate(OUTSIDE_KINDS):
        frame = rendered(request.config, OUTSIDE, k, SEED)
        out[kind] = classify_frame(frame, REFS)
    return out


@pytest.mark.parametrize("kind", OUTSIDE_KINDS)
def test_a_rendered_state_outside_the_twelve_gets_no_class(outside_results, kind):
    """No class, and no confidence a robot would act on anywhere in the JSON."""
    result = outside_results[kind]
    assert result.prediction is None, (kind, result.best_guess)
    data = result.to_json("c.png", "d.png")
    assert data["class"] is None
    assert data["confidence"] is None or data["confidence"] < 0.25
    assert data["reason"].startswith("cannot tell: ")


def test_crumpled_cloth_is_named_crumpled(outside_results):
    result = outside_results["crumpled"]
    assert result.why == WhyKind.CRUMPLED
    assert result.reason.startswith("cannot tell: crumpled: stickers ")
    assert result.to_json("c.png", "d.png")["why"]["kind"] == "crumpled"


def test_no_state_fits_names_the_stickers_and_how_far_they_are(outside_results):
    result = outside_results["strip-and-corner"]
    assert result.why == WhyKind.NO_STATE_FITS
    assert "cannot tell: no known state fits: stickers " in result.reason
    assert " mm from where " in result.reason
    why = result.to_json("c.png", "d.png")["why"]
    assert why["kind"] == "no state fits"
    moved = why["unexplained"]["stickers_mm"]
    assert len(moved) >= 2 and all(v > 15 for v in moved.values())
    assert why["classes"]  # the nearest candidates are kept


def test_folded_in_quarters_is_too_little_cloth_for_any_state(outside_results):
    result = outside_results["quarter"]
    assert result.why == WhyKind.NO_STATE_FITS
    assert "less than any known state" in result.reason


def _outcome(label, predicted=None, why=None, error=None):
    pair = LabelledPair("c.png", "d.png", label)
    return PairOutcome(pair, predicted, reason=None if predicted else "cannot tell: x",
                       why=why, error=error)


def test_a_none_pair_is_right_only_without_a_class():
    outs = [
        _outcome(OUTSIDE, why="no state fits"),
        _outcome(OUTSIDE, why="too few stickers"),  # no class given: right
        _outcome(OUTSIDE, "09"),  # a class for a state outside the twelve: wrong
        _outcome(OUTSIDE, error="unreadable"),
        _outcome("02", "02"),
    ]
    result = summarise(outs, 1.0)
    assert result.outcome_counts == {"right": 3, "cannot_tell": 0, "wrong": 1, "unreadable": 1}
    k = result.labels.index(OUTSIDE)
    assert result.confusion[k][k] == 2
    assert result.per_class[OUTSIDE]["recall"] == pytest.approx(0.5)


def test_labels_csv_takes_none_and_refuses_a_variant_for_it(tmp_path):
    for name in ("a", "b"):
        for kind in ("color", "depth"):
            (tmp_path / f"{name}_{kind}.png").write_bytes(b"")
    (tmp_path / "labels.csv").write_text(
        "color,depth,label,variant\na_color.png,a_depth.png,None,\n"
        "b_color.png,b_depth.png,none,A\n"
    )
    pairs, problems = find_labelled_pairs(tmp_path, lenient=True)
    assert [p.label for p in pairs] == [OUTSIDE]
    assert len(problems) == 1 and "has no variant" in problems[0].message


def test_a_no_known_state_span_is_never_smoothed_into_its_neighbours():
    """Frames of 02 around two frames in none of the states: the timeline shows none
    there, and the changes into and out of it."""
    owners = [(r.class_id, r.variant) for r in REFS.references]
    d02 = np.where([o == ("02", "A") for o in owners], 0.01, 1.0)
    outs = []
    for t in range(8):
        outside = t in (3, 4)
        outs.append(PairOutcome(
            LabelledPair(f"{t}_color.png", f"{t}_depth.png", "02"),
            None if outside else "02", None if outside else "A",
            distances=tuple(d02), why="no state fits" if outside else None,
        ))
    timeline = track_outcomes(outs, REFS)
    shown = [f.smoothed_class for f in timeline.frames]
    assert shown == ["02", "02", "02", OUTSIDE, OUTSIDE, "02", "02", "02"]
    assert [t for t, _, _ in timeline.changes] == [3, 5]


@pytest.fixture(scope="module")
def outside_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("outside")
    r = CliRunner().invoke(
        main, ["render", str(out), "--per-class", "0", "--outside", "2", "--seed", "7", "-j", "1"]
    )
    assert r.exit_code == 0, r.output
    return out


def test_render_outside_writes_pairs_labelled_none(outside_folder):
    with open(outside_folder / "labels.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["label"] for r in rows] == [OUTSIDE] * 2
    truth = json.loads((outside_folder / "truth.json").read_text())
    kinds = [v["state_params"]["outside"] for v in truth["images"].values()]
    assert kinds == list(OUTSIDE_KINDS[:2])


def test_evaluate_scores_states_outside_the_twelve(outside_folder):
    r = CliRunner().invoke(main, ["evaluate", str(outside_folder), "-j", "1", "--json"])
    assert "Traceback" not in r.output
    data = json.loads(r.stdout)
    assert data["outcomes"]["right"] == 2 and data["outcomes"]["wrong"] == 0
    assert r.exit_code == 0, r.output  # every pair right: done


def test_plan_refuses_and_verify_fails_a_napkin_in_no_known_state(outside_folder):
    color = str(outside_folder / "none_001_color.png")  # gate-folded
    depth = color.replace("_color", "_depth")
    r = CliRunner().invoke(main, ["plan", color, depth, "--goal", "08"])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert "no known state fits" in r.output
    r = CliRunner().invoke(main, ["verify", color, depth, "--expect", "09"])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert r.output.startswith("failed: the napkin is in no known state")


def test_label_says_cannot_tell_for_a_mesh_outside_the_twelve(tmp_path):
    """An episode of a flat rest frame, a strip folded over, a gate fold and a corner
    folded twice: the first two right, the other two no class."""
    meshes = [sample_state("01", None, np.random.default_rng(1), placement=False).mesh,
              sample_state("09", "AB", np.random.default_rng(2)).mesh,
              sample_outside("gate", np.random.default_rng(3)).mesh,
              sample_outside("strip-and-corner", np.random.default_rng(4)).mesh]
    path = tmp_path / "episode.npz"
    np.savez(path, positions=np.stack([m.xyz for m in meshes]) * 1000,
             grid=np.array(meshes[0].shape))
    r = CliRunner().invoke(main, ["label", str(path), "--units", "mm", "--json"])
    assert "Traceback" not in r.output
    frames = json.loads(r.stdout)["episodes"][0]["frames"]
    assert [f["class"] for f in frames] == ["01", "09", None, None]
    assert all("no known state fits" in f["note"] for f in frames[2:])


def test_watch_shows_a_frame_in_no_known_state_as_none_and_keeps_smoothing():
    """dgli watch's online smoother: a frame in none of the twelve is shown as none (its
    own answer and the smoothed state), then the state comes back with the evidence."""
    import time

    from dgli_vision.analysis.live import _Arrival, _Worker

    owners = [(r.class_id, r.variant) for r in REFS.references]
    d02 = tuple(float(v) for v in np.where([o == ("02", "A") for o in owners], 0.01, 1.0))
    worker = _Worker(REFS, None, keep_path=False)
    answers = [(("02", "A"), 1.0, d02, None)] * 3 + [((OUTSIDE, None), 0.0, (), "cannot tell")]
    answers += [(("02", "A"), 1.0, d02, None)] * 2
    shown = [
        worker.record(_Arrival(t, SimpleNamespace(time=None), time.perf_counter()), 0, a).smoothed
        for t, a in enumerate(answers)
    ]
    assert shown == [("02", "A")] * 3 + [(OUTSIDE, None)] + [("02", "A")] * 2
