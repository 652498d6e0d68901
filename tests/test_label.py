"""`dgli label`: other simulators' cloth episodes (NPZ, SoftGym, CloSE .mat, OBJ/PLY
folders) exported from the project's own simulator, labelled frame by frame."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.analysis.track import score_timeline
from dgli_vision.classifier.classify import classify_coordinates, reference_distances
from dgli_vision.classifier.references import load_references
from dgli_vision.cli import main
from dgli_vision.core.classes import VARIANTS
from dgli_vision.core.layout import default_layout
from dgli_vision.labelling.distances import frame_distances, verdicts
from dgli_vision.labelling.episodes import ClothEpisode, ReadOptions, grid_faces
from dgli_vision.labelling.export import (
    remesh,
    rigid_motion,
    to_simulator,
    write_mat,
    write_meshes,
    write_npz,
)
from dgli_vision.labelling.label import EpisodeLabels
from dgli_vision.labelling.material import cloth_material
from dgli_vision.labelling.observe import observe_frames, place_stickers
from dgli_vision.labelling.run import LabelJob, label_episodes
from dgli_vision.sim.cloth.mesh import flat_mesh
from dgli_vision.sim.cloth.sequences import sequence_progress, sequence_state, sequence_steps
from dgli_vision.sim.cloth.states import sample_state

REFS = load_references()
SEED = 27


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A flat rest frame, then one finished state of every class (variants drawn);
    written in every input format under its own rigid motion, up axis
    and unit, as the grid and remeshed."""
    rng = np.random.default_rng(SEED)
    meshes, truth = [flat_mesh(default_layout())], [("01", None)]
    for k, (c, vs) in enumerate(VARIANTS.items()):
        v = vs[(k + SEED) % len(vs)]
        meshes.append(sample_state(c, v, np.random.default_rng([SEED, int(c), k])).mesh)
        truth.append((c, v))
    pos = np.stack([m.xyz for m in meshes])
    ny, nx = meshes[0].shape
    rm = remesh((400.0, 400.0), 3000, rng)
    rpos = rm.positions(meshes)
    out = tmp_path_factory.mktemp("episodes")
    transposed = pos.reshape(len(pos), ny, nx, 3).transpose(0, 2, 1, 3).reshape(pos.shape)
    cases = {
        "grid_y_cm.npz": (pos, "y", "cm", dict(grid=(ny, nx))),
        "softgym_y_m.npz": (pos, "y", "m", dict(grid=(ny, nx), softgym=True)),
        "transposed_z_mm.npz": (transposed, "z", "mm", dict(grid=(nx, ny))),
        "remeshed_-x_mm.npz": (rpos, "-x", "mm", dict(faces=rm.faces)),
        "close_z_m.mat": (rpos, "z", "m", None),
        "objs_y_cm": (rpos, "y", "cm", ".obj"),
        "plys_z_m": (rpos, "z", "m", ".ply"),
    }
    episodes = []
    for name, (p, up, units, how) in cases.items():
        sim = to_simulator(rigid_motion(p, rng), up, units)
        path = out / name
        if name.endswith(".mat"):
            write_mat(path, sim, rm.border)
        elif isinstance(how, str):
            write_meshes(path, sim, rm.faces, suffix=how)
        else:
            write_npz(path, sim, **how)
        episodes.append((str(path), ReadOptions(up_axis=up, units=units)))
    return episodes, truth, len(rm.uv)


def _label(path: str, options: ReadOptions, **kw) -> EpisodeLabels:
    (result,) = label_episodes(LabelJob((path,), options, **kw))
    assert isinstance(result, EpisodeLabels), result
    return result


