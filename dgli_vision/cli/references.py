"""``dgli references build``: the reference set the classifier matches against."""

from __future__ import annotations

import click

from ..core.words import counted
from .errors import handle_errors
from .options import output_option, overwrite_option, size_option
from .output import command_line, echo, napkin_provenance, package_version


@click.group()
def references() -> None:
    """Build the reference set the classifier matches against."""


@references.command("build")
@click.argument("db", type=click.Path())
@output_option("Reference file to write.")
@size_option
@overwrite_option
@handle_errors
def references_build(
    db: str, output: str, size_mm: tuple[float, float] | None, overwrite: bool
) -> None:
    """Pick one representative per class and variant from the simulated database DB.

    The set is for the napkin size DB was simulated for; --size only checks it.
    """
    from ..classifier.references import build_references, write_references
    from ..core.errors import InvalidInputError
    from ..core.layout import layout_of_size
    from ..sim.database_files import read_database

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
        "command": command_line(),
        **napkin_provenance(have),
        "database": db_provenance,
        "n_states": len(records),
        "package_version": package_version(),
        "method": "per (class, variant): the state nearest (Spearman) to the group centroid",
    }
    refs = build_references(records, provenance=provenance)
    write_references(output, refs, overwrite=overwrite)
    echo(
        f"wrote {counted(len(refs), 'reference')} from {counted(len(records), 'state')} "
        f"to {output}"
    )
