"""What the long runs (``dgli evaluate``, ``track``, ``render``, ``extract``) share:
recordings, the lock of an output folder, results.jsonl journals, stop signals."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any, Protocol

import click

from ..core.errors import DgliError
from .output import command_line, progress_bar

if TYPE_CHECKING:
    from ..classifier.references import ReferenceSet
    from ..core.io import JsonLinesWriter
    from ..sources.labelled import LabelledPair
    from ..sources.recording import Recording

#: A run's journal: the writer of its results.jsonl and the objects already in it.
Journal = tuple["JsonLinesWriter", list[dict[str, Any]]]


class JournalledRun(Protocol):
    """What :func:`run_journalled` and :func:`classify_into` need of a command's run."""

    refs: ReferenceSet
    jobs: int
    as_json: bool

    def go(self, journal: Journal | None, *, overwrite: bool) -> None: ...


def open_recording_with(path: str, opts: dict[str, Any]) -> Recording:
    """The recording at ``path`` with the options of :func:`recording_options`."""
    from ..sources.recording import open_recording

    return open_recording(
        path,
        color_topic=opts["color_topic"],
        depth_topic=opts["depth_topic"],
        info_topic=opts["info_topic"],
        tolerance=opts["tolerance_ms"] / 1000.0,
        labels=opts["labels_path"],
    )


def recording_notes(recording: Recording, quiet: bool = False) -> None:
    """A recording's notes on stderr (topics read, distortion, frames without a partner)."""
    if not quiet and recording.kind != "folder":
        for note in recording.notes:
            click.echo(f"{recording.kind}: {note}", err=True)


#: How each stop signal ends a command: 128 + its number, as a shell reports it.
STOP_EXIT_CODES = {2: 130, 15: 143}  # SIGINT, SIGTERM


class Stop:
    """Whether a stop signal came, and which (Ctrl-C unless SIGTERM came).

    Inside :meth:`holding`, a stop waits for the block to end: what the block keeps (a
    result written to the journal and counted) is kept whole or not at all.
    """

    stopped = False
    signum = 2
    _holding = False
    _pending = False

    @property
    def exit_code(self) -> int:
        return STOP_EXIT_CODES.get(self.signum, 128 + self.signum)

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        """Signal handler: note the stop, and interrupt the work unless it is held."""
        self.signum, self.stopped = signum, True
        if self._holding:
            self._pending = True
            return
        raise KeyboardInterrupt

    def cut_short(self, exc: BaseException) -> bool:
        """Whether ``exc`` is this stop interrupting the work: the KeyboardInterrupt that
        :meth:`on_signal` raises, or the SystemError a C function raises around it when
        the signal came while it ran (``np.fromfile`` checking its path, say)."""
        if isinstance(exc, KeyboardInterrupt):
            return True
        cause = exc.__cause__ or exc.__context__
        return self.stopped and isinstance(exc, SystemError) and isinstance(
            cause, KeyboardInterrupt
        )

    def holding(self):
        """A block that a stop signal does not cut in two (it interrupts after it)."""
        from contextlib import contextmanager

        @contextmanager
        def context():
            self._holding = True
            try:
                yield
            finally:
                self._holding = False
            if self._pending:
                self._pending = False
                raise KeyboardInterrupt

        return context()

    def ends(self):
        """A block that a stop signal ends early: the stop's KeyboardInterrupt (or the
        SystemError around it, :meth:`cut_short`), and the broken pool of workers a stop
        sent to the whole process group leaves, end the block quietly; anything else is
        raised."""
        from concurrent.futures.process import BrokenProcessPool
        from contextlib import contextmanager

        @contextmanager
        def context():
            try:
                yield
            except (KeyboardInterrupt, SystemError) as exc:
                if not self.cut_short(exc):
                    raise
                self.stopped = True
            except BrokenProcessPool:  # a stop sent to the whole group ended the workers
                if not self.stopped:
                    raise

        return context()


