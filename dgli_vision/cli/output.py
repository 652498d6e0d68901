"""What the commands share in their output: provenance records and progress bars."""

from __future__ import annotations

import sys
from typing import Any

import click


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
                value = ",".join(map(str, value))
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
        return click.progressbar(length=length, label=label, file=sys.stderr, show_eta=True)
    from contextlib import nullcontext

    class _Silent:
        def update(self, n: int) -> None:
            pass

    return nullcontext(_Silent())


def progress(items: list, label: str, *, quiet: bool = False):
    """``items`` with a progress bar and the time left on a terminal; the plain list
    otherwise."""
    if _live(quiet):
        return click.progressbar(items, label=label, file=sys.stderr, show_eta=True)
    from contextlib import nullcontext

    return nullcontext(items)
