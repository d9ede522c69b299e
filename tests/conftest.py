"""Shared fixtures (`arduinobot serve` as a real subprocess, a course workspace) and the
``slow`` marker.

The launcher itself is tests/helpers/serve.py (the benches use it too); test modules
import it, and every other helper, from ``tests.helpers``, never from here.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from .helpers import procs
from .helpers.serve import Server, start_server


@pytest.fixture(scope="session")
def server() -> Iterator[Server]:
    """One `arduinobot serve` (2 workers) shared by the modules that only query it."""
    srv = start_server(["--workers", "2"])
    yield srv
    srv.stop()


@pytest.fixture(scope="session")
def client(server: Server):
    from arduinobot.client.client import PlannerClient
    with PlannerClient(server.endpoint, timeout=30) as c:
        yield c


@pytest.fixture(scope="session")
def course_ws(tmp_path_factory):
    """A user's colcon workspace as ROS 2 and the MoveIt Setup Assistant leave it."""
    from .helpers.course_workspace import make_course_workspace
    return make_course_workspace(tmp_path_factory.mktemp("course_ws"))


@pytest.fixture(scope="session")
def desc():
    """The shipped arduinobot as `load_description` gives it with no environment."""
    from arduinobot.description import load_description
    return load_description(env={})


@pytest.fixture
def scene_builder(desc, tmp_path):
    """A kept scene's builder for the shipped arm (it can attach and fix objects to links)."""
    from arduinobot.planner.frames import RobotFrames
    from arduinobot.scene.builder import SceneBuilder
    return SceneBuilder(tuple(desc.robot.links), tmp_path / "meshes", robot=RobotFrames(desc))


# -- the `slow` marker: tests that start `arduinobot serve` or router processes or a browser
# (`./dev test -m "not slow"` is the quick loop; the default run, and CI, run everything).
# It is set explicitly: `@pytest.mark.slow` on a test (or `pytestmark` on a module) that
# starts one itself or through a fixture of its module, and here for every test that uses
# the shared server (the fixtures below, or any fixture built on them).
SERVER_FIXTURES = frozenset({"server"})

_LAUNCHES_BEFORE = pytest.StashKey[int]()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark ``slow`` every test whose fixtures include the shared server."""
    for item in items:
        if SERVER_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


# A net under the explicit marker: a test that is not marked but starts a serve or router
# through the launcher (tests/helpers/procs.py counts them) fails, so `-m "not slow"`
# cannot silently start processes. (A browser is not launched there: its one test is
# marked by hand.)
@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item):
    item.stash[_LAUNCHES_BEFORE] = procs.launch_count()
    return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item):
    result = yield
    started = procs.launch_count() - item.stash.get(_LAUNCHES_BEFORE, procs.launch_count())
    if started and item.get_closest_marker("slow") is None:
        pytest.fail(f"{item.nodeid} started {started} serve/router process(es) but is not "
                    "marked slow: add @pytest.mark.slow (or pytestmark) to it",
                    pytrace=False)
    return result
