"""What the commands share in their output: standard output written, flushed and
checked (:func:`echo`, :func:`echo_json`), provenance records and progress bars."""

from __future__ import annotations

import errno
import sys
from collections.abc import Callable
from typing import Any

import click

from ..core.errors import OutputError, StdoutClosed


def stdout_name() -> str:
    """``standard output``, with the file it is redirected to when it is a regular file
    (``standard output ('/data/run.json')``), for messages."""
    import os
    import stat

    from ..core.io import display_path

    try:
        fd = sys.stdout.fileno()
        if stat.S_ISREG(os.fstat(fd).st_mode):
            return f"standard output ('{display_path(os.readlink(f'/proc/self/fd/{fd}'))}')"
    except (OSError, ValueError, AttributeError):
        pass
    return "standard output"


def stdout_reader_gone() -> bool:
    """Whether standard output is a pipe (or socket) that nobody reads any more."""
    import select

    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return False


def stdout_error(exc: OSError) -> Exception:
    """What a failed write to standard output becomes: :class:`StdoutClosed` for a
    pipe whose reader has gone, else an :class:`OutputError` naming standard output
    (and its file) and the reason (a full disk, an I/O error)."""
    if exc.errno == errno.EPIPE or isinstance(exc, BrokenPipeError) or stdout_reader_gone():
        return StdoutClosed()
    return OutputError(f"cannot write to {stdout_name()}: {exc.strerror or exc}")


def echo(text: str = "", *, nl: bool = True) -> None:
    """Write ``text`` (and a newline) to standard output and flush it: every command's
    answer goes through here, so that a full disk or a closed pipe is never lost.

    Raises
    ------
    OutputError
        Standard output cannot take it (no space left on device, an I/O error): the
        message names its file.
    StdoutClosed
        Standard output is a pipe whose reader has gone.
    """
    stream = sys.stdout
    if stream is None:
        raise OutputError("standard output is closed; dgli prints its answer there")
    try:
        stream.write(text + "\n" if nl else text)
        stream.flush()
    except OSError as exc:
        raise stdout_error(exc) from None


def answer_then_report(answer: Callable[[], None], report: Callable[[], None] | None) -> None:
    """Print a run's answer (``answer()``), then write its report (``report()``, None:
    none asked for), the report even when standard output cannot take the answer (a
    pipe whose reader has gone, ``| head -1``; a full disk): the report and its
    results.jsonl are the run's record, and what stopped the answer is raised after
    it (exit 141 for the pipe, 2 for the disk)."""
    try:
        answer()
    except (StdoutClosed, OutputError):
        if report is not None:
            report()
        raise
    if report is not None:
        report()


def echo_json(data: Any) -> None:
    """``data`` as one line of JSON on standard output (:func:`echo`)."""
    import json

    echo(json.dumps(data))


def verdict_json(result: Any, color: str, depth: str, extrinsics: Any = None) -> Any:
    """The JSON object of ``dgli classify --json`` for a
    :class:`~dgli_vision.classifier.pipeline.FrameResult`: its ``to_json()`` with the
    table's normal ``"up"`` and ``"frame"``, every 3D point in the frame of
    ``extrinsics`` (an :class:`~dgli_vision.core.extrinsics.Extrinsics`; None: the
    camera's), and the camera's handedness it was read with, ``"mirroring"``."""
    from ..core.extrinsics import in_frame

    data = result.to_json(color, depth)
    data["up"] = [round(float(v), 6) for v in result.observation.up]
    data["mirroring"] = getattr(result, "mirroring", "no")
    return in_frame(data, extrinsics)