def test_finished_states_right_by_class_and_variant_in_every_format(finished):
    episodes, truth, n_vertices = finished
    assert 2800 <= n_vertices <= 3300  # the remeshed cloth: about 3,000 vertices, no grid
    for path, options in episodes:
        ep = _label(path, options)
        got = [(f.class_id, f.variant) for f in ep.frames]
        assert got == truth, path
        assert all(f.progress is None for f in ep.frames), path
        assert ep.info["size_mm"] == pytest.approx([400, 400], abs=2), path
        # OmniGibson's predicates on the same frames: the flat cloth is Unfolded, a
        # half fold Folded, a diagonal fold (its hull's diagonal unchanged) not Folded
        og = {t: f.omnigibson for f, t in zip(ep.frames, truth)}
        assert og[("01", None)] == (False, True), path
        assert og[next(t for t in truth if t[0] == "11")] == (True, False), path
        assert og[next(t for t in truth if t[0] == "12")][0] is False, path


def _sequence(name: str, n_frames: int, rng: np.random.Generator):
    steps = sequence_steps(name, rng=rng)
    yaw = float(rng.uniform(0, 2 * np.pi))
    progress = sequence_progress(name, n_frames)
    return [sequence_state(name, p, steps=steps, yaw=yaw) for p in progress]


def test_folding_sequence_changes_found_within_two_frames_remeshed(tmp_path):
    rng = np.random.default_rng(SEED + 1)
    states = _sequence("I", 20, rng)
    rm = remesh((400.0, 400.0), 3000, rng)
    path = tmp_path / "seq.npz"
    sim = to_simulator(rigid_motion(rm.positions([s.mesh for s in states]), rng), "y", "mm")
    write_npz(path, sim, faces=rm.faces)
    ep = _label(str(path), ReadOptions(up_axis="y", units="mm"))
    truth = [s.class_id for s in states]
    score = score_timeline(
        truth, [f.class_id for f in ep.frames], [f.smoothed_class for f in ep.frames]
    )
    assert score.raw_accuracy >= 0.95
    assert score.recall == 1.0 and score.precision == 1.0
    assert [t for t, _, _ in ep.changes] == list(score.found_changes)
    assert ep.changes[-1][2] == ("06", "AC")
    # frames of a fold past 90 degrees say which fold is in progress (or, nearly laid
    # flat, none); those before 90 degrees that it has not turned past
    stage = [s.params.get("stage", "") for s in states]
    past = [f.progress for f, st in zip(ep.frames, stage) if "settling" in st and f.progress]
    rising = [f.progress for f, st in zip(ep.frames, stage) if "rising" in st and f.progress]
    assert past and all(p["past_90"] and p["fold"] in ("A over", "C over") for p in past)
    assert rising and not any(p["past_90"] for p in rising)


def test_batched_distances_and_verdicts_equal_the_classifiers():
    rng = np.random.default_rng(SEED + 2)
    states = _sequence("I", 10, rng)
    pos = np.stack([s.mesh.xyz for s in states])
    ny, nx = states[0].mesh.shape
    material = cloth_material(ClothEpisode("seq", pos, grid_faces(ny, nx), (ny, nx)))
    ev = observe_frames(pos, material, place_stickers(material))
    e = ev.evidence
    assert e.unknown.any() and np.isfinite(e.past).any()  # a flap held up edge-on
    batch = frame_distances(ev, REFS)
    n_unknown = (e.unknown & ~np.isfinite(e.past)).sum(axis=1)
    v = verdicts(batch, REFS, n_unknown, ev.known_coordinates().sum(axis=1))
    for t in range(len(pos)):
        one = reference_distances(ev.coords[t], REFS, e.frame(t))
        np.testing.assert_allclose(batch[t], one, rtol=0, atol=1e-12)
        p = classify_coordinates(ev.coords[t], REFS, e.frame(t), distances=one)
        best = REFS.references[v.best[t]]
        assert (best.class_id, best.variant) == (p.class_id, p.variant)
        assert v.confidence[t] == pytest.approx(p.confidence, abs=1e-4)


