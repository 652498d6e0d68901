"""Every error of a command as one line on stderr and its exit code (never a traceback)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import wraps
from typing import Any, TypeVar

import click

from ..core.errors import DgliError

F = TypeVar("F", bound=Callable[..., Any])


def _os_error_message(exc: OSError) -> str:
    """One line for an operating-system error that no library function named: the file
    (or standard output) and the reason."""
    from ..core.io import display_path

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
        from ..core.errors import OutputError

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


def handle_errors(fn: F) -> F:
    """Turn every error into one line on stderr and its exit code (never a traceback).

    A :class:`~dgli_vision.core.errors.DgliError` gives its own message and code; an
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
                from ..core.errors import OutputError

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


def guarded(run: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Run click's ``main`` with an operating-system error outside any command (help or
    a usage error written to a full or closed stream) as one line, exit 2."""
    try:
        return run(*args, **kwargs)
    except OSError as exc:
        _fail(_os_error_message(exc), 2)
