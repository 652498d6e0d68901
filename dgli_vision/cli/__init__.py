"""Command line: ``dgli`` (a group of commands) and ``dgli-classify``.

The only package that prints or exits. :mod:`.main` holds the group and registers the
commands of the other modules; this module re-exports the two entry points named in
pyproject.toml.
"""

from .main import classify_main, main

__all__ = ["classify_main", "main"]