def test_dask_cluster_and_local_processes_give_the_results_of_one_process(finished):
    import distributed  # the 'dask' extra, installed by scripts/setup.sh --test
    episodes, _, _ = finished
    paths = (episodes[0][0], episodes[5][0])  # both y up, in cm
    options = ReadOptions(up_axis="y", units="cm")
    one = [r.to_json() for r in label_episodes(LabelJob(paths, options, jobs=1))]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
    ) as cluster:
        job = LabelJob(paths, options, dask=cluster.scheduler_address)
        far = [r.to_json() for r in label_episodes(job)]
    assert far == one
    assert isinstance(one[0], dict) and one[0]["frames"]
    # two local processes: each episode split in two parts, put together in order
    (split,) = label_episodes(LabelJob(paths[1:], options, jobs=2))
    assert split.to_json() == one[1]


def _write_bad(tmp_path: Path) -> dict[str, str]:
    flat = flat_mesh(default_layout())
    ny, nx = flat.shape
    upright = np.stack([flat.xyz, flat.xyz]) * 100  # z up, cm
    pos = to_simulator(np.stack([flat.xyz, flat.xyz]), "y", "cm")
    nan = pos.copy()
    nan[1, 5, 2] = np.nan
    paths = {}
    np.savez(tmp_path / "nan.npz", positions=nan, grid=np.array([ny, nx]))
    paths["nan"] = "frame 1: positions are NaN"
    np.savez(tmp_path / "grid.npz", positions=pos, grid=np.array([ny, nx + 1]))
    paths["grid"] = "does not match"
    np.savez(tmp_path / "shape.npz", positions=pos[..., :2], grid=np.array([ny, nx]))
    paths["shape"] = "must be (T, N, 3)"
    faces = grid_faces(ny, nx)
    extra = np.array([[faces[0, 0], faces[0, 2], len(flat.xyz) - 1]])  # a 3rd on an edge
    np.savez(tmp_path / "manifold.npz", positions=pos, faces=np.concatenate([faces, extra]))
    paths["manifold"] = "shared by more than two triangles"
    disc = np.linalg.norm(flat.uv - 200.0, axis=1) <= 200.0  # a round cloth
    keep = np.flatnonzero(disc)
    remap = -np.ones(len(flat.uv), int)
    remap[keep] = np.arange(len(keep))
    inside = faces[disc[faces].all(axis=1)]
    np.savez(tmp_path / "round.npz", positions=pos[:, keep], faces=remap[inside])
    paths["round"] = "not rectangular"
    np.savez(tmp_path / "upright.npz", positions=upright, grid=np.array([ny, nx]))
    paths["upright"] = "is --up-axis right?"
    np.savez(tmp_path / "units.npz", positions=pos * 1000, grid=np.array([ny, nx]))  # in 10 um
    paths["units"] = "are --units right"
    return paths


def test_bad_inputs_one_line_each_and_the_batch_goes_on(tmp_path, finished):
    bad = _write_bad(tmp_path)
    good = finished[0][0][0]
    args = [str(tmp_path / f"{k}.npz") for k in bad] + [good]
    res = CliRunner().invoke(main, ["label", *args, "--up-axis", "y", "--units", "cm", "--json"])
    assert res.exit_code == 2
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == len(bad)
    for line, (name, why) in zip(errors, bad.items()):
        assert f"{name}.npz" in line and why in line, line
    assert "Traceback" not in res.output
    data = json.loads(res.stdout)
    assert [e["path"] for e in data["episodes"]] == [good]
    assert [f["path"] for f in data["summary"]["failed"]] == args[:-1]


