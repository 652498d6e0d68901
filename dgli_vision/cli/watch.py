"""``dgli watch``: the state of every frame of a live camera (or a recording played like
one), as it comes."""

from __future__ import annotations

import shutil
import sys
from collections.abc import Iterable
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

import click

from .errors import handle_errors
from .options import colours_option, extrinsics_option, overwrite_option, references_option
from .output import echo, echo_json

if TYPE_CHECKING:
    from ..analysis.live import LiveSummary, LiveUpdate
    from ..classifier.pipeline import FrameResult
    from ..classifier.references import ReferenceSet
    from ..core.fold_graph import StateKey
    from ..core.frame import RGBDFrame
    from ..sources.recording import RecordedPair


#: ``--rerun [FILE.rrd]`` of ``dgli watch`` and ``dgli track``.
rerun_option = click.option(
    "--rerun",
    "rerun",
    is_flag=False,
    flag_value="",
    default=None,
    metavar="[FILE.rrd]",
    help="Log each frame to the Rerun viewer (the 'viewer' extra): spawn the viewer, or "
    "with FILE.rrd write a recording it opens (rerun FILE.rrd).",
)


def viewer_of(rerun: str | None, overwrite: bool, extrinsics: object, name: str):
    """The viewer log of ``--rerun`` (None without it)."""
    if rerun is None:
        return None
    from ..analysis.viewer import RerunLog

    return RerunLog(rerun or None, overwrite=overwrite, extrinsics=extrinsics, name=name)


@click.command()
@click.option(
    "--realsense",
    "serial",
    is_flag=False,
    flag_value="",
    default=None,
    metavar="[SERIAL]",
    help="Watch a RealSense camera (this serial number, or the first one found); needs "
    "the 'realsense' extra.",
)
@click.option(
    "--bag",
    "bag",
    type=click.Path(),
    help="Play a recording through the live path: a RealSense or ROS bag (or a folder of "
    "pairs with times).",
)
@click.option(
    "--every",
    default=1,
    show_default=True,
    type=click.IntRange(1),
    help="Classify only every N-th frame (the others are skipped, not dropped).",
)
@click.option("--jsonl", is_flag=True, help="One JSON object per frame on stdout.")
@click.option(
    "--overlay-dir",
    type=click.Path(file_okay=False),
    help="Write each classified frame's overlay here (frame_NNNNNN.png).",
)
@click.option(
    "--realtime/--fast",
    default=True,
    show_default=True,
    help="--bag: play at the recorded pace (frames that come while one is classified are "
    "dropped, as from a camera) or as fast as frames are classified (none dropped).",
)
@click.option(
    "--camera-mode",
    default="1280x720@30",
    show_default=True,
    help="--realsense: the colour stream, WIDTHxHEIGHT@FPS.",
)
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(1),
    default=None,
    help="Processes classifying frames side by side (1: in this process) [default: all "
    "cores; 1 with --overlay-dir].",
)
@rerun_option
@click.option(
    "--goal",
    default=None,
    metavar="STATE",
    help="--rerun: also log the plan towards this state (08, 02/A, 05/AB/B) from each "
    "frame: its first step's grasp, place and fold line.",
)
@references_option
@colours_option
@extrinsics_option
@overwrite_option
@handle_errors
def watch(
    serial: str | None,
    bag: str | None,
    every: int,
    jsonl: bool,
    overlay_dir: str | None,
    realtime: bool,
    camera_mode: str,
    jobs: int | None,
    rerun: str | None,
    goal: str | None,
    references_path: str | None,
    colours_path: str | None,
    extrinsics_path: str | None,
    overwrite: bool,
) -> None:
    """Classify the frames of a live camera as they come, smoothed over time.

    The newest frame is classified as soon as the one before is done; frames that come
    meanwhile are dropped (counted, never queued), so the answer is never late by more
    than a frame. With --jsonl, one JSON object per frame on stdout: frame, time,
    state, smoothed, confidence, change, dropped, latency_ms, note, corners, up and
    points_frame (docs/live.md; with --extrinsics the corners and up in the robot's base
    frame); then a last line {"summary": ...}. Otherwise the state changes, and on a
    terminal a live status line. With --rerun, each frame is logged to the Rerun
    viewer (the 'viewer' extra): the image with the stickers found and missing, the 3D
    stickers, segments and table, the state and confidence over time, and with --goal
    the plan's grasp and place; --rerun FILE.rrd writes a recording instead of
    spawning the viewer. Ctrl-C (or SIGTERM) stops after the frame being classified,
    prints the summary and exits 0.
    """
    from ..core.errors import InvalidInputError
    from ..core.extrinsics import read_extrinsics
    from ..sources.colours_file import read_colours
    from .runs import references_of

    if (serial is None) == (bag is None):
        raise InvalidInputError("dgli watch needs one source: --realsense [SERIAL] or --bag FILE")
    extrinsics = read_extrinsics(extrinsics_path) if extrinsics_path else None
    refs, _ = references_of(references_path)
    colours = read_colours(colours_path) if colours_path else None
    in_here = overlay_dir is not None or rerun is not None
    if jobs is None:
        jobs = 1 if in_here else _cores()
    elif jobs > 1 and overlay_dir is not None:
        raise InvalidInputError("--overlay-dir draws each frame in this process: use -j 1")
    elif jobs > 1 and goal is not None:
        raise InvalidInputError("--goal plans from each frame in this process: use -j 1")
    if goal is not None and rerun is None:
        raise InvalidInputError("--goal is logged to the viewer: add --rerun [FILE.rrd]")
    target = _goal_of(goal, refs)
    overlays = _overlay_folder(overlay_dir, overwrite)
    viewer = viewer_of(rerun, overwrite, extrinsics, bag or f"realsense {serial or ''}")
    try:
        frames, notes = _source(serial, bag, camera_mode)
        for note in notes:
            click.echo(f"{bag}: {note}", err=True)
        out = _Printer(jsonl, overlays, extrinsics, viewer=viewer, goal=target)
        summary = _run(
            frames, refs, colours, every, realtime and bag is not None, out, bool(bag), jobs
        )
    finally:
        if viewer is not None:
            viewer.close()
    out.done(summary)
    if viewer is not None and viewer.path is not None:
        click.echo(f"viewer recording written to {viewer.path}", err=True)
    if summary.classified and not summary.stopped and not out.answered:
        sys.exit(1)  # the source ended and no frame could be classified at all


