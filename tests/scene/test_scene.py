import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.obstacles import Obstacle, validate_obstacles


def test_box_needs_positive_size_and_names_field():
    with pytest.raises(InvalidRequest) as e:
        Obstacle("t", "box", size=(1, 0, 1), where="obstacles[2]")
    assert e.value.field == "obstacles[2].size"


def test_from_mapping_rejects_unknown_and_bad_shape():
    with pytest.raises(InvalidRequest) as e:
        Obstacle.from_mapping({"id": "a", "shape": "cone"}, where="obstacles[0]")
    assert e.value.field == "obstacles[0].shape"
    with pytest.raises(InvalidRequest):
        Obstacle.from_mapping({"id": "a", "shape": "sphere", "radius": 1, "colour": 3})
    o = Obstacle.from_mapping({"id": "a", "shape": "cylinder", "radius": 0.1, "length": 1})
    assert o.length == 1.0 and o.pose().shape == (4, 4)


def test_duplicate_and_link_ids():
    a = Obstacle("a", "sphere", radius=0.1)
    with pytest.raises(InvalidRequest):
        validate_obstacles([a, a])
    with pytest.raises(InvalidRequest):
        validate_obstacles([Obstacle("base_link", "sphere", radius=0.1)], link_names=["base_link"])
