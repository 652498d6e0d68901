"""Command line: ``dgli`` (a group of commands). The only module that prints or exits.

Commands are thin adapters: parse, call the library, format. Heavy modules are imported
inside the command that needs them, so that ``dgli --help`` starts fast.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from functools import wraps
from typing import Any, TypeVar

import click

from .errors import DgliError

F = TypeVar("F", bound=Callable[..., Any])


def _handle_errors(fn: F) -> F:
    """Turn a DgliError into one line on stderr and its exit code (never a traceback)."""

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except DgliError as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(exc.exit_code)

    return wrapper  # type: ignore[return-value]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="dgli_vision")
def main() -> None:
    """dgli_vision: classify the state of a marked napkin with dGLI cloth coordinates."""


@main.command()
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object.")
@_handle_errors
def coords(as_json: bool) -> None:
    """Show the 28 dGLI cloth coordinates of the flat napkin (SPEC section 2)."""
    from .dgli import pair_indices
    from .layout import default_layout

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
        return f"{value:,.0f}x"
    return f"{value:.3g} {unit}"


@main.command()
@click.option("--states", default=100_000, show_default=True, help="States in the batch case.")
@click.option("--repeats", default=5, show_default=True, help="Timing rounds (best is kept).")
@click.option(
    "--markdown",
    type=click.Path(dir_okay=False, writable=True),
    help="Also write the figures as a Markdown table to this file.",
)
@_handle_errors
def bench(states: int, repeats: int, markdown: str | None) -> None:
    """Measure the benchmark figures of DESIGN.md (one core where it says so)."""
    import platform

    from .bench import run_dgli_benchmarks

    results = run_dgli_benchmarks(n_states=states, repeats=repeats)
    rows = []
    for r in results:
        value = _format_figure(r.value, r.unit)
        verdict = "" if r.ok is None else ("ok" if r.ok else "MISSED")
        rows.append((r.name, value, r.goal, verdict))
        click.echo(f"{r.name:<60} {value:>18}  {r.goal:<16} {verdict}")
    if markdown:
        from .io import write_text

        lines = [
            "| benchmark | figure | goal | verdict |",
            "|---|---|---|---|",
            *(f"| {n} | {v} | {g} | {ok} |" for n, v, g, ok in rows),
            "",
            f"Machine: {platform.machine()}, Python {platform.python_version()}, "
            f"numpy {__import__('numpy').__version__}.",
        ]
        write_text(markdown, "\n".join(lines) + "\n")