def _source(
    serial: str | None, bag: str | None, mode: str
) -> tuple[Iterable[RecordedPair], list[str]]:
    """The frames to watch and the notes on them."""
    from ..core.errors import InvalidInputError
    from ..sources.realsense import camera_pairs
    from ..sources.recording import open_recording

    if bag is not None:
        recording = open_recording(bag, live=True)
        return recording.frames, recording.notes
    try:
        size, fps = mode.split("@")
        width, height = (int(v) for v in size.lower().split("x"))
        rate = int(fps)
    except ValueError:
        raise InvalidInputError(
            f"--camera-mode {mode!r} is not WIDTHxHEIGHT@FPS (e.g. 1280x720@30)"
        ) from None
    return camera_pairs(serial or None, width=width, height=height, fps=rate), []


def _goal_of(goal: str | None, refs: ReferenceSet) -> tuple[StateKey, object] | None:
    """The goal state and the napkin's layout to plan with (None: no --goal)."""
    from ..core.errors import InvalidInputError
    from ..core.layout import layout_of_size
    from ..planning.plan import parse_state

    if goal is None:
        return None
    try:
        key = parse_state(goal, need_variant=False)
    except ValueError as exc:
        raise InvalidInputError(f"--goal: {exc}") from None
    return key, layout_of_size(refs.napkin_mm)


def _overlay_folder(folder: str | None, overwrite: bool) -> Path | None:
    """The overlay folder, made now; one holding files stops the run unless --overwrite."""
    from ..core.errors import OutputError, OverwriteError

    if folder is None:
        return None
    root = Path(folder)
    if root.is_dir() and any(root.iterdir()) and not overwrite:
        raise OverwriteError(
            f"overlay folder '{root}' is not empty; empty it or add --overwrite"
        )
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot make overlay folder '{root}': {exc.strerror}") from None
    return root


def _run(
    frames: Iterable[RecordedPair],
    refs: ReferenceSet,
    colours: dict[str, tuple[int, int, int]] | None,
    every: int,
    realtime: bool,
    out: _Printer,
    keep_path: bool,
    jobs: int,
) -> LiveSummary:
    """The live loop with Ctrl-C and SIGTERM turned into a clean stop."""
    import signal
    import threading

    from ..analysis.live import watch as watch_frames

    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    before = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return watch_frames(
            frames,
            refs,
            every=every,
            realtime=realtime,
            colours=colours,
            on_update=out.update,
            stop=stop,
            keep_path=keep_path,
            jobs=jobs,
        )
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)


