"""The ground (issue 38, item 5): the plane the base stands on is an obstacle by default,
so a straight line cannot end under it; a request opts out with ``"ground": false``.

Typed as the SO-101's owner did (tests/helpers/so101.py, the folder as published): a LIN
to 1.5 cm under the plane the base stands on, which planned before."""

from __future__ import annotations

import pytest

from arduinobot.contract.errors import PlanningError
from arduinobot.description import load_description
from arduinobot.service.local import LocalService
from tests.helpers.so101 import make_so101

UNDER = {"line": {"position": [0.2, 0.0, -0.015]}}  # 1.5 cm under the plane [m]


@pytest.fixture(scope="module")
def svc(tmp_path_factory):
    return LocalService(load_description(make_so101(tmp_path_factory.mktemp("so101")), env={}))


def test_a_line_below_the_ground_is_refused_naming_the_ground(svc):
    with pytest.raises(PlanningError) as e:
        svc.request("plan", {"goal": UNDER, "seed": 1})
    pairs = e.value.details["pairs"]
    assert any("ground" in p for p in pairs), e.value.details
    # it stops where the tool meets the plane, not at the start: the arm's own base
    # stands on the ground without colliding
    assert 0.5 < e.value.details["fraction"] < 1.0, e.value.details


def test_home_and_a_plan_above_the_ground_still_plan(svc):
    reply = svc.request("plan", {"goal": {"line": {"position": [0.2, 0.0, 0.05]}}, "seed": 1})
    assert reply["verification"]["ok"], reply["verification"]


def test_ground_false_opts_out(svc):
    reply = svc.request("plan", {"goal": UNDER, "seed": 1, "ground": False})
    assert reply["verification"]["ok"], reply["verification"]
    assert reply["trajectory"]["points"], "no trajectory"
