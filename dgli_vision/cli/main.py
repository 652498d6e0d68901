"""Command line: ``dgli`` (a group of commands). The only module that prints or exits.

Commands are thin adapters: parse, call the library, format. Heavy modules are imported
inside the command that needs them, so that ``dgli --help`` starts fast.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from functools import wraps
from typing import Any, TypeVar

import click

from ..condition_names import CONDITION_HELP
from ..errors import DgliError

F = TypeVar("F", bound=Callable[..., Any])

# Options shared by several commands: one name, one help text, one validation.
intrinsics_option = click.option(
    "--intrinsics",
    type=click.Path(),
    help='Camera intrinsics: Open3D JSON (with optional lens "distortion"), an OpenCV '
    "calibration file or a ROS camera_info YAML (default: intrinsics.json beside COLOR, else "
    "nominal Kinect).",
)
colours_option = click.option(
    "--colours",
    "colours_path",
    type=click.Path(),
    help="Sticker colours measured by 'dgli calibrate' [default: the printed nominal ones].",
)
references_option = click.option(
    "--references",
    "references_path",
    type=click.Path(),
    help="Reference set file [default: references/default.json or $DGLI_REFERENCES].",
)


#: The largest napkin side ``--size`` takes, mm. The simulated cloth is a 5 mm grid, so
#: memory and time grow with the area: a 1000 mm napkin's database (``dgli simulate
#: --per-class 1``) takes about a minute and 1.7 GB.
MAX_NAPKIN_MM = 1000.0


def _parse_size(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[float, float] | None:
    from ..layout import parse_size

    if value is None:
        return None
    try:
        size = parse_size(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None
    if max(size) > MAX_NAPKIN_MM:
        raise click.BadParameter(
            f"napkin size {value!r}: each side is at most {MAX_NAPKIN_MM:g} mm (the stickers "
            "and the simulated cloth are made for napkins, not tablecloths)"
        )
    return size


#: ``--size W[xH]``: the napkin's size in mm (the stickers keep their distances from the
#: corners; fold sizes scale with the cloth).
size_option = click.option(
    "--size",
    "size_mm",
    callback=_parse_size,
    default=None,
    metavar="W[xH]",
    help="Napkin size in mm, e.g. 300 or 500x700 [default: 400]. The stickers keep their "
    "distances from the corners; fold sizes scale with the cloth.",
)


def _napkin_provenance(layout: Any) -> dict[str, Any]:
    """``{"napkin_mm": [W, H]}`` for a napkin of other than the nominal size, else ``{}``
    (so that files of the nominal napkin stay as they were)."""
    return {} if layout.is_nominal else {"napkin_mm": [layout.width_mm, layout.height_mm]}


def per_class_option(default: int, maximum: int, help_text: str) -> Callable[[F], F]:
    """``--per-class N``: how many of each class, 1 to ``maximum``: bounded, so that a
    slip of the keyboard (100000) stops at once with a clear message instead of running
    for hours and out of memory."""
    return click.option(
        "--per-class",
        default=default,
        show_default=True,
        type=click.IntRange(1, maximum),
        help=f"{help_text} (at most {maximum}).",
    )


#: ``-j/--jobs N``: worker processes, all cores by default.
jobs_option = click.option(
    "-j",
    "--jobs",
    type=click.IntRange(1),
    default=None,
    help="Worker processes [default: all cores].",
)


def report_option(help_text: str) -> Callable[[F], F]:
    """``--report DIR``: a folder to write a report into."""
    return click.option("--report", "report_dir", type=click.Path(file_okay=False), help=help_text)


overwrite_option = click.option(
    "--overwrite",
    is_flag=True,
    help="Replace existing files that dgli did not write (never needed for its own output).",
)


def output_option(help_text: str) -> Callable[[F], F]:
    """``-o/--output FILE``: the file a command writes."""
    return click.option("-o", "--output", required=True, type=click.Path(), help=help_text)


def json_option(help_text: str = "Print one JSON object.") -> Callable[[F], F]:
    """``--json``: machine-readable output on stdout."""
    return click.option("--json", "as_json", is_flag=True, help=help_text)


def recording_options(fn: F) -> F:
    """Options for reading a recorded episode (a ROS or RealSense bag)."""
    options = [
        click.option(
            "--color-topic",
            help="A bag's colour image topic [default: found by type "
            "and name, e.g. /camera/color/image_raw].",
        ),
        click.option(
            "--depth-topic",
            help="A bag's depth topic, aligned to colour [default: "
            "e.g. /camera/aligned_depth_to_color/image_raw].",
        ),
        click.option(
            "--info-topic",
            help="A bag's CameraInfo topic [default: the colour camera's camera_info].",
        ),
        click.option(
            "--tolerance",
            "tolerance_ms",
            type=click.FloatRange(0, min_open=True),
            default=20.0,
            show_default=True,
            help="Largest time between a colour image and its depth, in ms.",
        ),
        click.option(
            "--labels",
            "labels_path",
            type=click.Path(),
            help="A bag's labels: CSV with frame (from 0) or time (s from the start), "
            "label and optionally variant.",
        ),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def _open_recording(path: str, opts: dict[str, Any]) -> Any:
    """The recording at ``path`` with the options of :func:`recording_options`."""
    from ..recording import open_recording

    return open_recording(
        path,
        color_topic=opts["color_topic"],
        depth_topic=opts["depth_topic"],
        info_topic=opts["info_topic"],
        tolerance=opts["tolerance_ms"] / 1000.0,
        labels=opts["labels_path"],
    )


def _recording_notes(recording: Any, quiet: bool = False) -> None:
    """A recording's notes on stderr (topics read, distortion, frames without a partner)."""
    if not quiet and recording.kind != "folder":
        for note in recording.notes:
            click.echo(f"{recording.kind}: {note}", err=True)


def _os_error_message(exc: OSError) -> str:
    """One line for an operating-system error that no library function named: the file
    (or standard output) and the reason."""
    from ..io import display_path

    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.filename is not None:
        return f"'{display_path(exc.filename)}': {reason}"
    if _raised_writing_stdout(exc):
        return f"cannot write to standard output: {reason}"
    return reason


def _raised_writing_stdout(exc: BaseException) -> bool:
    """Whether ``exc`` came from ``click.echo`` writing to standard output."""
    tb = exc.__traceback__
    while tb is not None:
        frame = tb.tb_frame
        if frame.f_code.co_name == "echo" and "click" in frame.f_code.co_filename:
            try:
                return frame.f_locals["file"].fileno() == 1
            except (KeyError, AttributeError, OSError, ValueError):
                return False
        tb = tb.tb_next
    return False


def _flush_stdout() -> None:
    """Flush standard output, so that a full disk or closed pipe there is reported."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except OSError as exc:
        from ..errors import OutputError

        raise OutputError(f"cannot write to standard output: {exc.strerror or exc}") from None


def _stdout_failed() -> bool:
    """Whether standard output cannot take what is waiting in its buffer."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except (OSError, ValueError):
        return True
    return False


def _fail(message: str, code: int) -> None:
    """Print ``error: message`` on stderr (if stderr can take it) and exit with ``code``;
    output that standard output could not take is dropped, so that Python does not
    report it again at exit."""
    if _stdout_failed():
        import os

        try:  # point the descriptor at /dev/null: the interpreter's last flush succeeds
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
    try:
        click.echo(f"error: {message}", err=True)
    except (OSError, ValueError):
        pass  # stderr is closed or full too: the exit code is all that is left
    sys.exit(code)


def _handle_errors(fn: F) -> F:
    """Turn every error into one line on stderr and its exit code (never a traceback).

    A :class:`~dgli_vision.errors.DgliError` gives its own message and code; an
    operating-system error that got through (a full disk, a closed or full standard
    output, a name too long) exits 2 naming the file; running out of memory exits 2.
    Standard output is flushed before the command counts as done, so that a full
    ``/dev/full`` or a closed pipe is reported rather than lost. A closed standard output
    (``>&-``) stops the command before any work: it is where the answer goes.
    """

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            if sys.stdout is None:
                from ..errors import OutputError

                raise OutputError("standard output is closed; dgli prints its answer there")
            try:
                result = fn(*args, **kwargs)
            except SystemExit:
                _flush_stdout()
                raise
            _flush_stdout()
            return result
        except DgliError as exc:
            _fail(str(exc), exc.exit_code)
        except OSError as exc:
            _fail(_os_error_message(exc), 2)
        except MemoryError:
            _fail("out of memory", 2)

    return wrapper  # type: ignore[return-value]


