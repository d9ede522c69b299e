"""``serve``'s topics-in options as the command line reads them: refused with a one-line
reason before anything starts (a topic without --ros2, a cloud option without
--cloud-topic, a bad name, id, rate or resolution), and the extensions they ask for."""

from __future__ import annotations

import pytest

from arduinobot.cli.argtypes import UsageError
from arduinobot.cli.main import build_parser
from arduinobot.cli.ros2_options import ros2_inputs
from tests.helpers.cli import run_cli


class Lease:  # serve's node lease, never acquired here: nothing starts
    def acquire(self, session):
        raise AssertionError("no extension starts in this test")

    def release(self) -> None:
        raise AssertionError("no extension starts in this test")


def _inputs(*args: str, ros2: bool = True):
    ns = build_parser().parse_args(["serve", *(["--ros2"] if ros2 else []), *args])
    return ros2_inputs(ns, Lease() if ros2 else None)


@pytest.mark.parametrize(("args", "ros2", "words"), [
    (["--cloud-topic", "/camera/points"], False, "--cloud-topic goes with --ros2"),
    (["--camera-topic", "/c/image_raw", "--cloud-rate", "2"], False,
     "--camera-topic, --cloud-rate go with --ros2"),
    (["--cloud-id", "x"], True, "--cloud-id goes with --cloud-topic"),
    (["--cloud-topic", "/camera/points", "--cloud-rate", "0"], True, "--cloud-rate"),
    (["--cloud-topic", "/camera/points", "--cloud-rate", "25"], True, "(0, 10] Hz"),
    (["--cloud-topic", "/camera/points", "--cloud-resolution", "0.5"], True,
     "--cloud-resolution: 0.5 must be a cell edge from 0.002 to 0.1"),
    (["--cloud-topic", "/camera/points", "--cloud-id", "a b"], True, "--cloud-id 'a b'"),
    (["--cloud-topic", "/camera//points"], True, "--cloud-topic:"),
    (["--camera-topic", "~/image"], True, "--camera-topic:"),
])
def test_bad_topic_options_are_refused_in_one_line(args, ros2, words):
    with pytest.raises(UsageError) as e:
        _inputs(*args, ros2=ros2)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_the_options_ask_for_one_extension_each_and_the_camera():
    assert _inputs().extensions == () and _inputs().camera is None
    both = _inputs("--cloud-topic", "/camera/points", "--camera-topic", "/camera/image_raw")
    assert len(both.extensions) == 2 and both.camera is not None
    assert both.camera.topic == "/camera/image_raw"


def test_serve_says_so_before_it_loads_anything():
    r = run_cli("serve", "--cloud-topic", "/camera/points", timeout=120)
    assert r.returncode == 2 and "--cloud-topic goes with --ros2" in r.stderr