def test_cli_json_names_and_report_files(tmp_path, finished):
    path = finished[0][1][0]
    out = tmp_path / "out"
    res = CliRunner().invoke(
        main, ["label", path, "--up-axis", "y", "--json", "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    (ep,) = data["episodes"]
    assert {"path", "frames", "changes"} <= set(ep)
    frame = ep["frames"][3]
    assert {"index", "class", "variant", "progress", "confidence", "smoothed"} <= set(frame)
    assert set(frame["smoothed"]) == {"class", "variant"}
    assert data["summary"]["frames"] == len(ep["frames"])
    stem = Path(path).stem
    lines = (out / f"{stem}.jsonl").read_text().splitlines()
    assert [json.loads(x) for x in lines] == ep["frames"]
    assert (out / f"{stem}.csv").read_text().startswith("frame,class,variant")
    assert (out / f"{stem}_timeline.png").stat().st_size > 1000
    assert json.loads((out / "summary.json").read_text())["labelled"] == 1


def test_a_single_frame_is_an_episode_of_one_frame(tmp_path):
    state = sample_state("06", "BD", np.random.default_rng(SEED))
    path = tmp_path / "one.npz"
    np.savez(path, positions=state.mesh.xyz * 1000, grid=np.array(state.mesh.shape))
    flat = flat_mesh(default_layout())
    np.savez(tmp_path / "rest.npz", positions=flat.xyz * 1000, grid=np.array(flat.shape))
    args = ["label", str(path), "--units", "mm", "--json"]
    res = CliRunner().invoke(main, args)  # the frame is its own rest frame: folded
    assert res.exit_code == 2 and "rest frame is folded" in res.stderr
    res = CliRunner().invoke(main, [*args, "--rest", str(tmp_path / "rest.npz")])
    assert res.exit_code == 0, res.output
    (frame,) = json.loads(res.stdout)["episodes"][0]["frames"]
    assert (frame["class"], frame["variant"]) == ("06", "BD")


def test_rest_file_and_size_for_a_remeshed_cloth_in_unknown_units(tmp_path):
    """A folded frame alone cannot give the material coordinates of a remeshed cloth: the
    flat rest comes from --rest, and --size scales positions in arbitrary units."""
    rng = np.random.default_rng(SEED + 3)
    state = sample_state("09", "CD", np.random.default_rng(SEED))
    rm = remesh((400.0, 400.0), 600, rng)
    flat, folded = rm.positions([flat_mesh(default_layout()), state.mesh]) * 3.7
    write_meshes(tmp_path / "rest", flat[None], rm.faces)
    write_meshes(tmp_path / "frame", folded[None], rm.faces, suffix=".ply")
    args = ["label", str(tmp_path / "frame" / "frame_00000.ply"), "--json"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2 and "--rest" in res.stderr  # its own first frame is folded
    rest = str(tmp_path / "rest" / "frame_00000.obj")
    res = CliRunner().invoke(main, [*args, "--rest", rest, "--size", "400"])
    assert res.exit_code == 0, res.output
    (ep,) = json.loads(res.stdout)["episodes"]
    assert ep["size_mm"] == [400.0, 400.0]
    assert (ep["frames"][0]["class"], ep["frames"][0]["variant"]) == ("09", "CD")


def test_simulate_writes_episodes_that_label_reads_and_gets_right(tmp_path):
    """`dgli simulate OUT --episodes`: a command writes what `dgli label` reads, so that
    label can be tried from the docs alone; its truth.json scores the labels."""
    out = tmp_path / "episodes"
    run = CliRunner().invoke(main, ["simulate", str(out), "--episodes", "--frames", "6"])
    assert run.exit_code == 0, run.output
    names = sorted(p.name for p in out.glob("*.npz"))
    assert names == ["sequence_I.npz", "sequence_II.npz", "sequence_III.npz"]
    truth = json.loads((out / "truth.json").read_text())["episodes"]
    res = CliRunner().invoke(main, ["label", *map(str, sorted(out.glob("*.npz"))), "--json"])
    assert res.exit_code == 0, res.output
    frames = wrong = right = 0
    for ep in json.loads(res.stdout)["episodes"]:
        for got, want in zip(ep["frames"], truth[Path(ep["path"]).name], strict=True):
            frames += 1
            right += got["class"] == want["class"]
            wrong += got["class"] is not None and got["class"] != want["class"]
    assert frames == 18 and wrong == 0 and right >= 16
    again = CliRunner().invoke(main, ["simulate", str(out), "--episodes", "--frames", "6"])
    assert again.exit_code == 0  # its own files are replaced without --overwrite
    mixed = CliRunner().invoke(main, ["simulate", str(out), "--episodes", "--per-class", "3"])
    assert mixed.exit_code == 2 and "drop --per-class" in mixed.output
    assert "Traceback" not in mixed.output
