"""The error hierarchy: every failure the library reports is a :class:`DgliError`.

The CLI turns these into a one-line message and an exit code in one handler; library
code raises them and never prints or exits.
"""

from __future__ import annotations

__all__ = [
    "CalibrationError",
    "DetectionError",
    "DgliError",
    "InvalidInputError",
    "MissingExtraError",
    "OutputError",
    "OverwriteError",
    "ReferenceError_",
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


class CalibrationError(InvalidInputError):
    """Camera intrinsics are malformed or inconsistent with the images."""


class DetectionError(DgliError):
    """The input was read but too little was seen to decide (exit code 1)."""

    exit_code = 1


class ReferenceError_(DgliError):
    """The reference set is missing, malformed or incompatible."""


class MissingExtraError(DgliError):
    """An optional dependency a command needs is not installed (exit code 2); the message
    names the extra to install (``pip install dgli_vision[photoreal]``)."""


class OverwriteError(DgliError):
    """A command would replace a file it did not write (exit code 2; ``--overwrite``)."""


class OutputError(DgliError):
    """A file (or standard output) cannot be written: a full disk, no permission, a name
    too long, a folder that cannot be made, an image format without a writer. The
    message names the file, the reason, and what was written before it and is kept."""
