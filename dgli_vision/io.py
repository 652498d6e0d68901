"""Reading and writing files: the only module of the library that touches the disk."""

from __future__ import annotations

from pathlib import Path

from .errors import UnreadableInputError

__all__ = ["write_text"]


def write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` (UTF-8), creating parent folders.

    Raises
    ------
    UnreadableInputError
        If the file cannot be written.
    """
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UnreadableInputError(f"cannot write '{p}': {exc.strerror}") from None
