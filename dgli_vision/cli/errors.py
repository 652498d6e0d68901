"""Every error of a command as one line on stderr and its exit code (never a traceback)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import wraps
from typing import Any, TypeVar

import click

from ..core.errors import DgliError
from .output import StdoutClosed

F = TypeVar("F", bound=Callable[..., Any])


def _os_error_message(exc: OSError) -> str:
    """One line for an operating-system error that no library function named: the file
    (or standard output) and the reason."""
    from ..core.io import display_path

    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.filename is not None:
        return f"'{display_path(exc.filename)}': {reason}"
    if _raised_writing_stdout(exc):
        from .output import stdout_name

        return f"cannot write to {stdout_name()}: {reason}"
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
        from .output import stdout_error

        raise stdout_error(exc) from None


def _stdout_failed() -> bool:
    """Whether standard output cannot take what is waiting in its buffer."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except (OSError, ValueError):
        return True
    return False


#: The exit code of a command whose standard output was a pipe that its reader closed
#: (``dgli watch --jsonl | head -1``): 128 + SIGPIPE, what a shell reports for a Unix tool
#: that the signal ended. Nothing is printed.
PIPE_CLOSED_EXIT = 141


def _drop_stdout() -> None:
    """Point standard output at /dev/null, so that the interpreter's last flush of what
    it could not take succeeds instead of printing an error at exit."""
    import os

    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def _quiet_exit() -> None:
    """End as a Unix tool does when its output pipe is closed: no message, exit 141."""
    _drop_stdout()
    sys.exit(PIPE_CLOSED_EXIT)


def _fail(message: str, code: int) -> None:
    """Print ``error: message`` on stderr (if stderr can take it) and exit with ``code``;
    output that standard output could not take is dropped, so that Python does not
    report it again at exit."""
    if _stdout_failed():
        _drop_stdout()
    try:
        click.echo(f"error: {message}", err=True)
    except (OSError, ValueError):
        pass  # stderr is closed or full too: the exit code is all that is left
    sys.exit(code)


def handle_errors(fn: F) -> F:
    """Turn every error into one line on stderr and its exit code (never a traceback).

    A :class:`~dgli_vision.core.errors.DgliError` gives its own message and code; an
    operating-system error that got through (a full disk, a closed or full standard
    output, a name too long) exits 2 naming the file; running out of memory exits 2.
    Standard output is flushed before the command counts as done, so that a full
    ``/dev/full`` is reported (naming the file standard output goes to) rather than lost.
    A pipe whose reader has gone (``| head -1``) ends the command quietly with exit 141,
    as it ends a Unix tool, after the command's own clean-up (``finally`` blocks: a
    camera's pipeline stopped, files closed). A closed standard output (``>&-``) stops
    the command before any work: it is where the answer goes.
    """

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            if sys.stdout is None:
                from ..core.errors import OutputError

                raise OutputError("standard output is closed; dgli prints its answer there")
            try:
                result = fn(*args, **kwargs)
            except SystemExit:
                _flush_stdout()
                raise
            _flush_stdout()
            return result
        except StdoutClosed:
            _quiet_exit()
        except DgliError as exc:
            _fail(str(exc), exc.exit_code)
        except OSError as exc:
            if _pipe_closed(exc):
                _quiet_exit()
            _fail(_os_error_message(exc), 2)
        except MemoryError:
            _fail("out of memory", 2)

    return wrapper  # type: ignore[return-value]


def _pipe_closed(exc: OSError) -> bool:
    """Whether ``exc`` is standard output's pipe, closed by its reader."""
    import errno

    from .output import stdout_reader_gone

    return exc.errno == errno.EPIPE and stdout_reader_gone()


def _line_buffered_stdout() -> None:
    """Under ``python -u`` (or PYTHONUNBUFFERED), standard output's text layer writes
    straight to the file, and a short write (the last blocks a filling disk takes) is
    dropped without an error: the answer is cut and the command exits 0. A buffered
    writer between them, flushed at every line, writes the rest or raises."""
    import io

    stream = sys.stdout
    raw = getattr(stream, "buffer", None)
    if isinstance(stream, io.TextIOWrapper) and isinstance(raw, io.RawIOBase):
        sys.stdout = io.TextIOWrapper(
            io.BufferedWriter(raw),
            encoding=stream.encoding,
            errors=stream.errors,
            line_buffering=True,
            write_through=True,
        )


def guarded(run: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Run click's ``main`` with an operating-system error outside any command (help or
    a usage error written to a full or closed stream) as one line, exit 2 (a closed pipe:
    quietly, exit 141), and standard output that reports every failed write."""
    _line_buffered_stdout()
    try:
        return run(*args, **kwargs)
    except StdoutClosed:
        _quiet_exit()
    except OSError as exc:
        if _pipe_closed(exc):
            _quiet_exit()
        _fail(_os_error_message(exc), 2)
