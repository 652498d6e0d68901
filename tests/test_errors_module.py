"""Errors in one module (issue 51): every exception class of the package lives in
core/errors.py, and the modules that raised them before still give them by their old
names."""

from __future__ import annotations


def test_every_exception_class_lives_in_core_errors_under_its_old_names_too():
    from dgli_vision.cli import output
    from dgli_vision.core import errors
    from dgli_vision.planning import plan
    from dgli_vision.sources import mcap_file

    assert plan.PlanRefused is errors.PlanRefused and issubclass(errors.PlanRefused,
                                                                 errors.DgliError)
    assert output.StdoutClosed is errors.StdoutClosed
    assert mcap_file.McapError is errors.McapError and issubclass(errors.McapError,
                                                                  ValueError)
    for cls in (errors.PlanRefused, errors.StdoutClosed, errors.McapError):
        assert cls.__module__ == "dgli_vision.core.errors"
