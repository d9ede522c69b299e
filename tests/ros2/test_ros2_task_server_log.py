"""``serve --ros2`` says what its /task_server serves (issue 38, item 7): the action and
the task numbers it runs, or, for a robot without a tasks.yaml, a warning that every
goal will be rejected (before: nothing at all, every goal rejected in silence)."""

from __future__ import annotations

import pytest

from tests.helpers.serve import start_server
from tests.helpers.so101 import make_so101


@pytest.mark.slow
def test_serve_ros2_names_the_task_server_and_its_tasks():
    srv = start_server(["--workers", "1", "--ros2", "--ros-domain-id", "11"])
    try:
        before = "\n".join(srv.stderr_lines)
    finally:
        srv.stop()
    assert "task_server" in before and "runs task numbers 0, 1, 2" in before, before
    assert "will reject every goal" not in before, before


@pytest.mark.slow
def test_serve_ros2_without_tasks_warns_every_goal_will_be_rejected(tmp_path):
    urdf = make_so101(tmp_path, name="my_arm")  # no shipped config: no tasks.yaml
    srv = start_server([str(urdf), "--workers", "1", "--ros2", "--ros-domain-id", "12"])
    try:
        before = "\n".join(srv.stderr_lines)
    finally:
        srv.stop()
    assert "WARNING" in before and "task_server will reject every goal" in before, before
    assert "robot 'my_arm' has no tasks.yaml" in before, before
