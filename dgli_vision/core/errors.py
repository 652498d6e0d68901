"""The error hierarchy: every failure the library reports is a :class:`DgliError`.

The CLI turns these into a one-line message and an exit code in one handler; library
code raises them and never prints or exits. Every exception class of the package lives
here, also the two that are not a :class:`DgliError` (:class:`StdoutClosed`, the quiet
end of a closed pipe, and :class:`McapError`, which the recording readers turn into one
that names the file); the modules that raise them import them from here under the same
names (``dgli_vision.planning.plan.PlanRefused`` and the others still work).
"""

from __future__ import annotations

__all__ = [
    "CalibrationError",
    "DetectionError",
    "DgliError",
    "InvalidInputError",
    "InvalidValueError",
    "McapError",
    "MissingExtraError",
    "OutputError",
    "OverwriteError",
    "PlanRefused",
    "ReferenceSetError",
    "ResumeMismatchError",
    "RunBusyError",
    "StdoutClosed",
    "UnreadableInputError",
]


class DgliError(Exception):
    """Base class of dgli_vision's errors; the message says what failed and why."""

    #: Exit code the CLI uses for this error (DESIGN.md: 2 = bad or unreadable input).
    exit_code = 2


class UnreadableInputError(DgliError):
    """A file is missing or cannot be read or decoded."""


class InvalidInputError(DgliError):
    """A file was read but its content is not what is expected."""


class InvalidValueError(InvalidInputError, ValueError):
    """An argument's value is not one the library accepts: a class or state name, an
    option's text (``AB=180,DA=175``), a count below its minimum, an image of the wrong
    shape or type, a request the renderer cannot meet.

    It is also a :class:`ValueError`, so code that validates its own input and catches
    ``ValueError`` (as scikit-image's callers do) keeps working. Pure contract checks of
    the numerics (``core/dgli.py``, ``core/distance.py``, ``sim/cloth``'s geometry) raise
    a bare ``ValueError``: they are a programmer's mistake, not a user's.
    """


class CalibrationError(InvalidInputError):
    """Camera intrinsics are malformed or inconsistent with the images."""


class DetectionError(DgliError):
    """The input was read but too little was seen to decide (exit code 1)."""

    exit_code = 1


class ReferenceSetError(DgliError):
    """The reference set is missing, malformed or incompatible (exit code 2)."""


class MissingExtraError(DgliError):
    """An optional dependency a command needs is not installed (exit code 2); the message
    names the extra to install (``pip install dgli_vision[photoreal]``)."""


class OverwriteError(DgliError):
    """A command would replace a file it did not write (exit code 2; ``--overwrite``)."""


class OutputError(DgliError):
    """A file (or standard output) cannot be written: a full disk, no permission, a name
    too long, a folder that cannot be made, an image format without a writer. The
    message names the file, the reason, and what was written before it and is kept."""


class RunBusyError(DgliError):
    """Another run is writing into the same folder (exit code 2)."""


class ResumeMismatchError(DgliError):
    """``--resume`` was asked of a journal written by a different run (exit code 2)."""


class PlanRefused(DgliError):
    """No plan: the goal is not reachable by single folds, or the state cannot be told,
    or the step's corner cannot be placed. The message is the reason (raised by
    :mod:`dgli_vision.planning`)."""


class StdoutClosed(Exception):
    """Standard output is a pipe whose reader has gone (``dgli ... | head -1``): the
    command ends quietly, as Unix tools do (:func:`~dgli_vision.cli.errors.handle_errors`).
    Not a :class:`DgliError`: it is no failure to report."""


class McapError(ValueError):
    """A record of an MCAP file that does not fit the file or its chunk (truncated or
    corrupt), raised by :mod:`dgli_vision.sources.mcap_file`; the recording readers turn
    it into an :class:`UnreadableInputError` naming the file."""


def __getattr__(name: str) -> type[DgliError]:
    # ``ReferenceError_`` was this class's name up to 0.1.0; code that catches it by the
    # old name keeps working, with a DeprecationWarning.
    if name == "ReferenceError_":
        import warnings

        warnings.warn(
            "ReferenceError_ is renamed ReferenceSetError", DeprecationWarning, stacklevel=2
        )
        return ReferenceSetError
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
