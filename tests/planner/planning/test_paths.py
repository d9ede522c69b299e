import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest, NoPathFound, StartInCollision
from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.planner.planning.pathfinding.paths import PROOF_REPLANS, PathPlanner, PathRequest
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.planning_scenes import SPLIT, SPLIT_GOAL, SPLIT_START

PILLAR = Obstacle("pillar", "box", size=(0.15, 0.15, 3.0), xyz=(0.0, 0.9, 0.6))


@pytest.fixture(scope="module")
def env():
    d = load_description()
    w = CollisionWorld(d, obstacles=[PILLAR])
    return d, w, PathPlanner(w, d)


GOAL = JointGoal({"joint_1": -1.2, "joint_2": -0.6, "joint_3": -0.6})
START = np.array([1.2, -0.6, -0.6, 0.0])


def test_straight_line(env):
    d, _, _ = env
    pp = PathPlanner(CollisionWorld(d), d)
    r = pp.solve(PathRequest(start=np.zeros(4), goal=NamedGoal("reach_forward"), seed=1))
    assert r.straight_line and r.path.shape == (2, 4) and r.planner == "straight line"


def test_detour_is_collision_free_densely(env):
    _, w, pp = env
    assert w.first_invalid(interpolate(np.array([START, GOAL_Q()]), 0.002)) >= 0
    r = pp.solve(PathRequest(start=START, goal=GOAL, seed=7))
    assert not r.straight_line and r.planner == "RRTConnect"
    assert np.allclose(r.path[0], START) and np.allclose(r.path[-1], GOAL_Q())
    assert w.first_invalid(interpolate(r.path, 0.0005)) == -1
    assert set(r.timings) == {"validate", "straight_line", "plan", "simplify", "recheck"}
    assert r.checks > 0 and r.length > 0


def GOAL_Q():
    return np.array([-1.2, -0.6, -0.6, 0.0])


def test_seed_makes_results_reproducible(env):
    _, _, pp = env
    a = pp.solve(PathRequest(start=START, goal=GOAL, seed=11))
    b = pp.solve(PathRequest(start=START, goal=GOAL, seed=11))
    assert np.array_equal(a.path, b.path)


def test_seed_zero_is_a_seed_too(env):
    # OMPL ignores a seed of 0 (its generator goes on from where it was): 0 must not
    _, _, pp = env
    a = pp.solve(PathRequest(start=START, goal=GOAL, seed=0))
    b = pp.solve(PathRequest(start=START, goal=GOAL, seed=0))
    assert np.array_equal(a.path, b.path)


def test_seed_beyond_32_bits_names_the_field(env):
    _, _, pp = env
    with pytest.raises(InvalidRequest) as e:
        pp.solve(PathRequest(start=START, goal=GOAL, seed=2**32))
    assert e.value.field == "seed" and "4294967295" in str(e.value)


@pytest.mark.parametrize("name", ["RRT", "PRM", "KPIECE1", "LBKPIECE1", "BITstar"])
def test_other_planners(env, name):
    _, w, pp = env
    r = pp.solve(PathRequest(start=START, goal=GOAL, planner=name, seed=3, planning_time=2.0))
    assert r.planner == name and w.first_invalid(interpolate(r.path, 0.002)) == -1


def test_errors(env):
    _, _, pp = env
    with pytest.raises(InvalidRequest) as e:
        pp.solve(PathRequest(start=START, goal=GOAL, planner="Nope"))
    assert e.value.field == "planner"
    with pytest.raises(InvalidRequest):
        pp.solve(PathRequest(start=START, goal=GOAL, group="legs"))  # type: ignore[arg-type]
    with pytest.raises(StartInCollision) as e:
        pp.solve(PathRequest(start=np.array([0, -1.5, -1.0, 0.0]), goal=GOAL))
    assert e.value.pairs


def test_no_path_found(env):
    # a free start and a free goal on either side of a wall the arm cannot pass (see
    # tests/helpers/planning_scenes.py): the planner says NoPathFound, nothing else
    d, _, _ = env
    w = CollisionWorld(d, obstacles=list(SPLIT))
    start = np.array([SPLIT_START[n] for n in w.kin.joint_names])
    goal = start.copy()
    goal[:3] = [SPLIT_GOAL[n] for n in ("joint_1", "joint_2", "joint_3")]
    assert w.check(start).valid and w.check(goal).valid
    # the premise: every state with joint_1 = 0 (which any motion between them passes)
    # collides, so no planner could find a path
    lim = d.robot.position_limits(w.kin.joint_names)
    qs = np.random.default_rng(0).uniform(lim[:, 0], lim[:, 1], (2000, 4))
    qs[:, 0] = 0.0
    assert not any(w.is_valid(q) for q in qs)
    with pytest.raises(NoPathFound) as e:
        PathPlanner(w, d).solve(PathRequest(start=start, goal=JointGoal(SPLIT_GOAL),
                                            planning_time=0.2, seed=1))
    assert e.value.code == "NO_PATH_FOUND"


def test_detours_keep_room_where_the_ends_allow(env):
    # the start grazes the pillar (inside the room): a short free edge leaves it, the
    # rest of the detour keeps the room, and the whole path is certified
    d, w, pp = env
    roomy = pp.roomy(("joint_1", "joint_2", "joint_3"))
    assert roomy.padding == pytest.approx(w.padding + pp.room) and not roomy.narrow_phase
    # pillar pairs only: the fingers do not move relative to each other in the arm group
    assert ("gripper_right", "gripper_left") not in roomy.pair_names
    near = None
    for a in np.linspace(1.2, 0.0, 600):
        q = np.array([a, -0.6, -0.6, 0.0])
        if not w.is_valid(q):
            break
        near = q
    assert near is not None and not roomy.is_valid(near)
    r = pp.solve(PathRequest(start=near, goal=GOAL, seed=5))
    assert not r.straight_line and r.certificate.free
    assert np.array_equal(r.path[0], near) and np.allclose(r.path[-1], GOAL_Q())
    assert all(roomy.is_valid(q) for q in r.path[1:])
    assert roomy.first_invalid(interpolate(r.path[1:], 0.01)) == -1
    strict = PathPlanner(w, d, room=0.0).solve(PathRequest(start=near, goal=GOAL, seed=5))
    assert strict.certificate.free
    # the room shows in the proof: a path that keeps it needs fewer exact distances
    assert r.certificate.exact <= strict.certificate.exact


def test_a_spent_proof_budget_plans_again_and_still_certifies(env, caplog):
    # no budget at all for the found path's proof: a path whose proof needs one near
    # stop (this one starts grazing the pillar) is refused at that edge, planned again,
    # and past PROOF_REPLANS planned by the finer planner (its own budgets): what comes
    # back is certified, and no contact shows at 0.002 rad
    d, w, _ = env
    near = None
    for a in np.linspace(1.2, 0.0, 600):
        q = np.array([a, -0.6, -0.6, 0.0])
        if not w.is_valid(q):
            break
        near = q
    pp = PathPlanner(w, d, room=0.0, proof_budget=(0, 0))
    with caplog.at_level("INFO", logger="arduinobot.planner.planning.pathfinding.paths"):
        r = pp.solve(PathRequest(start=near, goal=GOAL, seed=5))
    spent = [m for m in caplog.messages if m.startswith("path not certified") and "nan" in m]
    assert len(spent) == PROOF_REPLANS + 1
    assert r.certificate is not None and r.certificate.free
    assert np.array_equal(r.path[0], near) and np.allclose(r.path[-1], GOAL_Q())
    assert w.first_invalid(interpolate(r.path, 0.002)) == -1