def _guarded(run: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Run click's ``main`` with an operating-system error outside any command (help or
    a usage error written to a full or closed stream) as one line, exit 2."""
    try:
        return run(*args, **kwargs)
    except OSError as exc:
        _fail(_os_error_message(exc), 2)


class _Group(click.Group):
    """The ``dgli`` group: :func:`_guarded` around click's own output too."""

    def main(self, *args: Any, **kwargs: Any) -> Any:
        return _guarded(super().main, *args, **kwargs)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="dgli_vision")
def main() -> None:
    """dgli_vision: classify the state of a marked napkin with dGLI cloth coordinates."""


def _command_line() -> str:
    """The current command, rebuilt from its parsed parameters, for provenance records."""
    import shlex

    ctx = click.get_current_context()
    sub = ctx.command_path.split(" ", 1)
    words = ["dgli", *sub[1:]] if ctx.parent is not None else [ctx.command_path]
    for param in ctx.command.params:
        value = ctx.params.get(param.name)
        if isinstance(param, click.Argument):
            words.append(shlex.quote(str(value)))
        elif (
            value is not None
            and value is not False
            and value != ()
            and (
                value != param.default
                or ctx.get_parameter_source(param.name) == click.core.ParameterSource.COMMANDLINE
            )
        ):
            flag = max(param.opts, key=len)
            words.append(flag if value is True else f"{flag} {shlex.quote(str(value))}")
    return " ".join(words)


def _package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dgli_vision")
    except PackageNotFoundError:  # pragma: no cover - running from a bare checkout
        return "unknown"


def _pair_key(pair: Any) -> tuple[str, str]:
    import os

    # realpath, not Path.resolve: a symbolic link loop is the pair's read error, not a crash
    return os.path.realpath(pair.color), os.path.realpath(pair.depth)


def _outcomes_of(items: list, pairs: list | None) -> dict[tuple[str, str], Any]:
    """Outcomes of ``pairs`` (None: any) among the objects of a results.jsonl (others
    left out), by pair."""
    from ..evaluate import outcome_from_dict

    wanted = None if pairs is None else {_pair_key(p) for p in pairs}
    done = {}
    for item in items:
        try:
            outcome = outcome_from_dict(item)
        except (KeyError, TypeError, ValueError):
            continue
        if wanted is None or _pair_key(outcome.pair) in wanted:
            done[_pair_key(outcome.pair)] = outcome
    return done


def _progress_bar(length: int, label: str, *, quiet: bool = False):
    """A progress bar on a terminal; an object that ignores updates otherwise."""
    if sys.stderr.isatty() and not quiet:
        return click.progressbar(length=length, label=label, file=sys.stderr)
    from contextlib import nullcontext

    class _Silent:
        def update(self, n: int) -> None:
            pass

    return nullcontext(_Silent())


def _progress(items: list, label: str):
    """A progress bar on a terminal; the plain iterable otherwise."""
    if sys.stderr.isatty():
        return click.progressbar(items, label=label, file=sys.stderr)
    from contextlib import nullcontext

    return nullcontext(items)


#: The most cloth ``dgli simulate`` holds, counted in states of the nominal 400 mm napkin
#: (a state of a larger napkin counts by its area): about 3 GB.
MAX_SIMULATED_CLOTH = 10_000


def _check_simulation_size(per_class: int, in_progress: int, layout: Any) -> None:
    """Refuse, before the work, a database that would not fit in memory."""
    from ..classes import CLASS_IDS
    from ..database import FOLD_BINS_DEG
    from ..fold_graph import fold_edges

    folds = sum("under" not in fold for *_, fold in fold_edges())
    n_states = per_class * len(CLASS_IDS) + in_progress * folds * len(FOLD_BINS_DEG)
    area = layout.width_mm * layout.height_mm / 400.0**2
    if n_states * area > MAX_SIMULATED_CLOTH:
        raise click.BadParameter(
            f"{n_states} states of a {layout.width_mm:g} x {layout.height_mm:g} mm napkin "
            f"hold as much cloth as {n_states * area:.0f} of the 400 mm one; at most "
            f"{MAX_SIMULATED_CLOTH} fit in memory: lower --per-class or --in-progress",
            param_hint="'--per-class'",
        )


@main.command()
@click.argument("out", type=click.Path(file_okay=False))
@per_class_option(20, 200, "States per class")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the database.")
@click.option("--no-wrinkles", is_flag=True, help="Fold cleanly, without wrinkles.")
@click.option(
    "--in-progress",
    default=3,
    show_default=True,
    type=click.IntRange(0, 20),
    help="States with a fold in progress, per fold and angle bin (0: none; at most 20).",
)
@size_option
@overwrite_option
@_handle_errors
def simulate(
    out: str,
    per_class: int,
    seed: int,
    no_wrinkles: bool,
    in_progress: int,
    size_mm: tuple[float, float] | None,
    overwrite: bool,
) -> None:
    """Write a simulated database of cloth states to OUT (meshes, truth, index).

    Besides PER-CLASS states of every class with its folds laid flat, the database holds
    states with one fold in progress (every fold a robot can make, turned 10-170
    degrees), labelled by the 90-degree rule; `dgli compare` leaves them out.
    """
    from ..cloth.states import CLASS_IDS
    from ..database import simulate_folds_in_progress, simulate_states
    from ..database_files import write_database
    from ..layout import layout_of_size

    layout = layout_of_size(size_mm)
    _check_simulation_size(per_class, in_progress, layout)
    kw = {"wrinkles": not no_wrinkles, "layout": layout}
    states = []
    with _progress(list(CLASS_IDS), "simulating") as classes:
        for class_id in classes:
            states += simulate_states(per_class, seed, classes=(class_id,), **kw)
    if in_progress:
        states += simulate_folds_in_progress(in_progress, seed, **kw)
    provenance = {
        "command": _command_line(),
        "seed": seed,
        "per_class": per_class,
        "in_progress": in_progress,
        "wrinkles": not no_wrinkles,
        **_napkin_provenance(layout),
        "package_version": _package_version(),
    }
    index = write_database(out, states, provenance, overwrite=overwrite)
    click.echo(f"wrote {len(states)} states to {index}")