def command_line() -> str:
    """The current command, rebuilt from its parsed parameters, for provenance records."""
    import shlex

    ctx = click.get_current_context()
    sub = ctx.command_path.split(" ", 1)
    words = ["dgli", *sub[1:]] if ctx.parent is not None else [ctx.command_path]
    for param in ctx.command.params:
        value = ctx.params.get(param.name)
        if isinstance(param, click.Argument):
            values = value if isinstance(value, (tuple, list)) else (value,)
            words += [shlex.quote(str(v)) for v in values]  # nargs=-1: each on its own
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
            if isinstance(value, (tuple, list)):  # a parsed list (--conditions a,b)
                sep = getattr(param, "list_separator", ",")  # a state: 05/AB/B
                value = sep.join(str(v) for v in value if v is not None)
            words.append(flag if value is True else f"{flag} {shlex.quote(str(value))}")
    return " ".join(words)


def package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dgli_vision")
    except PackageNotFoundError:  # pragma: no cover - running from a bare checkout
        return "unknown"


def napkin_provenance(layout: Any) -> dict[str, Any]:
    """``{"napkin_mm": [W, H]}`` for a napkin of other than the nominal size, else ``{}``
    (so that files of the nominal napkin stay as they were)."""
    return {} if layout.is_nominal else {"napkin_mm": [layout.width_mm, layout.height_mm]}


def _live(quiet: bool) -> bool:
    """Progress is drawn on a terminal only: not into a pipe or a file, and never with
    --json (``quiet``)."""
    return sys.stderr.isatty() and not quiet


def progress_bar(length: int, label: str, *, quiet: bool = False):
    """A progress bar with the time left on a terminal (``bar.update(n)`` after each
    ``n`` items done); an object that ignores updates otherwise."""
    if _live(quiet):
        return _FromFirstItem(
            click.progressbar(length=length, label=label, file=sys.stderr, show_eta=True)
        )
    from contextlib import nullcontext

    class _Silent:
        def update(self, n: int) -> None:
            pass

    return nullcontext(_Silent())


class _FromFirstItem:
    """A click progress bar whose time left is reckoned from the first item done: the
    time before it (workers starting, the references loading) is no part of the rate,
    so a 10 s job is not first said to need 48 s. No time left is shown until a rate
    is known (two updates apart)."""

    def __init__(self, bar: Any) -> None:
        self.bar, self.t0, self.p0 = bar, None, 0

    def __enter__(self) -> _FromFirstItem:
        self.bar.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.__exit__(*exc)

    def update(self, n: int) -> None:
        import time

        now = time.time()
        bar = self.bar
        if self.t0 is None:
            self.t0, self.p0 = now, bar.pos + n
            bar.update(n)
            bar.avg, bar.eta_known, bar.last_eta = [], False, 0.0
            return
        done = bar.pos + n - self.p0
        if done > 0:  # click's rate is (now - start) / pos: from the first item on
            bar.start = now - (now - self.t0) * (bar.pos + n) / done
        bar.update(n)


def progress(items: list, label: str, *, quiet: bool = False, lines: bool = False):
    """``items`` with a progress bar and the time left on a terminal; the plain list
    otherwise, or with ``lines`` (and not ``quiet``) the items with a line on stderr
    every tenth of them (:func:`progress_lines`): a log or CI sees the work go on."""
    if _live(quiet):
        return click.progressbar(items, label=label, file=sys.stderr, show_eta=True)
    from contextlib import nullcontext

    if lines and not quiet:
        return nullcontext(progress_lines(items, label))
    return nullcontext(items)


def progress_lines(items: list, label: str, every: int | None = None):
    """``items``, one at a time, with ``LABEL: K of N done (T s, about R s left)`` on
    stderr after every ``every``-th (default a tenth of them) and after the last."""
    import time

    n = len(items)
    every = every or max(1, -(-n // 10))
    start = time.monotonic()
    for k, item in enumerate(items, 1):
        yield item
        if k % every == 0 or k == n:
            spent = time.monotonic() - start
            left = spent / k * (n - k)
            click.echo(
                f"{label}: {k} of {n} done ({spent:.0f} s"
                + (f", about {left:.0f} s left)" if k < n else ")"),
                err=True,
            )