def stop_signals():
    """A context in which Ctrl-C and SIGTERM stop the work (a KeyboardInterrupt, never
    inside :meth:`Stop.holding`), yielding a :class:`Stop` that says which came."""
    import signal
    import threading
    from contextlib import contextmanager

    @contextmanager
    def context():
        stop = Stop()
        if threading.current_thread() is not threading.main_thread():
            yield stop
            return
        before = {s: signal.signal(s, stop.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield stop
        finally:
            for s, handler in before.items():
                signal.signal(s, handler)

    return context()


def folder_lock(folder: Path):
    """The lock of an output folder (:class:`~dgli_vision.core.run_lock.RunLock`), held for
    the ``with`` block; a stale lock left by a killed run is taken over with a note."""
    from contextlib import contextmanager

    from ..core.run_lock import RunLock

    @contextmanager
    def context():
        lock = RunLock(folder, command_line())
        lock.acquire()
        try:
            if lock.took_over:
                click.echo(
                    f"note: took over the lock of a run that ended without releasing it "
                    f"(pid {lock.took_over.get('pid')})",
                    err=True,
                )
            yield lock
        finally:
            lock.release()

    return context()


def open_journal(path: Path, header: dict[str, Any], resume: bool, overwrite: bool) -> Journal:
    """The writer of a run's results.jsonl and the objects already in it: with
    ``resume``, those of the same run (refused, naming the difference, when its header
    differs from ``header``); otherwise a new file starting with ``header`` (refused when
    an earlier run's results are there, unless ``overwrite``). A result whose images
    have changed since (size or time: captured again under the same names) is left out
    of those, with a note: it is classified again."""
    from ..core.errors import OverwriteError
    from ..core.io import JsonLinesWriter, read_jsonl
    from ..core.run_lock import check_resume, current_results, repair_journal

    earlier = read_jsonl(path) if resume else []
    if earlier:
        check_resume(path, earlier[0], header)
        repair_journal(path)
        kept, stale = current_results(earlier[1:])
        if stale:
            unit = "frame" if header.get("kind") == "track" else "pair"
            which = f"1 {unit} has" if stale == 1 else f"{stale} {unit}s have"
            click.echo(
                f"note: {which} changed since the interrupted run (image size or time): "
                "classified again",
                err=True,
            )
        return JsonLinesWriter(path, append=True), kept
    if path.exists() and not (resume or overwrite):
        raise OverwriteError(
            f"'{path}' holds the results of an earlier run; use --resume to go on "
            "with it, or --overwrite to start again"
        )
    writer = JsonLinesWriter(path, append=False)
    try:
        writer.write(header)
    except DgliError:
        writer.close()  # quietly: the failed write names the file
        raise
    return writer, []


def classify_into(
    todo: Iterable[LabelledPair],
    count: int,
    label: str,
    run: JournalledRun,
    writer: JsonLinesWriter | None,
    done: dict,
    stop: Stop,
    key: Callable[[LabelledPair], tuple[str, str]] | None = None,
    **options: Any,
) -> None:
    """Classify the pairs of ``todo`` (``count`` of them) on ``run.jobs`` workers with
    ``run.refs`` and a progress bar, each outcome into ``done`` by its pair (``key`` of
    it, :func:`~dgli_vision.analysis.evaluate.pair_key` by default) and, at once, into
    ``writer`` (results.jsonl): a run stopped by Ctrl-C or SIGTERM (``stop``) keeps what
    is done. ``options`` go to ``evaluate_pairs``."""
    from ..analysis.evaluate import evaluate_pairs, pair_key
    from ..core.run_lock import files_stamp

    with stop.ends(), progress_bar(count, label, quiet=run.as_json) as bar:
        for outcome in evaluate_pairs(
            todo, run.refs, jobs=run.jobs, on_progress=bar.update, **options
        ):
            with stop.holding():  # in the journal and counted, or neither
                if writer:  # flushed at once: an interrupted run keeps its work
                    pair = outcome.pair  # and the images it was read from, by stamp
                    stamp = files_stamp(pair.color, pair.depth)
                    writer.write({**outcome.to_json(), "files": stamp})
                done[(key or pair_key)(outcome.pair)] = outcome


def references_of(references_path: str | None) -> tuple[ReferenceSet, Path]:
    """The reference set of ``--references`` (None: the default one) and its path."""
    from ..classifier.references import default_references_path, load_references

    refs_path = Path(references_path) if references_path else default_references_path()
    return load_references(refs_path), refs_path


def require_report_for_resume(resume: bool, report_dir: str | None) -> None:
    """Refuse ``--resume`` without ``--report DIR``."""
    if resume and not report_dir:
        from ..core.errors import InvalidInputError

        raise InvalidInputError("--resume needs --report DIR, where results.jsonl is kept")


def run_journalled(
    run: JournalledRun,
    report_dir: str | None,
    files: tuple[str, ...],
    header: dict[str, Any],
    *,
    resume: bool,
    overwrite: bool,
) -> None:
    """``run.go`` without a report folder; with one, check its ``files`` first (before
    the work, not after it), then, holding the folder's lock, with the journal
    (results.jsonl) of the run described by ``header`` (the arguments of
    :func:`~dgli_vision.core.run_lock.run_header_of`)."""
    if not report_dir:
        run.go(None, overwrite=overwrite)
        return
    from ..core.io import guard_outputs
    from ..core.run_lock import run_header_of

    out = Path(report_dir)
    guard_outputs([out / name for name in files], overwrite=overwrite)
    with folder_lock(out):
        journal = open_journal(out / "results.jsonl", run_header_of(**header), resume, overwrite)
        run.go(journal, overwrite=overwrite)
