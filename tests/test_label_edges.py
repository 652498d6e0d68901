"""`dgli label` at its edges: the up axis's sign, a cloth turned over, a folded rest
frame, files that used to end in a traceback, and output that used to be lost."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout
from dgli_vision.core.run_lock import RunLock
from dgli_vision.labelling import episodes as episodes_module
from dgli_vision.labelling.episodes import ReadOptions
from dgli_vision.labelling.export import remesh, rigid_motion, write_npz
from dgli_vision.labelling.label import EpisodeFailure, EpisodeLabels
from dgli_vision.labelling.run import LabelJob, label_episodes
from dgli_vision.sim.cloth.mesh import flat_mesh
from dgli_vision.sim.cloth.sequences import sequence_state, sequence_steps
from dgli_vision.sim.cloth.states import sample_state

SEED = 38
STATES = [("02", "A"), ("03", "B"), ("04", "CD"), ("09", "AB"), ("10", "BC"), ("11", "DA")]


@pytest.fixture(scope="module")
def grid_episode():
    """A flat rest frame and six folded states (z up, metres), with their truth."""
    flat = flat_mesh(default_layout())
    meshes = [flat] + [
        sample_state(c, v, np.random.default_rng([SEED, k])).mesh
        for k, (c, v) in enumerate(STATES)
    ]
    pos = rigid_motion(np.stack([m.xyz for m in meshes]), np.random.default_rng(SEED))
    return pos, flat.shape, [("01", None), *STATES]


def _label(path, options: ReadOptions | None = None):
    (result,) = label_episodes(LabelJob((str(path),), options or ReadOptions()))
    return result


def _turned_over(pos: np.ndarray) -> np.ndarray:
    """The cloth turned over on the table (half a turn about a horizontal axis)."""
    out = pos.copy()
    out[..., 1] *= -1
    out[..., 2] = 2 * pos[..., 2].min() - pos[..., 2]
    return out


def test_up_axis_of_the_wrong_sign_is_an_error_not_swapped_labels(tmp_path, grid_episode):
    pos, shape, truth = grid_episode
    path = tmp_path / "z_up.npz"
    write_npz(path, pos, grid=shape)
    right = _label(path)
    assert isinstance(right, EpisodeLabels)
    assert [(f.class_id, f.variant) for f in right.frames] == truth
    wrong = _label(path, ReadOptions(up_axis="-z"))  # 5 of 6 folds were labelled swapped
    assert isinstance(wrong, EpisodeFailure)
    assert "below the table" in wrong.error and "sign of --up-axis" in wrong.error


def test_a_frame_below_the_table_is_cannot_tell(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    frames = np.concatenate([pos[:1]] * 9 + [pos[1:2]] * 2)  # 11 frames, one sunk
    frames[10, :, 2] -= 0.004
    path = tmp_path / "sunk.npz"
    write_npz(path, frames, grid=shape)
    ep = _label(path)
    assert isinstance(ep, EpisodeLabels)
    assert ep.frames[9].class_id == "02"
    assert ep.frames[10].class_id is None and "below the table" in ep.frames[10].note


@pytest.mark.parametrize("remeshed", [False, True])
def test_a_cloth_lying_back_face_up_is_reported_not_labelled(tmp_path, grid_episode, remeshed):
    pos, shape, _ = grid_episode
    frames = np.stack([pos[0], _turned_over(pos[:1])[0], pos[0]])
    path = tmp_path / "turned.npz"
    if remeshed:
        rm = remesh((400.0, 400.0), 800, np.random.default_rng(SEED))
        flat = flat_mesh(default_layout())
        local = rm.positions([flat])[0]
        moved = np.stack([local, _turned_over(local[None])[0], local])
        write_npz(path, moved, faces=rm.faces)
    else:
        write_npz(path, frames, grid=shape)
    ep = _label(path)
    turned = ep.frames[1]
    assert turned.class_id is None and turned.confidence == 0.0  # was 08 at 1.0
    assert turned.note.startswith("cannot tell: back face up")
    assert ep.frames[0].class_id == ep.frames[2].class_id == "01"
    assert ep.frames[1].smoothed_class == "01"  # smoothing goes over it


def test_a_folded_first_frame_is_refused(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    half = pos[[6, 0, 1]]  # starts as a half fold: 4 of 6 states were wrong
    write_npz(tmp_path / "half.npz", half, grid=shape)
    res = CliRunner().invoke(main, ["label", str(tmp_path / "half.npz"), "--json"])
    assert res.exit_code == 2
    assert "half.npz" in res.stderr and "rest frame is folded" in res.stderr
    rm = remesh((400.0, 400.0), 800, np.random.default_rng(SEED))
    flat = flat_mesh(default_layout())
    corner = sample_state("02", "A", np.random.default_rng(SEED)).mesh
    write_npz(tmp_path / "mesh.npz", rm.positions([corner, flat]), faces=rm.faces)
    failed = _label(tmp_path / "mesh.npz")
    assert isinstance(failed, EpisodeFailure) and "rest frame is folded" in failed.error
    # a grid whose first frame has one corner folded was labelled, with a note: refused
    write_npz(tmp_path / "corner.npz", pos[[1, 0, 1]], grid=shape)
    res = CliRunner().invoke(main, ["label", str(tmp_path / "corner.npz"), "--json"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    (line,) = [e for e in res.stderr.splitlines() if e.startswith("error:")]
    assert "corner.npz" in line and "rest frame is folded" in line and "--rest" in line
    assert json.loads(res.stdout)["episodes"] == []


@pytest.mark.parametrize("remeshed", [False, True])
def test_an_episode_starting_with_a_corner_fold_settled_gives_no_confident_answer(
    tmp_path, remeshed
):
    """Sequence II from its first corner laid flat on the table: without --rest every
    frame was labelled from the folded first frame; now the episode is refused with the
    reason, and with the flat cloth as --rest every answer is right."""
    steps = sequence_steps("II")
    progress = np.linspace(1.0, 4.0, 13)  # 02 laid flat first, then three more corners
    states = [sequence_state("II", float(t), steps=steps) for t in progress]
    meshes = [flat_mesh(default_layout())] + [s.mesh for s in states]
    truth = [(s.class_id, s.variant) for s in states]
    pos = rigid_motion(np.stack([m.xyz for m in meshes]), np.random.default_rng(SEED))
    if remeshed:
        rm = remesh((400.0, 400.0), 800, np.random.default_rng(SEED))
        pos = rm.positions(meshes)
        write_npz(tmp_path / "episode.npz", pos[1:], faces=rm.faces)
        write_npz(tmp_path / "rest.npz", pos[:1], faces=rm.faces)
    else:
        write_npz(tmp_path / "episode.npz", pos[1:], grid=meshes[0].shape)
        write_npz(tmp_path / "rest.npz", pos[:1], grid=meshes[0].shape)
    args = ["label", str(tmp_path / "episode.npz"), "--json"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "episode.npz" in res.stderr and "rest frame is folded" in res.stderr
    assert json.loads(res.stdout)["episodes"] == []  # no frame answered from it
    res = CliRunner().invoke(main, [*args, "--rest", str(tmp_path / "rest.npz")])
    assert res.exit_code == 0, res.output
    (ep,) = json.loads(res.stdout)["episodes"]
    answers = [(f["class"], f["variant"]) for f in ep["frames"]]
    wrong = [(a, t) for a, t in zip(answers, truth) if a[0] is not None and a != t]
    assert not wrong and sum(a[0] is not None for a in answers) >= len(truth) // 2


def test_a_size_the_mesh_contradicts_is_refused(tmp_path, grid_episode):
    """--size 250 on a 400 mm cloth (metres) labelled one frame wrong and four variants:
    the rest frame's own size, a napkin's, says otherwise."""
    pos, shape, _ = grid_episode
    write_npz(tmp_path / "cloth.npz", pos, grid=shape)
    res = CliRunner().invoke(main, ["label", str(tmp_path / "cloth.npz"), "--size", "250"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    (line,) = [e for e in res.stderr.splitlines() if e.startswith("error:")]
    assert "cloth.npz" in line and "--size 250x250" in line and "400 x 400 mm" in line
    for near in ("400", "410x390"):  # within a few percent: scaled to it
        res = CliRunner().invoke(main, ["label", str(tmp_path / "cloth.npz"), "--size", near])
        assert res.exit_code == 0, res.output
    # positions in no napkin's size in --units (millimetres read as metres): --size scales
    write_npz(tmp_path / "mm.npz", pos * 1000, grid=shape)
    res = CliRunner().invoke(main, ["label", str(tmp_path / "mm.npz"), "--size", "400",
                                    "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["episodes"][0]["size_mm"] == [400.0, 400.0]


def test_a_grid_rest_frame_that_is_not_flat_is_refused(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    bent = pos[:2].copy()
    rows = bent[0].reshape(*shape, 3)
    rows[shape[0] // 2 :, :, 2] += np.linspace(0, 0.2, shape[0] - shape[0] // 2)[:, None]
    write_npz(tmp_path / "bent.npz", bent, grid=shape)
    failed = _label(tmp_path / "bent.npz")
    assert isinstance(failed, EpisodeFailure) and "not flat" in failed.error


def _bad_files(tmp_path: Path, pos: np.ndarray, shape: tuple[int, int]) -> dict[str, str]:
    """Files that ended in a traceback, and what their one line says."""
    grid = np.array(shape)
    np.savez(tmp_path / "coincide.npz", positions=np.zeros((2, pos.shape[1], 3)), grid=grid)
    (tmp_path / "empty.mat").write_bytes(b"")
    np.savez(tmp_path / "whole.npz", positions=pos, grid=grid)
    data = (tmp_path / "whole.npz").read_bytes()
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    np.savez(tmp_path / "complex.npz", positions=pos.astype(complex), grid=grid)
    import scipy.io

    cells = np.empty((1, len(pos)), dtype=object)
    for t, p in enumerate(pos):
        cells[0, t] = p.astype(complex)
    scipy.io.savemat(tmp_path / "complex.mat", {"phiPositions": cells, "Eb": [[1, 2], [2, 3]]})
    huge = pos.copy()
    huge[1] *= 1e300
    np.savez(tmp_path / "huge.npz", positions=huge, grid=grid)
    # a zero-filled positions array: 24 MB inflated from a few KB stored
    with zipfile.ZipFile(tmp_path / "bomb.npz", "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open("positions.npy", "w") as fh:
            np.lib.format.write_array(fh, np.zeros((1000, 1000, 3)))
        with zf.open("grid.npy", "w") as fh:
            np.lib.format.write_array(fh, np.array([1000, 1000]))
    return {
        "coincide.npz": "lie at one point",
        "empty.mat": "cannot read as a MATLAB file",
        "truncated.npz": "cannot read as NPZ",
        "complex.npz": "complex",
        "complex.mat": "not real numbers",
        "huge.npz": "frame 1: positions are NaN, infinite or beyond",
        "bomb.npz": "would inflate to",
    }


def test_files_that_raised_are_one_line_each(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    bad = _bad_files(tmp_path, pos[:2], shape)
    args = [str(tmp_path / name) for name in bad]
    res = CliRunner().invoke(main, ["label", *args, "--json"])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == len(bad), res.stderr
    for line, (name, why) in zip(errors, bad.items()):
        assert name in line and why in line, line
    res = CliRunner().invoke(main, ["label", str(tmp_path / "whole.npz"), "--size", "1e30"])
    assert res.exit_code == 2 and "--size" in res.stderr and "out of range" in res.stderr


def test_npz_members_are_sized_before_they_are_read(tmp_path, grid_episode, monkeypatch):
    pos, shape, _ = grid_episode
    path = tmp_path / "extra.npz"
    np.savez_compressed(path, positions=pos[:2], grid=np.array(shape), junk=np.zeros(10**6))
    read = []
    real = np.lib.format.read_array
    monkeypatch.setattr(
        np.lib.format, "read_array", lambda fh, **kw: read.append(fh.name) or real(fh, **kw)
    )
    assert isinstance(_label(path), EpisodeLabels)
    assert sorted(read) == ["grid.npy", "positions.npy"]  # the unused member stays shut
    monkeypatch.setattr(episodes_module, "MAX_NPZ_BYTES", 1000)  # a declared 2.4 GB
    read.clear()
    failed = _label(path)
    assert isinstance(failed, EpisodeFailure) and "would inflate to" in failed.error
    assert read == []


def test_a_second_run_into_the_folder_is_refused(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    write_npz(tmp_path / "a.npz", pos[:2], grid=shape)
    out = tmp_path / "out"
    with RunLock(out, "dgli label a.npz -o out"):
        res = CliRunner().invoke(main, ["label", str(tmp_path / "a.npz"), "-o", str(out)])
    assert res.exit_code == 2 and "in use by another dgli run" in res.stderr
    assert not (out / "a.jsonl").exists()


def test_interrupted_run_resumes_to_the_same_files(tmp_path, grid_episode, monkeypatch):
    pos, shape, _ = grid_episode
    paths = []
    for k in range(3):
        paths.append(str(tmp_path / f"e{k}.npz"))
        write_npz(paths[-1], pos[[0, k + 1]], grid=shape)
    whole = tmp_path / "whole"
    res = CliRunner().invoke(main, ["label", *paths, "-o", str(whole)])
    assert res.exit_code == 0, res.output
    summary = json.loads((whole / "summary.json").read_text())
    assert summary["command"].startswith(f"dgli label {paths[0]} {paths[1]} ")  # not a repr

    import dgli_vision.labelling.run as run_module

    real = run_module.label_episodes

    def stopped_after_one(job):
        for k, result in enumerate(real(job)):
            if k == 1:
                raise KeyboardInterrupt  # Ctrl-C while the second episode is labelled
            yield result

    out = tmp_path / "out"
    monkeypatch.setattr(run_module, "label_episodes", stopped_after_one)
    res = CliRunner().invoke(main, ["label", *paths, "-o", str(out)])
    assert res.exit_code == 130, res.output
    assert "interrupted: 1 of 3 episodes done" in res.stderr and "--resume" in res.stderr
    assert json.loads((out / "summary.json").read_text())["interrupted"] == {"done": 1, "of": 3}
    assert not (out / "e1.jsonl").exists()
    res = CliRunner().invoke(main, ["label", *paths, "-o", str(out)])
    assert res.exit_code == 2 and "--resume" in res.stderr  # not silently started again
    monkeypatch.setattr(run_module, "label_episodes", real)
    res = CliRunner().invoke(main, ["label", *paths, "-o", str(out), "--resume"])
    assert res.exit_code == 0, res.output
    for name in ("e0.jsonl", "e1.jsonl", "e2.csv"):
        assert (out / name).read_text() == (whole / name).read_text()
    again = json.loads((out / "summary.json").read_text())
    assert {k: v for k, v in again.items() if k != "command"} == {
        k: v for k, v in summary.items() if k != "command"
    }
    res = CliRunner().invoke(main, ["label", *paths, "-o", str(out), "--resume", "--units", "cm"])
    assert res.exit_code == 2 and "changed since its run" in res.stderr


def test_sigterm_exits_143_keeping_the_episodes_done(tmp_path, grid_episode):
    pos, shape, _ = grid_episode
    paths = []
    for k in range(40):
        paths.append(str(tmp_path / f"e{k:02d}.npz"))
        write_npz(paths[-1], pos[[0, 1 + k % 6]], grid=shape, compress=False)
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dgli_vision", "label", *paths, "-o", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    journal = out / "results.jsonl"
    for _ in range(600):
        if journal.exists() and len(journal.read_text().splitlines()) >= 3:
            break
        if proc.poll() is not None:
            break
        import time

        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "interrupted:" in err
    done = [json.loads(x) for x in journal.read_text().splitlines()[1:]]
    assert done and all((out / f"{d['episode']}.csv").exists() for d in done)


def test_json_on_a_disk_that_fills_up_exits_2(tmp_path, grid_episode):
    """A file size limit (as a disk that fills up) takes the first 20,000 bytes of the
    JSON: the buffered write dropped the rest without an error, and the command exited
    0 with truncated JSON."""
    pos, shape, _ = grid_episode
    paths = [str(tmp_path / "a.npz"), str(tmp_path / "b.npz")]
    for p in paths:
        write_npz(p, np.concatenate([pos] * 6), grid=shape)
    target = tmp_path / "out.json"

    def limit() -> None:
        import resource

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    with target.open("w") as fh:
        proc = subprocess.run(
            [sys.executable, "-m", "dgli_vision", "label", *paths, "--json"],
            stdout=fh,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=limit,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},  # a text stream on the raw file
        )
    assert target.stat().st_size == 20_000  # the JSON is longer: it did not all go
    assert proc.returncode == 2, proc.stderr
    assert "cannot write to standard output" in proc.stderr
