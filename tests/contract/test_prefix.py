"""A key prefix is literal (issue 39, item 10): ``--prefix '*'`` was accepted and the
service answered every other prefix's keys; now the prefix's wildcards, reserved
characters and empty chunks are refused naming ``prefix``, by the library and by every
command's ``--prefix``."""

from __future__ import annotations

import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.zconfig import check_prefix
from arduinobot.service.server import ServeOptions
from tests.helpers.cli import run_cli


@pytest.mark.parametrize("prefix", ["*", "**", "lab/*", "arm$*", "a#b", "a?b", "a b",
                                    "", "/lab", "lab/", "lab//arm"])
def test_a_prefix_that_is_not_literal_is_refused(prefix: str) -> None:
    with pytest.raises(InvalidRequest) as e:
        check_prefix(prefix)
    assert e.value.field == "prefix"
    with pytest.raises(InvalidRequest):
        ServeOptions(prefix=prefix)


@pytest.mark.parametrize("prefix", ["arduinobot", "lab/arm-1", "a_b.c"])
def test_a_literal_prefix_is_taken(prefix: str) -> None:
    assert check_prefix(prefix) == prefix and ServeOptions(prefix=prefix).prefix == prefix


@pytest.mark.parametrize("command", [["serve", "--no-robot"], ["plan", "--named", "home"]])
def test_the_commands_refuse_a_wildcard_prefix_before_anything_starts(command: list[str]
                                                                       ) -> None:
    out = run_cli(*command, "--prefix", "*", timeout=120)
    assert out.returncode == 2, out  # argparse's usage error
    assert "--prefix" in out.stderr and "'*'" in out.stderr
