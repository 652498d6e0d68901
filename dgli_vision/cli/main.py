"""Command line: ``dgli`` (a group of commands). The only package that prints or exits.

Commands are thin adapters: parse, call the library, format. Each lives in a module of
this package and is registered here; heavy modules are imported inside the command that
needs them, so that ``dgli --help`` starts fast.
"""

from __future__ import annotations

from typing import Any

import click

from .bench import bench
from .calibrate import calibrate
from .classify import classify_cmd
from .compare import compare, sequence
from .errors import guarded
from .evaluate import evaluate
from .extract import extract
from .label import label_cmd
from .napkin import coords, stickers
from .plan import plan_cmd
from .references import references
from .render import render_cmd
from .robustness import robustness
from .simulate import simulate
from .track import track
from .verify import verify_cmd
from .watch import watch
from .write_recording import write_recording_cmd


class _Group(click.Group):
    """The ``dgli`` group: :func:`guarded` around click's own output too."""

    def main(self, *args: Any, **kwargs: Any) -> Any:
        return guarded(super().main, *args, **kwargs)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="dgli_vision")
def main() -> None:
    """dgli_vision: classify the state of a marked napkin with dGLI cloth coordinates."""


for _command in (
    simulate,
    evaluate,
    render_cmd,
    references,
    compare,
    sequence,
    track,
    extract,
    classify_cmd,
    calibrate,
    robustness,
    stickers,
    coords,
    bench,
    label_cmd,
    watch,
    plan_cmd,
    verify_cmd,
    write_recording_cmd,
):
    main.add_command(_command)


def classify_main() -> None:
    """Entry point of ``dgli-classify`` (the same command as ``dgli classify``)."""
    guarded(classify_cmd.main, prog_name="dgli-classify")