def _cores() -> int:
    """The processors this process may run on."""
    import os

    getter = getattr(os, "sched_getaffinity", None)
    return len(getter(0)) if getter is not None else os.cpu_count() or 1


def _state_text(key: StateKey | None) -> str:
    from ..core.classes import CLASS_NAMES

    if key is None:
        return "cannot tell"
    name = CLASS_NAMES.get(key[0], "(no known state)")
    return f"{key[0]} {name}" + (f" {key[1]}" if key[1] else "")


class _Printer:
    """Writes each frame's answer: a JSON line, or the changes and a status line."""

    def __init__(
        self, jsonl: bool, overlays: Path | None, extrinsics=None, *, viewer=None, goal=None
    ) -> None:
        self.jsonl, self.overlays, self.extrinsics = jsonl, overlays, extrinsics
        self.viewer, self.goal = viewer, goal
        self.tty = sys.stderr.isatty()
        self.answered = False  # some frame got a state
        self.status_shown = False
        self.width = max(40, shutil.get_terminal_size().columns - 1)

    def update(
        self, update: LiveUpdate, frame: RGBDFrame | None, result: FrameResult | None
    ) -> None:
        """One classified frame (called by the worker)."""
        self.answered = self.answered or update.state is not None
        if self.overlays is not None and result is not None:
            from ..analysis.overlay import frame_overlay
            from ..core.io import write_png

            name = self.overlays / f"frame_{update.frame:06d}.png"
            write_png(name, frame_overlay(result.frame_as_read(frame), result))
        if self.viewer is not None:
            self.viewer.frame(
                update.frame, update.time, state=update.state, smoothed=update.smoothed,
                confidence=update.confidence, note=update.note,
                frame=result.frame_as_read(frame), result=result,
                corners=update.corners, plan=self._plan(frame, result),
            )
        if self.jsonl:  # "frame" is the frame's number: the points' frame is points_frame
            from ..core.extrinsics import in_frame

            echo_json(in_frame(update.to_json(), self.extrinsics, frame_key="points_frame"))
        elif update.change is not None:
            self._clear()
            t = "" if update.time is None else f" ({update.time:.2f} s)"
            echo(
                f"frame {update.frame}{t}: {_state_text(update.change[0])} -> "
                f"{_state_text(update.change[1])}"
            )
        if self.tty:
            conf = "" if update.confidence is None else f" {update.confidence:.2f}"
            line = (
                f"frame {update.frame}: {_state_text(update.smoothed)} (frame says "
                f"{_state_text(update.state)}{conf}); {update.latency_ms:.0f} ms, "
                f"{update.dropped} dropped"
            )
            click.echo("\r" + line[: self.width].ljust(self.width), nl=False, err=True)
            self.status_shown = True

    def _plan(self, frame: RGBDFrame | None, result: FrameResult | None):
        """The plan from this frame to --goal (None: no goal, or no plan from here)."""
        if self.goal is None or result is None or result.prediction is None:
            return None
        from ..planning.api import plan_frame
        from ..planning.plan import PlanRefused

        try:
            return plan_frame(result, frame, *self.goal)
        except PlanRefused:
            return None

    def _clear(self) -> None:
        if self.status_shown:
            click.echo("\r" + " " * self.width + "\r", nl=False, err=True)
            self.status_shown = False

    def done(self, summary: LiveSummary) -> None:
        """The summary: a last JSON line with --jsonl, and one line on stderr."""
        self._clear()
        if self.jsonl:
            echo_json({"summary": summary.to_json()})
        rate = summary.classified / summary.seconds if summary.seconds else 0.0
        last = summary.path[-1] if summary.path else None
        click.echo(
            ("stopped: " if summary.stopped else "")
            + f"{summary.arrived} frames, {summary.classified} classified ({rate:.1f} per "
            f"second), {summary.dropped} dropped, {summary.skipped} skipped by --every; "
            f"latency median {summary.latency_ms['median']:.0f} ms, p90 "
            f"{summary.latency_ms['p90']:.0f} ms; last state {_state_text(last)}",
            err=True,
        )
