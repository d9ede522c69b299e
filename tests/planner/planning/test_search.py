"""The OMPL search layer: planners offered, log level, seeds, a search's failure."""

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest, NoPathFound
from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import sampled_motion_valid
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.pathfinding.search import (
    MAX_SEED,
    PLANNERS,
    Track,
    available_planners,
    search,
    set_ompl_log_level,
)
from arduinobot.scene.obstacles import Obstacle


@pytest.fixture(scope="module")
def world():
    d = load_description()
    w = CollisionWorld(d, obstacles=[Obstacle("pillar", "box", size=(0.15, 0.15, 3.0),
                                              xyz=(0.0, 0.9, 0.6))])
    return w, d.robot.position_limits(w.kin.joint_names)


def test_a_seed_out_of_range_names_its_field():
    from arduinobot.planner.planning.pathfinding.search import check_seed

    for seed in (None, 0, MAX_SEED):
        check_seed(seed)
    for bad in (-1, MAX_SEED + 1, True, 1.0, "7"):
        with pytest.raises(InvalidRequest) as e:
            check_seed(bad, "steps[2].seed")
        assert e.value.field == "steps[2].seed" and "4294967295" in e.value.message


def test_the_planners_offered_are_ompls():
    offered = available_planners()
    assert "RRTConnect" in offered and set(offered) <= set(PLANNERS)


def test_a_log_level_not_offered_names_the_field():
    with pytest.raises(InvalidRequest) as e:
        set_ompl_log_level("loud")  # type: ignore[arg-type]
    assert e.value.field == "level"
    set_ompl_log_level("none")


def _search(world, seed, *, budget=1.0, goal=(-1.2, -0.6, -0.6, 0.0)):
    w, lim = world
    start = np.array([1.2, -0.6, -0.6, 0.0])
    return search([_track(w, start, goal)], np.array([0, 1, 2]), lim, planner="RRTConnect",
                  seed=seed, budget=budget, planning_time=budget).path


def _track(w, start, goal, turns=None):
    return Track(w, lambda a, b: sampled_motion_valid(w, a, b, 0.02), np.asarray(start),
                 np.array([goal]), turns=turns)


@pytest.mark.parametrize("seed", [0, 5, MAX_SEED])
def test_a_seeded_search_repeats_itself(world, seed):
    a = _search(world, seed)
    _search(world, 99)  # another search in between draws from OMPL's generator
    b = _search(world, seed)
    assert np.array_equal(a, b)
    assert np.allclose(a[0], [1.2, -0.6, -0.6, 0.0]) and np.allclose(a[-1, :3], [-1.2, -0.6, -0.6])
    assert np.all(a[:, 3] == 0.0)  # the joint outside the columns keeps the start's value


def test_no_path_is_an_error_not_an_approximation(world):
    w, _ = world
    inside = (0.0, 0.0, 0.0, 0.0)  # upright, in the pillar: never reached
    assert not w.is_valid(np.array(inside))
    with pytest.raises(NoPathFound) as e:
        _search(world, 1, budget=0.05, goal=inside)
    assert e.value.details["planner"] == "RRTConnect"


def test_the_slices_take_turns_and_name_the_planner_that_found_the_path(world):
    # a first slice of one iteration cannot reach round the pillar: the fallback's turn
    # comes, then the asked planner's again with twice the iterations, and so on; the
    # path found is named by the planner whose tree reached the goal, and it is seeded
    w, lim = world
    start = np.array([1.2, -0.6, -0.6, 0.0])

    def run():
        return search([_track(w, start, (-1.2, -0.6, -0.6, 0.0))], np.array([0, 1, 2]), lim,
                      planner="RRTConnect", seed=3, budget=10.0, planning_time=10.0,
                      first_slice=1)
    a, b = run(), run()
    assert a.rounds > 1 and a.planner in ("RRTConnect", "BKPIECE1")
    assert a.rounds == b.rounds and a.planner == b.planner and np.array_equal(a.path, b.path)


def test_a_tracks_turns_end_the_search_with_its_count(world):
    w, lim = world
    with pytest.raises(NoPathFound) as e:
        search([_track(w, (1.2, -0.6, -0.6, 0.0), (-1.2, -0.6, -0.6, 0.0), turns=2)],
               np.array([0, 1, 2]), lim, planner="RRTConnect", seed=3, budget=10.0,
               planning_time=10.0, first_slice=1)
    assert e.value.details["rounds"] == 2
    assert e.value.details["planners"] == ["RRTConnect", "BKPIECE1"]


def test_tracks_take_turns_within_each_planners_turn(world):
    # a track with two turns that can never reach its goal (in the pillar) and an open
    # one: the open track's first slice comes before the closed track's second planner,
    # so with slices too short for the fallback to matter the path is found in round 2
    # (track 1, the asked planner), and the search repeats itself
    w, lim = world
    start = (1.2, -0.6, -0.6, 0.0)
    closed = _track(w, start, (0.0, 0.0, 0.0, 0.0), turns=2)
    opened = _track(w, start, (-1.2, -0.6, -0.6, 0.0))

    def run():
        return search([closed, opened], np.array([0, 1, 2]), lim, planner="RRTConnect",
                      seed=4, budget=10.0, planning_time=10.0)
    a, b = run(), run()
    assert a.track == 1 and a.planner == "RRTConnect" and a.rounds == 2
    assert a.rounds == b.rounds and np.array_equal(a.path, b.path)
    assert np.allclose(a.path[-1, :3], [-1.2, -0.6, -0.6])
