"""Tests of raymitsuba/cli/common.py: the commands' exit statuses and error lines."""

from __future__ import annotations

import pytest

from raymitsuba.cli import common as cli_common
from raymitsuba.model import Diagnostic, Severity


def test_exit_statuses():
    assert (cli_common.EXIT_FAILURE, cli_common.EXIT_SCENE_ERROR) == (1, 2)


def test_report_prints_each_diagnostic_to_stderr(capsys):
    d = Diagnostic(Severity.WARNING, "s.ray", 2, 1, "careful", "eye 0 0 4")
    cli_common.report([d, d])
    out, err = capsys.readouterr()
    assert out == "" and err == d.format() + "\n" + d.format() + "\n"


def test_fail_prints_one_error_line_and_exits_with_the_code(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli_common.fail("raymitsuba fit", "no such key", 2)
    assert exit_.value.code == 2
    assert capsys.readouterr().err == "raymitsuba fit: error: no such key\n"


def test_error_message_is_the_innermost_causes_last_line():
    try:
        try:
            raise AttributeError("first line\n'Surfaces' object has no attribute 'color'")
        except AttributeError as cause:
            raise RuntimeError("drjit.custom(...): error while performing a custom "
                               "differentiable operation. (see above).") from cause
    except RuntimeError as e:
        assert cli_common.error_message(e) == "'Surfaces' object has no attribute 'color'"
    assert cli_common.error_message(KeyError()) == "KeyError"
