"""Issue 37, item 1: the project installs one top-level package, ``arduinobot``, whose
public faces import from it directly; the old generic names (``service``, ``planner``,
...) are gone, so a user's own ``planner.py`` shadows nothing of ours."""

from __future__ import annotations

import subprocess
import sys
from importlib import metadata

import pytest

OLD_NAMES = ("service", "planner", "clients", "execution", "description", "ros2")


def test_the_distribution_installs_one_top_level_package():
    tops = metadata.distribution("arduinobot").read_text("top_level.txt")
    assert tops is not None
    assert tops.split() == ["arduinobot"]


@pytest.mark.parametrize("name", OLD_NAMES)
def test_an_old_generic_name_no_longer_imports(tmp_path, name):
    # from an empty folder: only what is installed can be found
    r = subprocess.run([sys.executable, "-c", f"import {name}"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert f"No module named '{name}'" in r.stderr


def test_a_users_own_planner_module_does_not_shadow_ours(tmp_path):
    (tmp_path / "planner.py").write_text("raise SystemExit('the user\\'s planner.py')\n")
    code = "import arduinobot.planner as p; print(p.__name__)"
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "arduinobot.planner"


def test_the_public_faces_come_from_the_one_name_without_loading_the_stack(tmp_path):
    code = ("import sys, arduinobot\n"
            "heavy = ('zenoh', 'ompl', 'fcl', 'numba', 'toppra', 'ruckig')\n"
            "print(sorted(m for m in heavy if m in sys.modules))\n"
            "from arduinobot import (PlannerClient, MotionPlanner, MotionRequest, JointGoal,\n"
            "    load_description, PlanningError, ServiceError, Obstacle, Code)\n"
            "print(PlannerClient.__module__, MotionPlanner.__module__, "
            "PlanningError.__module__)")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "[]"  # importing the name loads none of the planning stack
    assert lines[1].split() == ["arduinobot.client.client",
                                "arduinobot.planner.planning.pipeline",
                                "arduinobot.contract.errors"]


def test_an_unknown_public_name_is_an_attribute_error():
    import arduinobot
    with pytest.raises(AttributeError, match="NoSuchThing"):
        arduinobot.NoSuchThing  # noqa: B018
    assert set(arduinobot.__all__) <= set(dir(arduinobot))