@main.command()
@click.argument("folder", type=click.Path())
@report_option("Write a report here.")
@json_option("Print the summary as JSON.")
@jobs_option
@references_option
@colours_option
@recording_options
@click.option(
    "--lenient",
    is_flag=True,
    help="Skip (and list) label rows with an unknown class or variant, or repeated, "
    "instead of stopping.",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted run: keep the pairs already in the report folder's "
    "results.jsonl and classify the rest (refused when the run differs: references, "
    "labels, colours, intrinsics, options).",
)
@overwrite_option
@_handle_errors
def evaluate(
    folder: str,
    report_dir: str | None,
    as_json: bool,
    jobs: int | None,
    references_path: str | None,
    colours_path: str | None,
    lenient: bool,
    resume: bool,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """Classify every labelled pair of FOLDER and report accuracy and confusions.

    FOLDER may also be a recorded episode (a ROS or RealSense bag) with --labels.

    Labels are checked first: an unknown class or variant, or a pair listed twice,
    stops the run (exit 2) unless --lenient; pairs that cannot be read are listed with
    their error and the run goes on. With --report, each pair's result is appended to
    results.jsonl as it is done; Ctrl-C or SIGTERM writes the report of what is done and
    exits 130 (143), and --resume goes on from there, giving the same report as an
    uninterrupted run. Exit 1 when no pair could be classified, 2 when none could be read.
    """
    from pathlib import Path

    from ..colours_file import read_colours
    from ..errors import InvalidInputError
    from ..evaluation_report import REPORT_FILES
    from ..io import guard_outputs
    from ..labelled import find_labelled_pairs
    from ..recording import is_recording_file
    from ..references import default_references_path, load_references

    recording = None
    if is_recording_file(folder):
        if not recording_opts["labels_path"]:
            raise InvalidInputError(
                f"recording '{folder}' needs --labels FILE to be evaluated (CSV: frame or "
                "time, label, variant); 'dgli track' reads it without labels"
            )
        recording = _open_recording(folder, recording_opts)
        pairs, problems = [], []
    else:
        pairs, problems = find_labelled_pairs(folder, lenient=lenient)
    for problem in problems:
        if problem.kind != "missing file":  # those are listed with the failures
            click.echo(f"skipped: {problem.message}", err=True)
    if resume and not report_dir:
        raise InvalidInputError("--resume needs --report DIR, where results.jsonl is kept")
    refs_path = Path(references_path) if references_path else default_references_path()
    refs = load_references(refs_path)
    if colours_path:
        read_colours(colours_path)  # a bad file stops the run before any work
    run = _EvaluationRun(
        folder,
        report_dir,
        pairs,
        problems,
        recording,
        refs,
        refs_path,
        colours_path,
        jobs,
        as_json,
    )
    if not report_dir:
        run.go(None, overwrite=overwrite)
        return
    out = Path(report_dir)  # fail before the work, not after it
    guard_outputs([out / name for name in REPORT_FILES], overwrite=overwrite)
    with _run_lock(out):
        header = _run_header(
            "evaluate",
            folder,
            None if recording else pairs,
            labels_path=recording_opts["labels_path"],
            refs_path=refs_path,
            colours_path=colours_path,
            options={"lenient": lenient, **recording_opts},
        )
        journal = _open_journal(out / "results.jsonl", header, resume, overwrite)
        run.go(journal, overwrite=overwrite)


def _run_header(
    kind: str,
    folder: str,
    pairs: Any,
    *,
    labels_path: str | None,
    refs_path: Any,
    colours_path: str | None,
    options: dict[str, Any],
) -> dict[str, Any]:
    """What defines a run of ``kind`` on ``folder``, for its results.jsonl (see
    :mod:`dgli_vision.run_lock`): the input (a folder by path, its pairs by their list,
    labels and intrinsics files by checksum; a recording file by path, size and time),
    the references and colours by checksum, and the options that change results.

    ``pairs`` are the folder's pairs, None for a recording file."""
    import os
    from pathlib import Path

    from ..run_lock import file_digest, intrinsics_digest, listing_digest, run_header

    root = Path(folder).resolve()
    if pairs is None:
        stat = root.stat()  # a recording is known by its size and time, not read twice
        source = listing_digest([(str(root), stat.st_size, stat.st_mtime_ns)])
        listing, intrinsics = None, None
    else:
        source = str(root)
        listing = listing_digest(
            (os.path.relpath(p.color, root), os.path.relpath(p.depth, root)) for p in pairs
        )
        intrinsics = intrinsics_digest(p.color for p in pairs)
    labels = file_digest(labels_path) if labels_path else file_digest(root / "labels.csv")
    if labels is None and pairs is not None:  # class folders
        labels = listing_digest((p.label, p.variant) for p in pairs)
    fields = {
        "input": source,
        "pairs": listing,
        "labels": labels,
        "references": file_digest(refs_path),
        "colours": file_digest(colours_path),
        "intrinsics": intrinsics,
        "options": {k: v for k, v in sorted(options.items()) if k != "labels_path"},
    }
    return run_header(kind, fields)


#: How each stop signal ends a command: 128 + its number, as a shell reports it.
STOP_EXIT_CODES = {2: 130, 15: 143}  # SIGINT, SIGTERM


class _Stop:
    """Whether a stop signal came, and which (Ctrl-C unless SIGTERM came)."""

    stopped = False
    signum = 2

    @property
    def exit_code(self) -> int:
        return STOP_EXIT_CODES.get(self.signum, 128 + self.signum)


def _stop_signals():
    """A context in which SIGTERM stops the work as Ctrl-C does (a KeyboardInterrupt),
    yielding a :class:`_Stop` that says which of the two came."""
    import signal
    import threading
    from contextlib import contextmanager

    @contextmanager
    def context():
        stop = _Stop()

        def on_term(signum: int, frame: Any) -> None:
            stop.signum, stop.stopped = signum, True
            raise KeyboardInterrupt

        if threading.current_thread() is not threading.main_thread():
            yield stop
            return
        before = signal.signal(signal.SIGTERM, on_term)
        try:
            yield stop
        finally:
            signal.signal(signal.SIGTERM, before)

    return context()


def _run_lock(folder: Any):
    """The lock of an output folder (:class:`~dgli_vision.run_lock.RunLock`), held for
    the ``with`` block; a stale lock left by a killed run is taken over with a note."""
    from contextlib import contextmanager

    from ..run_lock import RunLock

    @contextmanager
    def context():
        lock = RunLock(folder, _command_line())
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


def _open_journal(path: Any, header: dict[str, Any], resume: bool, overwrite: bool):
    """The writer of a run's results.jsonl and the objects already in it: with
    ``resume``, those of the same run (refused, naming the difference, when its header
    differs from ``header``); otherwise a new file starting with ``header`` (refused when
    an earlier run's results are there, unless ``overwrite``)."""
    from ..errors import OverwriteError
    from ..io import JsonLinesWriter, read_jsonl
    from ..run_lock import check_resume, repair_journal

    earlier = read_jsonl(path) if resume else []
    if earlier:
        check_resume(path, earlier[0], header)
        repair_journal(path)
        return JsonLinesWriter(path, append=True), earlier[1:]
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


def _classify_into(
    todo: Any,
    count: int,
    label: str,
    run: Any,
    writer: Any,
    done: dict,
    stop: Any,
    **options: Any,
) -> None:
    """Classify the pairs of ``todo`` (``count`` of them) on ``run.jobs`` workers with
    ``run.refs`` and a progress bar, each outcome into ``done`` by its pair and, at once,
    into ``writer`` (results.jsonl): a run stopped by Ctrl-C or SIGTERM (``stop``) keeps
    what is done. ``options`` go to ``evaluate_pairs``."""
    from concurrent.futures.process import BrokenProcessPool

    from ..evaluate import evaluate_pairs, outcome_to_dict

    try:
        with _progress_bar(count, label, quiet=run.as_json) as bar:
            for outcome in evaluate_pairs(
                todo, run.refs, jobs=run.jobs, on_progress=bar.update, **options
            ):
                if writer:  # flushed at once: an interrupted run keeps its work
                    writer.write(outcome_to_dict(outcome))
                done[_pair_key(outcome.pair)] = outcome
    except KeyboardInterrupt:
        stop.stopped = True
    except BrokenProcessPool:  # a stop sent to the whole group ended the workers
        if not stop.stopped:
            raise


class _EvaluationRun:
    """``dgli evaluate`` once its inputs are known: classify, print, report."""

    def __init__(
        self,
        folder: str,
        report_dir: str | None,
        pairs: list,
        problems: list,
        recording: Any,
        refs: Any,
        refs_path: Any,
        colours_path: str | None,
        jobs: int | None,
        as_json: bool,
    ) -> None:
        import os

        self.folder, self.report_dir = folder, report_dir
        self.pairs, self.problems, self.recording = pairs, problems, recording
        self.refs, self.refs_path, self.colours_path = refs, refs_path, colours_path
        self.jobs = jobs or os.cpu_count() or 1
        self.as_json = as_json

    def go(self, journal: tuple[Any, list] | None, *, overwrite: bool) -> None:
        """Classify what is not done yet (``journal``: the results.jsonl writer and the
        objects already in it), print, write the report, exit as the outcome says."""
        import time

        from ..evaluate import summarise

        writer, earlier = journal if journal else (None, [])
        done = _outcomes_of(earlier, None if self.recording else self.pairs)
        t0 = time.perf_counter()
        with _stop_signals() as stop:
            try:
                self._classify(done, writer, stop)
            finally:
                if writer:
                    writer.close()
        outcomes = [done[_pair_key(p)] for p in self.pairs if _pair_key(p) in done]
        result = summarise(outcomes, time.perf_counter() - t0)
        skipped = [p.message for p in self.problems if p.kind != "missing file"]
        if self.recording:
            _recording_notes(self.recording, quiet=self.as_json)
            skipped += [f"{name}: no label" for name in self.unlabelled]
        self._print(result, skipped)
        if self.report_dir:
            self._report(result, skipped, overwrite)
        if stop.stopped:
            click.echo(
                f"interrupted: {len(outcomes)} of {len(self.pairs)} pairs done"
                + ("; go on with the same command and --resume" if self.report_dir else ""),
                err=True,
            )
            sys.exit(stop.exit_code)
        if result.n and not result.classified:
            if all(o.error for o in outcomes):
                click.echo(f"error: none of the {result.n} pairs could be read", err=True)
                sys.exit(2)
            click.echo(f"error: none of the {result.n} pairs could be classified", err=True)
            sys.exit(1)

    def _classify(self, done: dict, writer: Any, stop: _Stop) -> None:
        """Classify the pairs not in ``done`` into it (and ``writer``), until all are or
        a stop signal comes (:func:`_stop_signals`)."""

        from ..colours_file import read_colours

        recording, pairs = self.recording, self.pairs
        colours = read_colours(self.colours_path) if self.colours_path else None
        self.unlabelled: list[str] = []

        def todo() -> Iterator[Any]:  # a recording's frames are read as they are classified
            for pair in recording.frames if recording else pairs:
                if recording and not pair.label:
                    self.unlabelled.append(pair.color)
                    continue
                if recording:
                    pairs.append(pair.light())
                if _pair_key(pair) not in done:
                    yield pair

        count = recording.count if recording else sum(_pair_key(p) not in done for p in pairs)
        if count:
            _classify_into(
                todo(), count, "classifying", self, writer, done, stop, colours=colours
            )

    def _print(self, result: Any, skipped: list[str]) -> None:
        from ..evaluate import json_ready

        if self.as_json:
            click.echo(json.dumps(json_ready({**result.to_dict(), "skipped": skipped})))
            return
        from ..report import markdown_table

        click.echo(
            f"{result.n} pairs, {result.classified} classified, "
            f"{len(result.failures)} failed or unclassified"
        )
        click.echo(
            f"class accuracy {result.accuracy:.2%}, "
            f"variant accuracy {result.variant_accuracy_text()}, "
            f"{result.seconds:.1f} s with {self.jobs} worker(s)"
        )
        click.echo(
            markdown_table(
                ["true \\ predicted", *result.labels, "none"],
                [[lab, *row] for lab, row in zip(result.labels, result.confusion)],
            ),
            nl=False,
        )
        for f in result.failures:
            click.echo(f"failed: {f['color']}: {f['error']}")

    def _report(self, result: Any, skipped: list[str], overwrite: bool) -> None:
        from pathlib import Path

        from ..evaluate import json_ready
        from ..evaluation_report import build_report
        from ..frames import read_color
        from ..io import file_sha256, record_outputs, write_outputs

        meta = {
            "command": _command_line(),
            "folder": self.folder,
            "references": str(self.refs_path),
            "references_sha256": file_sha256(self.refs_path),
            "package_version": _package_version(),
            "jobs": self.jobs,
            "skipped": skipped,
        }
        out = Path(self.report_dir)
        files = build_report(result, meta, read_color)
        write_outputs(
            {out / name: json_ready(c) if isinstance(c, dict) else c for name, c in files.items()},
            overwrite=overwrite,
            command=meta["command"],
        )
        record_outputs([out / "results.jsonl"], meta["command"])
        click.echo(f"report written to {out / 'report.md'}", err=True)


def _parse_conditions(ctx: click.Context, param: click.Parameter, value: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in value.split(",") if n.strip())
    unknown = [n for n in names if n not in CONDITION_HELP and n != "clean"]
    if unknown:
        raise click.BadParameter(
            f"unknown condition {unknown[0]!r}; expected some of {', '.join(CONDITION_HELP)}"
        )
    return names


@main.command("render")
@click.argument("out", type=click.Path(file_okay=False))
@per_class_option(1, 50, "Pairs per class")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the whole set.")
@click.option(
    "--clean", is_flag=True, help="Switch the sensor model off (no noise, blur, dropouts)."
)
@click.option(
    "--nominal", is_flag=True, help="Nominal scene: straight down from 520 mm, default lighting."
)
@click.option(
    "--conditions",
    "conditions",
    callback=_parse_conditions,
    default="",
    help="Capture conditions, comma-separated: "
    + ", ".join(f"{k} ({v})" for k, v in CONDITION_HELP.items())
    + ".",
)
@click.option(
    "--sequence",
    type=click.Choice(["I", "II", "III"]),
    default=None,
    help="Render this folding sequence as one recording instead (frames in order, "
    "frames.csv, labels by the 90-degree rule).",
)
@click.option(
    "--frames",
    default=25,
    show_default=True,
    type=click.IntRange(2),
    help="Frames of --sequence, spread evenly over its folds.",
)
@click.option(
    "--gripper",
    is_flag=True,
    help="A robot's gripper holds the corner being folded in every frame of --sequence "
    "(without --sequence: the condition grasp).",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted render of the same set into OUT: keep its complete "
    "pairs and render the rest (refused when the set differs).",
)
@size_option
@overwrite_option
@_handle_errors
def render_cmd(
    out: str,
    per_class: int,
    seed: int,
    clean: bool,
    nominal: bool,
    conditions: tuple[str, ...],
    sequence: str | None,
    frames: int,
    gripper: bool,
    resume: bool,
    size_mm: tuple[float, float] | None,
    overwrite: bool,
) -> None:
    """Render a labelled RGB-D folder of simulated states to OUT (the labelled-folder
    format of docs/napkin.md).

    With --sequence, a folding sequence as the frames of one recording, for `dgli track`.
    Ctrl-C or SIGTERM writes the pairs rendered so far with their labels.csv and exits
    130 (143); --resume renders the rest.
    """
    if gripper and "grasp" not in conditions:
        conditions = (*conditions, "grasp")
    from ..cloth.states import CLASS_IDS
    from ..dataset import sample_name
    from ..io import guard_outputs
    from ..labelled import labelled_folder_files
    from ..layout import layout_of_size

    cases = [] if sequence else [(c, k) for c in CLASS_IDS for k in range(per_class)]
    if sequence:
        names = [f"{sequence}_{k:03d}" for k in range(frames)]
    else:
        names = [sample_name(c, k) for c, k in cases]
    planned = labelled_folder_files(out, names, frames=bool(sequence))
    guard_outputs(planned, overwrite=overwrite)  # before the work

    layout = layout_of_size(size_mm)
    provenance = {
        "command": _command_line(),
        "seed": seed,
        **({"sequence": sequence, "frames": frames} if sequence else {"per_class": per_class}),
        "clean": clean,
        "nominal": nominal,
        **({"conditions": list(conditions)} if conditions else {}),
        **_napkin_provenance(layout),
        "package_version": _package_version(),
    }
    options = {"nominal": nominal, "clean": clean, "conditions": conditions, "layout": layout}
    with _run_lock(out):
        _render_set(out, names, cases, provenance, options, resume=resume, overwrite=overwrite)


def _render_set(
    out: str,
    names: list[str],
    cases: list[tuple[str, int]],
    provenance: dict[str, Any],
    options: dict[str, Any],
    *,
    resume: bool,
    overwrite: bool,
) -> None:
    """Render the pairs of ``names`` (of a sequence, or ``cases``: class and number) not
    kept from an interrupted run (``resume``), write them (all, or those done when a stop
    signal came), and exit 130/143 if stopped."""
    from ..dataset import (
        SEQUENCE_FRAME_SECONDS,
        kept_pairs,
        merge_kept_pairs,
        render_sample,
        render_sequence,
    )
    from ..labelled import write_labelled_folder

    sequence, seed = provenance.get("sequence"), provenance["seed"]
    kept = kept_pairs(out, provenance, names) if resume else {}
    todo = [k for k, n in enumerate(names) if n not in kept]
    if kept:
        click.echo(f"resuming: {len(kept)} of {len(names)} pairs kept", err=True)
    if sequence:
        stream = render_sequence(
            sequence,
            len(names),
            seed,
            skip={k for k, n in enumerate(names) if n in kept},
            **options,
        )
    else:
        stream = (render_sample(*cases[k], seed, **options) for k in todo)
    samples = []
    with _stop_signals() as stop:
        try:
            with _progress(todo, "rendering") as bar:
                for sample, _ in zip(stream, bar):
                    samples.append(sample)
        except KeyboardInterrupt:
            stop.stopped = True
    index = {n: k for k, n in enumerate(names)}
    times = [index[s.name] * SEQUENCE_FRAME_SECONDS for s in samples] if sequence else None
    labels = f"{out}/labels.csv"
    if samples:
        labels = write_labelled_folder(out, samples, provenance, overwrite=overwrite, times=times)
    if kept:
        merge_kept_pairs(out, kept, names, frames=bool(sequence), command=provenance["command"])
    done = len(samples) + len(kept)
    if stop.stopped:
        click.echo(
            f"interrupted: {done} of {len(names)} pairs written to {out}"
            + (f" (labels: {labels}); go on with the same command and --resume" if done else ""),
            err=True,
        )
        sys.exit(stop.exit_code)
    click.echo(f"wrote {done} pairs to {out} (labels: {labels})")


@main.group()
def references() -> None:
    """Build the reference set the classifier matches against."""


@references.command("build")
@click.argument("db", type=click.Path())
@output_option("Reference file to write.")
@size_option
@overwrite_option
@_handle_errors
def references_build(
    db: str, output: str, size_mm: tuple[float, float] | None, overwrite: bool
) -> None:
    """Pick one representative per class and variant from the simulated database DB.

    The set is for the napkin size DB was simulated for; --size only checks it.
    """
    from ..database_files import read_database
    from ..errors import InvalidInputError
    from ..layout import layout_of_size
    from ..references import build_references, write_references

    records, db_provenance = read_database(db)
    simulated = db_provenance.get("napkin_mm")
    have = layout_of_size(None if simulated is None else tuple(simulated))
    if size_mm is not None and (have.width_mm, have.height_mm) != size_mm:
        raise InvalidInputError(
            f"'{db}' was simulated for a {have.width_mm:g} x {have.height_mm:g} mm napkin, "
            f"not {size_mm[0]:g} x {size_mm[1]:g}: run `dgli simulate --size "
            f"{size_mm[0]:g}x{size_mm[1]:g}` first"
        )
    provenance = {
        "command": _command_line(),
        **_napkin_provenance(have),
        "database": db_provenance,
        "n_states": len(records),
        "package_version": _package_version(),
        "method": "per (class, variant): the state nearest (Spearman) to the group centroid",
    }
    refs = build_references(records, provenance=provenance)
    write_references(output, refs, overwrite=overwrite)
    click.echo(f"wrote {len(refs)} references from {len(records)} states to {output}")


def _sequence_records(name: str):
    from ..cloth.sequences import folding_sequence
    from ..database import records_from_states

    frames = folding_sequence(name)
    return records_from_states([(f"{name}_{k:03d}", s) for k, s in enumerate(frames)])


@main.command()
@click.argument("db", type=click.Path())
@report_option("Write the table and heatmaps here.")
@json_option("Print the table as JSON.")
@overwrite_option
@_handle_errors
def compare(db: str, report_dir: str | None, as_json: bool, overwrite: bool) -> None:
    """Davies-Bouldin index of dGLI and the baselines on DB and the three sequences.

    Columns: the database labelled by class, the three folding sequences labelled by
    their frames' true class, the database labelled by class and variant, and by class
    and variant with mirror images merged (the grouping comparable to the paper's
    corner-specific classes; see the report).
    """
    import dataclasses
    from pathlib import Path

    import numpy as np

    from ..compare import COMPARE_COLUMN_NOTES, davies_bouldin_table, distance_matrices
    from ..database_files import read_database
    from ..fold_graph import mirror_group
    from ..io import guard_outputs, write_outputs
    from ..report import csv_table, heatmap_image, markdown_table

    if report_dir:  # fail before the work, not after it
        guard_outputs([Path(report_dir) / "table.json"], overwrite=overwrite)
    records, _ = read_database(db)
    records = records.subset(records.folded)  # the paper's states: every fold laid flat
    keys = [f"{c}/{v or ''}" for c, v in zip(records.classes, records.variants)]
    order = np.argsort(np.asarray(keys), kind="stable")  # by class, then variant
    records = records.subset(order)
    by_variant = dataclasses.replace(
        records, classes=tuple(f"{c}/{v}" for c, v in zip(records.classes, records.variants))
    )
    mirrored = dataclasses.replace(
        records,
        classes=tuple(mirror_group(k) for k in zip(records.classes, records.variants)),
    )
    datasets = {
        "database": records,
        **{n: _sequence_records(n) for n in ("I", "II", "III")},
        "database by variant": by_variant,
        "by variant, mirrors merged": mirrored,
    }
    table = davies_bouldin_table(datasets)
    table["column_notes"] = COMPARE_COLUMN_NOTES
    columns = table["columns"]
    rows = [[name, *vals] for name, vals in table["rows"].items()]
    notes = "\n".join(f"- **{k}**: {v}" for k, v in COMPARE_COLUMN_NOTES.items())
    if as_json:
        click.echo(json.dumps(table))
    else:
        click.echo("Davies-Bouldin index (lower is better)")
        click.echo(markdown_table(["representation", *columns], rows), nl=False)
        click.echo("columns: " + "; ".join(f"{k}: {v}" for k, v in COMPARE_COLUMN_NOTES.items()))
    if report_dir:
        out = Path(report_dir)
        files: dict[Path, Any] = {
            out / "table.json": table,
            out / "table.md": "# Davies-Bouldin index (lower is better)\n\n"
            + markdown_table(["representation", *columns], rows)
            + "\n## What each column groups\n\n"
            + notes
            + "\n",
            out / "table.csv": csv_table(["representation", *columns], rows),
        }
        for name, mat in distance_matrices(records).items():
            files[out / f"distances_{name}.png"] = heatmap_image(
                mat,
                title=f"{name}: distances, samples by class",
                groups=records.classes,
                value_label="distance",
            )
        write_outputs(files, overwrite=overwrite, command=_command_line())
        click.echo(f"report written to {out}", err=True)


@main.command()
@click.argument("name", type=click.Choice(["I", "II", "III"]))
@references_option
@report_option("Write the heatmap and frames here.")
@json_option("Print a JSON object.")
@overwrite_option
@_handle_errors
def sequence(
    name: str,
    references_path: str | None,
    report_dir: str | None,
    as_json: bool,
    overwrite: bool,
) -> None:
    """Folding sequence NAME: frame distance matrix and detected state changes.

    The simulator's frames of the sequence, each compared with the references as a
    camera above would see it, then smoothed over time as `dgli track` does.
    """
    from pathlib import Path

    from ..cloth.sequences import SEQUENCES
    from ..compare import analyse_sequence
    from ..io import guard_outputs, write_outputs
    from ..references import load_references
    from ..report import heatmap_image

    if report_dir:  # fail before the work, not after it
        guard_outputs([Path(report_dir) / f"sequence_{name}.json"], overwrite=overwrite)
    refs = load_references(references_path)
    records = _sequence_records(name)
    result = analyse_sequence(records, refs)
    summary = {
        "sequence": name,
        "description": SEQUENCES[name][0],
        "frames": len(records),
        "truth": list(result.truth),
        "predicted": list(result.predicted),
        "smoothed": list(result.smoothed),
        "true_changes": list(result.true_changes),
        "detected_changes": list(result.detected_changes),
        "frame_accuracy": round(result.frame_accuracy, 4),
        "smoothed_accuracy": round(result.smoothed_accuracy, 4),
    }
    if as_json:
        click.echo(json.dumps(summary))
    else:
        click.echo(f"sequence {name}: {SEQUENCES[name][0]} ({len(records)} frames)")
        click.echo(f"  truth:     {' '.join(result.truth)}")
        click.echo(f"  per frame: {' '.join(result.predicted)}")
        click.echo(f"  smoothed:  {' '.join(result.smoothed)}")
        click.echo(
            f"  state changes: true at frames {list(result.true_changes)}, "
            f"detected at {list(result.detected_changes)}; frame accuracy "
            f"{result.frame_accuracy:.0%} per frame, {result.smoothed_accuracy:.0%} smoothed"
        )
    if report_dir:
        out = Path(report_dir)
        img = heatmap_image(
            result.distances,
            title=f"sequence {name}: Spearman distance of dGLI",
            groups=result.truth,
            value_label="1 - rho",
        )
        write_outputs(
            {out / f"sequence_{name}.json": summary, out / f"sequence_{name}.png": img},
            overwrite=overwrite,
            command=_command_line(),
        )


@main.command()
@click.argument("folder", metavar="RECORDING", type=click.Path())
@report_option(
    "Write the timeline (CSV, JSON, picture), the frame distance heatmap and each "
    "frame's result (results.jsonl, as it is done) here."
)
@json_option("Print the timeline as JSON.")
@jobs_option
@references_option
@colours_option
@recording_options
@click.option(
    "--resume",
    is_flag=True,
    help="Go on with an interrupted run: keep the frames already in the report folder's "
    "results.jsonl and classify the rest (refused when the run differs).",
)
@overwrite_option
@_handle_errors
def track(
    folder: str,
    report_dir: str | None,
    as_json: bool,
    jobs: int | None,
    references_path: str | None,
    colours_path: str | None,
    resume: bool,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """The state timeline of the frames of RECORDING.

    RECORDING is a folder of pairs (in the order of its frames.csv, color,depth[,time],
    or by name), a ROS 1 .bag, a ROS 2 bag (.db3, .mcap or its folder; needs the
    'recordings' extra) or a RealSense SDK .bag. A bag is read as it is classified.
    Each frame is classified, then the states are smoothed over time (a hidden Markov
    model whose moves are single folds and unfolds). A frame that cannot be read is a
    gap, listed; the run goes on. With labels (a folder's labels.csv, a bag's --labels),
    the timeline is scored. Exit 1 when no frame could be classified at all. With
    --report, each frame's result is kept as it is done: Ctrl-C or SIGTERM gives the
    timeline of the frames done and exits 130 (143), and --resume goes on from there.
    """
    from pathlib import Path

    from ..colours_file import read_colours
    from ..errors import InvalidInputError
    from ..io import guard_outputs
    from ..references import default_references_path, load_references

    recording = _open_recording(folder, recording_opts)
    if resume and not report_dir:
        raise InvalidInputError("--resume needs --report DIR, where results.jsonl is kept")
    refs_path = Path(references_path) if references_path else default_references_path()
    refs = load_references(refs_path)
    colours = read_colours(colours_path) if colours_path else None
    run = _TrackRun(folder, report_dir, recording, refs, colours, jobs, as_json)
    if not report_dir:
        run.go(None, overwrite=overwrite)
        return
    out = Path(report_dir)  # fail before the work, not after it
    guard_outputs([out / name for name in TRACK_FILES], overwrite=overwrite)
    with _run_lock(out):
        header = _run_header(
            "track",
            folder,
            recording.frames if recording.kind == "folder" else None,
            labels_path=recording_opts["labels_path"],
            refs_path=refs_path,
            colours_path=colours_path,
            options=recording_opts,
        )
        journal = _open_journal(out / "results.jsonl", header, resume, overwrite)
        run.go(journal, overwrite=overwrite)


#: The files of a ``dgli track`` report (besides its results.jsonl).
TRACK_FILES = ("timeline.json", "timeline.csv", "timeline.png", "distances.png")


class _TrackRun:
    """``dgli track`` once its inputs are known: classify, smooth, print, report."""

    def __init__(
        self,
        folder: str,
        report_dir: str | None,
        recording: Any,
        refs: Any,
        colours: dict | None,
        jobs: int | None,
        as_json: bool,
    ) -> None:
        import os

        self.folder, self.report_dir, self.recording = folder, report_dir, recording
        self.refs, self.colours = refs, colours
        self.jobs = jobs or os.cpu_count() or 1
        self.as_json = as_json

    def go(self, journal: tuple[Any, list] | None, *, overwrite: bool) -> None:
        """Classify the frames not done yet (``journal``: the results.jsonl writer and
        the objects already in it), smooth, print, report, exit as the outcome says."""
        from ..track import track_outcomes

        writer, earlier = journal if journal else (None, [])
        done = _outcomes_of(earlier, None)
        seen: list[Any] = []  # the frames in order, as far as they were read
        with _stop_signals() as stop:
            try:
                self._classify(done, writer, seen, stop)
            finally:
                if writer:
                    writer.close()
        outcomes = [done[k] for k in (_pair_key(p) for p in seen) if k in done]
        _recording_notes(self.recording, quiet=self.as_json)
        labelled = self.recording.labelled and all(o.pair.label for o in outcomes)
        timeline = track_outcomes(
            outcomes, self.refs, times=[o.pair.time for o in outcomes], labelled=labelled
        )
        data = {
            "folder": self.folder,
            "recording": {"kind": self.recording.kind, "notes": list(self.recording.notes)},
            "n_frames": len(outcomes),
            **_timeline_json(timeline),
        }
        if stop.stopped:
            data["interrupted"] = {"frames_done": len(outcomes), "frames": self.recording.count}
        self._print(data, timeline, len(outcomes))
        if self.report_dir:
            self._report(data, timeline, outcomes, labelled, overwrite)
        if stop.stopped:
            click.echo(
                f"interrupted: {len(outcomes)} of {self.recording.count} frames done"
                + ("; go on with the same command and --resume" if self.report_dir else ""),
                err=True,
            )
            sys.exit(stop.exit_code)
        if all(f.gap for f in timeline.frames):
            sys.exit(1)

    def _classify(self, done: dict, writer: Any, seen: list, stop: _Stop) -> None:


        def todo() -> Iterator[Any]:  # a bag's frames are read as they are classified
            for pair in self.recording.frames:
                seen.append(pair.light())
                if _pair_key(pair) not in done:
                    yield pair

        _classify_into(
            todo(), self.recording.count, "tracking", self, writer, done, stop,
            colours=self.colours, distances=True,
        )

    def _print(self, data: dict[str, Any], timeline: Any, n: int) -> None:
        from ..classes import CLASS_NAMES

        if self.as_json:
            click.echo(json.dumps(data))
            return

        def state(key: tuple[str, str | None]) -> str:
            return f"{key[0]} {CLASS_NAMES[key[0]]}" + (f" {key[1]}" if key[1] else "")

        first = next((f for f in timeline.frames if not f.gap), None)
        click.echo(
            f"{n} frames; "
            + (
                f"starts as {state((first.smoothed_class, first.smoothed_variant))}"
                if first
                else "no frame could be classified"
            )
        )
        for t, a, b in timeline.changes:
            click.echo(f"  frame {t}: {state(a)} -> {state(b)}")
        for f in timeline.frames:
            if f.gap:
                click.echo(f"gap: frame {f.index} ({f.color}): {f.note}")
        sc = timeline.score
        if sc is not None:
            click.echo(
                f"frame accuracy {sc.raw_accuracy:.0%} raw, {sc.smoothed_accuracy:.0%} "
                f"smoothed; state changes true {list(sc.true_changes)}, found "
                f"{list(sc.found_changes)} (precision {sc.precision:.2f}, recall "
                f"{sc.recall:.2f}, within 2 frames)"
            )

    def _report(
        self,
        data: dict[str, Any],
        timeline: Any,
        outcomes: list,
        labelled: bool,
        overwrite: bool,
    ) -> None:
        from pathlib import Path

        from ..classes import CLASS_IDS, CLASS_NAMES
        from ..evaluate import coordinate_matrix
        from ..evaluation_report import heatmap_sample, sample_distance_matrix
        from ..io import record_outputs, write_outputs
        from ..report import csv_table, heatmap_image, timeline_image
        from ..track import TIMELINE_COLUMNS, timeline_rows

        out = Path(self.report_dir)
        picture = timeline_image(
            CLASS_IDS,
            [f.smoothed_class for f in timeline.frames],
            [f.raw_class for f in timeline.frames],
            truth=[f.label or "" for f in timeline.frames] if labelled else None,
            names=CLASS_NAMES,
            title=f"timeline of {self.folder}",
        )
        shown = heatmap_sample(["frames"] * len(outcomes))  # evenly spread in time
        files: dict[Any, Any] = {
            out / "timeline.json": {"command": _command_line(), **data},
            out / "timeline.csv": csv_table(TIMELINE_COLUMNS, timeline_rows(timeline)),
            out / "timeline.png": picture,
        }
        if shown:
            files[out / "distances.png"] = heatmap_image(
                sample_distance_matrix(coordinate_matrix([outcomes[k] for k in shown])),
                title="frames: Spearman distance of dGLI"
                + (
                    ""
                    if len(shown) == len(outcomes)
                    else f" ({len(shown)} of {len(outcomes)} frames, evenly spread)"
                ),
                value_label="1 - rho",
            )
            files[out / "timeline.json"]["distances_png"] = {
                "frames_shown": len(shown),
                "frames": len(outcomes),
            }
        write_outputs(files, overwrite=overwrite, command=_command_line())
        record_outputs([out / "results.jsonl"], _command_line())
        click.echo(f"report written to {out}", err=True)


def _timeline_json(timeline: Any) -> dict[str, Any]:
    """A timeline's JSON object with NaN written as null."""
    from ..evaluate import json_ready
    from ..track import timeline_to_dict

    return json_ready(timeline_to_dict(timeline))


def _finite_seconds(
    ctx: click.Context, param: click.Parameter, value: float | None
) -> float | None:
    """A time in seconds from the start of a recording: a number, not NaN or infinite."""
    import math

    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"{value} is not a time in seconds; expected a number")
    return value


@main.command()
@click.argument("recording_path", metavar="RECORDING", type=click.Path())
@click.argument("out", type=click.Path(file_okay=False))
@click.option(
    "--every", default=1, show_default=True, type=click.IntRange(1), help="Keep every N-th frame."
)
@click.option(
    "--start",
    type=float,
    default=None,
    callback=_finite_seconds,
    help="First second to keep, from the start of the recording.",
)
@click.option(
    "--end",
    type=float,
    default=None,
    callback=_finite_seconds,
    help="Last second to keep, from the start of the recording.",
)
@recording_options
@overwrite_option
@_handle_errors
def extract(
    recording_path: str,
    out: str,
    every: int,
    start: float | None,
    end: float | None,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """Write the frames of RECORDING (a ROS or RealSense bag) to OUT as PNG pairs.

    OUT gets frame_NNNNNN_color.png / _depth.png (NNNNNN: the frame's number in the
    recording), intrinsics.json, frames.csv (color,depth,time in seconds from the start)
    and, with --labels, labels.csv: the folder format every command reads. Frames that
    cannot be written (no depth near them in time) are listed, not lost silently.
    """
    from ..errors import InvalidInputError
    from ..extract import extract_recording

    if start is not None and end is not None and end < start:
        raise InvalidInputError(f"--end {end} is before --start {start}")
    recording = _open_recording(recording_path, recording_opts)
    with _progress_bar(recording.count, "extracting") as bar:
        result = extract_recording(
            recording,
            out,
            every=every,
            start=start,
            end=end,
            overwrite=overwrite,
            command=_command_line(),
            on_progress=bar.update,
        )
    _recording_notes(recording)
    for line in result.skipped:
        click.echo(f"skipped: {line}", err=True)
    click.echo(f"wrote {result.written} frames to {out} (frames: {result.frames_csv})")


def result_to_json(result: Any, color: str, depth: str) -> dict[str, Any]:
    """The JSON object of `--json` for one classified pair (see the README)."""
    import numpy as np

    found = result.observation.visible
    p = result.prediction
    out: dict[str, Any] = {"color": color, "depth": depth}
    if p is None:
        guess = result.best_guess
        out.update(
            {
                "class": None,
                "name": None,
                "variant": None,
                "distance": None,
                "runner_up": None,
                "confidence": None if guess is None else guess.confidence,
                "reason": result.reason,
            }
        )
    else:
        ru = p.runner_up
        out.update(
            {
                "class": p.class_id,
                "name": p.name,
                "variant": p.variant,
                "distance": round(p.distance, 6),
                "confidence": p.confidence,
                "runner_up": None
                if ru is None
                else {
                    "class": ru.class_id,
                    "name": ru.name,
                    "variant": ru.variant,
                    "distance": round(ru.distance, 6),
                },
            }
        )
    unknown = result.observation.unknown
    evidence = result.observation.evidence
    out["stickers"] = {
        "found": int(found.sum()),
        "missing": np.flatnonzero(~found).tolist(),
        "unknown": {str(i): evidence.reasons[i] for i in np.flatnonzero(unknown)}
        if evidence is not None
        else {},
    }
    out["coordinates"] = [
        None if not np.isfinite(v) else round(float(v), 8) for v in result.coordinates
    ]
    return out


def verdict_line(result: Any) -> str:
    """One readable line for a classified pair."""
    p = result.prediction
    if p is None:
        return f"no class: {result.reason}"
    text = f"{p.class_id} {p.name}"
    if p.variant:
        text += f" ({p.variant})"
    text += f", distance {p.distance:.3f}, confidence {p.confidence:.2f}"
    if p.runner_up:
        ru = p.runner_up
        text += f"; runner-up {ru.class_id} {ru.name}" + (f" ({ru.variant})" if ru.variant else "")
        text += f" {ru.distance:.3f}"
    return text


def _image_output(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """An image file to write: its extension must name a format OpenCV writes."""
    from pathlib import Path

    if value is not None and Path(value).suffix.lower() not in (".png", ".jpg", ".jpeg"):
        raise click.BadParameter(f"'{value}': name the image *.png or *.jpg")
    return value


@click.command("classify")
@click.argument("color", type=click.Path())
@click.argument("depth", type=click.Path())
@intrinsics_option
@references_option
@colours_option
@json_option("Print one JSON object.")
@click.option(
    "--overlay",
    type=click.Path(dir_okay=False),
    callback=_image_output,
    help="Write the image with stickers, segments and verdict (PNG or JPEG).",
)
@overwrite_option
@_handle_errors
def classify_cmd(
    color: str,
    depth: str,
    intrinsics: str | None,
    references_path: str | None,
    colours_path: str | None,
    as_json: bool,
    overlay: str | None,
    overwrite: bool,
) -> None:
    """Classify the cloth state in one colour + depth pair.

    Exit 1 when no class can be given: too few stickers seen, or a confidence below
    the documented threshold ("cannot tell", with the reason).
    """
    from pathlib import Path

    from ..colours_file import read_colours
    from ..frames import read_frame
    from ..io import guard_outputs, write_outputs
    from ..pipeline import classify_frame
    from ..references import load_references

    if overlay:
        guard_outputs([overlay], overwrite=overwrite)
    frame = read_frame(color, depth, intrinsics)
    refs = load_references(references_path)
    colours = read_colours(colours_path) if colours_path else None
    result = classify_frame(frame, refs, colours=colours)
    if overlay:
        from ..report import overlay_image

        detail = f"{int(result.observation.visible.sum())}/16 stickers"
        image = overlay_image(
            frame.color, result.detections.centroids, verdict_line(result), detail=detail
        )
        write_outputs({Path(overlay): image}, overwrite=overwrite, command=_command_line())
    if as_json:
        click.echo(json.dumps(result_to_json(result, color, depth)))
    else:
        click.echo(verdict_line(result))
    if result.prediction is None:
        if not as_json:
            click.echo(f"error: '{color}': {result.reason}", err=True)
        sys.exit(1)


main.add_command(classify_cmd)


def classify_main() -> None:
    """Entry point of ``dgli-classify`` (the same command as ``dgli classify``)."""
    _guarded(classify_cmd.main, prog_name="dgli-classify")


@main.command()
@click.argument("color", type=click.Path())
@click.argument("depth", type=click.Path())
@click.option(
    "-o",
    "--output",
    type=click.Path(),
    help="Colours file to write (JSON). Required unless --lens-out is given.",
)
@click.option(
    "--lens-out",
    type=click.Path(),
    help="Also estimate the lens distortion (k1, k2) and write the intrinsics with it: "
    'Open3D JSON with "distortion", or an OpenCV file for .yaml/.yml/.xml.',
)
@click.option(
    "--focal",
    is_flag=True,
    help="With --lens-out, estimate the focal length too (from the stickers' depths).",
)
@intrinsics_option
@overwrite_option
@_handle_errors
def calibrate(
    color: str,
    depth: str,
    output: str | None,
    lens_out: str | None,
    focal: bool,
    intrinsics: str | None,
    overwrite: bool,
) -> None:
    """Measure the printed sticker colours (and the lens) from one image of the flat napkin.

    All 16 stickers must be in view. Use the colours with --colours on classify and
    evaluate when stickers print far from the nominal colours. With --lens-out, the
    radial lens distortion is fitted to the 16 sticker centres as to a chessboard. It is
    determined only if the stickers reach well towards the image border (place the napkin
    off to one side, towards a corner); otherwise nothing is written and the exit code
    is 1.
    """
    from pathlib import Path

    from ..colours_file import write_colours
    from ..frames import read_frame
    from ..io import guard_outputs, write_outputs
    from ..layout import default_layout
    from ..perception.calibrate import calibrate_colours

    if output is None and lens_out is None:
        raise click.UsageError("give -o FILE (the colours) and/or --lens-out FILE (the lens)")
    if focal and lens_out is None:
        raise click.UsageError("--focal needs --lens-out")
    guard_outputs([p for p in (output, lens_out) if p], overwrite=overwrite)
    frame = read_frame(color, depth, intrinsics)
    if output is not None:
        colours = calibrate_colours(
            frame.color, frame.depth_mm, frame.intrinsics, default_layout(), source=color
        )
        write_colours(
            output,
            colours,
            {"command": _command_line(), "package_version": _package_version()},
            overwrite=overwrite,
        )
        for name, rgb in colours.items():
            click.echo(f"{name:<7} {rgb}")
        click.echo(f"wrote {output}")
    if lens_out is None:
        return
    from ..intrinsics_files import intrinsics_text
    from ..perception.lens import estimate_lens

    est = estimate_lens(
        frame.color,
        frame.depth_mm,
        frame.intrinsics,
        default_layout(),
        fit_focal=focal,
        source=color,
    )
    for line in _lens_lines(est):
        click.echo(line)
    if est.problem is not None:
        click.echo(
            f"error: '{color}': lens poorly constrained, {lens_out} not written: {est.problem}",
            err=True,
        )
        sys.exit(1)
    text = intrinsics_text(est.intrinsics, lens_out)
    write_outputs({Path(lens_out): text}, overwrite=overwrite, command=_command_line())
    click.echo(f"wrote {lens_out}")


def _lens_lines(est: Any) -> list[str]:
    """What ``dgli calibrate --lens-out`` says about a :class:`LensEstimate`."""
    import math

    import numpy as np

    def term(name: str, value: float, sd: float, unit: str = "") -> str:
        if math.isnan(sd):
            return f"{name} {value:.4g}{unit} (held fixed: not determined by this view)"
        return f"{name} {value:.4f}{unit} +/- {sd:.4f}{unit}"

    intr = est.intrinsics
    focal = (
        f"focal length {est.focal:.1f} +/- {est.focal_sd:.1f} px"
        if not math.isnan(est.focal_sd)
        else f"focal length {intr.fx:.1f} px (as given)"
    )
    quality = "poorly constrained" if est.problem else "determined"
    return [
        f"lens ({quality}): {term('k1', est.k1, est.k1_sd)}; {term('k2', est.k2, est.k2_sd)}",
        f"{focal}; principal point ({intr.cx:.1f}, {intr.cy:.1f}) (as given)",
        f"the stickers reach {est.reach:.0%} of the way to the image corner; fit residual "
        f"{est.rms_px:.2f} px rms",
        f"sticker shift by the lens: max {est.shift_px.max():.1f} px, "
        f"median {float(np.median(est.shift_px)):.1f} px",
    ]


@main.command()
@per_class_option(4, 50, "Pairs per class")
@click.option("--seed", default=1000, show_default=True, type=int, help="Seed of the renders.")
@click.option(
    "--conditions",
    "conditions",
    callback=_parse_conditions,
    default="",
    help="Conditions to score, comma-separated [default: clean and all].",
)
@jobs_option
@click.option(
    "--markdown",
    type=click.Path(),
    help="Also write the table as Markdown to this file.",
)
@references_option
@json_option("Print the table as JSON.")
@overwrite_option
@_handle_errors
def robustness(
    per_class: int,
    seed: int,
    conditions: tuple[str, ...],
    jobs: int | None,
    markdown: str | None,
    references_path: str | None,
    as_json: bool,
    overwrite: bool,
) -> None:
    """Render fresh pairs under each capture condition and score the answers.

    Right, "cannot tell" (exit 1) and wrong, per condition: the robustness table. Then
    the reliability table: for bins of confidence, how many best guesses (those that
    became "cannot tell" included) were right, over all conditions.
    """
    import os
    from pathlib import Path

    from ..condition_names import CONDITION_NAMES
    from ..io import guard_outputs, write_outputs
    from ..references import load_references
    from ..report import markdown_table
    from ..robustness import (
        reliability_rows,
        reliability_table,
        robustness_table,
        score_condition,
    )

    if markdown:
        guard_outputs([markdown], overwrite=overwrite)
    refs = load_references(references_path)
    names = conditions or ("clean", *CONDITION_NAMES)
    jobs = jobs or os.cpu_count() or 1
    scores = []
    for name in names:
        for score in score_condition(name, refs, per_class=per_class, seed=seed, jobs=jobs):
            scores.append(score)
            if not as_json:
                click.echo(
                    f"{score.condition}: {score.right}/{score.n} right, {score.wrong} wrong",
                    err=True,
                )
    header, rows = robustness_table(scores)
    table = markdown_table(header, rows)
    reliability = "Reliability (best guesses over all conditions):\n\n" + markdown_table(
        *reliability_table(scores)
    )
    if as_json:
        click.echo(
            json.dumps(
                {
                    "seed": seed,
                    "per_class": per_class,
                    "rows": [dict(zip(header, r)) for r in rows],
                    "wrong": {s.condition: list(s.wrong_cases) for s in scores},
                    "reliability": reliability_rows(scores),
                }
            )
        )
    else:
        click.echo(table, nl=False)
        for s in scores:
            for case in s.wrong_cases:
                click.echo(f"wrong under {s.condition}: {case}")
        click.echo("\n" + reliability, nl=False)
    if markdown:
        command = _command_line()
        write_outputs(
            {Path(markdown): f"Robustness: `{command}`\n\n" + table + "\n" + reliability},
            overwrite=overwrite,
            command=command,
        )


@main.command()
@click.argument("out", type=click.Path(dir_okay=False))
@size_option
@overwrite_option
@_handle_errors
def stickers(out: str, size_mm: tuple[float, float] | None, overwrite: bool) -> None:
    """Write the printable sticker kit to OUT (SVG in millimetres, prints at 1:1) and a
    PNG preview beside it.

    The kit holds every sticker twice (front and back face) and a placement template for
    each corner, with a 100 mm bar to check the print scale.
    """
    from pathlib import Path

    from ..errors import InvalidInputError
    from ..io import write_outputs
    from ..layout import layout_of_size
    from ..sticker_sheet import sheet_image, sheet_svg, sticker_sheet

    svg = Path(out)
    if svg.suffix.lower() != ".svg":
        raise InvalidInputError(f"'{out}': the sticker kit is written as SVG; name it *.svg")
    preview = svg.with_suffix(".png")
    sheet = sticker_sheet(layout_of_size(size_mm))
    write_outputs(
        {svg: sheet_svg(sheet), preview: sheet_image(sheet)},
        overwrite=overwrite,
        command=_command_line(),
    )
    click.echo(f"wrote {svg} (print at 100 %, A3) and its preview {preview}")


@main.command()
@json_option("Print a JSON object.")
@_handle_errors
def coords(as_json: bool) -> None:
    """Show the 28 dGLI cloth coordinates of the flat napkin."""
    from ..dgli import pair_indices
    from ..layout import default_layout

    layout = default_layout()
    values = layout.flat_coordinates()
    i, j = pair_indices(layout.n_segments)
    if as_json:
        click.echo(json.dumps({"state": "flat", "unit": "1/m", "coordinates": values.tolist()}))
        return
    click.echo("dGLI cloth coordinates of the flat napkin (1/m), segment pairs i-j:")
    for a, b, v in zip(i, j, values):
        click.echo(f"  {a}-{b}  {v + 0.0:+.6f}")


def _format_figure(value: float, unit: str) -> str:
    if unit.endswith("/s"):
        for scale, prefix in ((1e6, "M "), (1e3, "k ")):
            if value >= scale:
                return f"{value / scale:.2f} {prefix}{unit}"
        return f"{value:.1f} {unit}"
    if unit == "x":
        return f"{value:,.0f}x" if value >= 10 else f"{value:.2f}x"
    return f"{value:.3g} {unit}"


@main.command()
@click.option("--states", default=100_000, show_default=True, help="States in the batch case.")
@click.option("--repeats", default=5, show_default=True, help="Timing rounds (best is kept).")
@click.option(
    "--markdown",
    type=click.Path(),
    help="Also write the figures as a Markdown table to this file.",
)
@click.option(
    "--only",
    type=click.Choice(["dgli", "pipeline", "recording"]),
    help="Run one group of benchmarks only.",
)
@click.option(
    "--samples",
    default="sample_images",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Labelled folder for the pipeline benchmarks.",
)
@overwrite_option
@_handle_errors
def bench(
    states: int,
    repeats: int,
    markdown: str | None,
    only: str | None,
    samples: str,
    overwrite: bool,
) -> None:
    """Measure the benchmark figures against their budgets (one core where a budget says so)."""
    import platform
    import shutil
    from pathlib import Path

    from ..bench import run_dgli_benchmarks, run_pipeline_benchmarks, run_recording_benchmarks
    from ..io import guard_outputs, write_outputs

    if markdown:
        guard_outputs([markdown], overwrite=overwrite)
    results = []
    if only in (None, "dgli"):
        results += run_dgli_benchmarks(n_states=states, repeats=repeats)
    if only in (None, "pipeline"):
        exe = Path(sys.executable).parent / "dgli-classify"
        exe_path = str(exe) if exe.exists() else shutil.which("dgli-classify")
        results += run_pipeline_benchmarks(samples, repeats=repeats, classify_exe=exe_path)
    if only in (None, "recording"):
        results += run_recording_benchmarks(samples)
    rows = []
    for r in results:
        value = _format_figure(r.value, r.unit)
        verdict = "" if r.ok is None else ("ok" if r.ok else "MISSED")
        rows.append((r.name, value, r.goal, verdict))
        click.echo(f"{r.name:<60} {value:>18}  {r.goal:<16} {verdict}")
    if markdown:
        lines = [
            "| benchmark | figure | goal | verdict |",
            "|---|---|---|---|",
            *(f"| {n} | {v} | {g} | {ok} |" for n, v, g, ok in rows),
            "",
            f"Machine: {platform.machine()}, Python {platform.python_version()}, "
            f"numpy {__import__('numpy').__version__}.",
        ]
        write_outputs(
            {Path(markdown): "\n".join(lines) + "\n"},
            overwrite=overwrite,
            command=_command_line(),
        )
