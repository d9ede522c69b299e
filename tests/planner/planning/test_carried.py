"""Objects the gripper carries (issue 28 item 2): a carried box is checked against the
scene along the whole motion (an independent FCL check of the box at its link's pose
every 0.002 rad of the returned trajectory), and a payload's mass enters the effort
check (an independent inverse dynamics, MuJoCo with the payload as a body, within the
limit on every sample; never faster than without it). On the shipped arm and on the
course-like workspace."""

from __future__ import annotations

import re

import fcl
import mujoco
import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest, StartInCollision
from arduinobot.description import load_description
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.scene.obstacles import AttachedObject, Obstacle, default_touch_links
from tests.helpers.carry import CarryCase, shipped_case
from tests.helpers.fk import link_pose
from tests.planner.kinematics.test_dynamics import to_mjcf

PAYLOAD = 0.2  # [kg]


def _dense(positions: np.ndarray, step: float = 0.002) -> np.ndarray:
    # the trajectory's samples with straight pieces between them cut so that no joint
    # moves more than ``step`` [rad] from one state to the next
    out = [positions[:1]]
    for a, b in zip(positions[:-1], positions[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        out.append(a + np.outer(np.arange(1, n + 1) / n, b - a))
    return np.concatenate(out)


def _box_hits(description, names, positions, box: Obstacle, link: str,
              table: Obstacle) -> int:
    # FCL on the carried box at its link's pose against the table, state by state
    tb = table.pose()
    table_obj = fcl.CollisionObject(fcl.Box(*table.size), fcl.Transform(tb[:3, :3], tb[:3, 3]))
    box_obj = fcl.CollisionObject(fcl.Box(*box.size), fcl.Transform())
    offset = box.pose()
    hits = 0
    for q in _dense(positions):
        t = link_pose(description.robot, link, names, q) @ offset
        box_obj.setRotation(t[:3, :3])
        box_obj.setTranslation(t[:3, 3])
        hits += fcl.collide(box_obj, table_obj, fcl.CollisionRequest(), fcl.CollisionResult()) > 0
    return hits


def _with_payload(robot, link: str, mass: float, com, inertia) -> mujoco.MjModel:
    # MuJoCo's model of the arm with the payload as a body welded inside ``link``'s
    xml = to_mjcf(robot)
    full = " ".join(repr(float(v)) for v in (inertia[0][0], inertia[1][1], inertia[2][2],
                                             inertia[0][1], inertia[0][2], inertia[1][2]))
    pos = " ".join(repr(float(v)) for v in com)
    payload = (f'<body name="payload"><inertial pos="{pos}" mass="{mass!r}" '
               f'fullinertia="{full}"/></body>')
    xml, n = re.subn(rf'(<body name="{link}"[^>]*>)', rf"\1{payload}", xml)
    assert n == 1
    return mujoco.MjModel.from_xml_string(xml)


def _mujoco_efforts(model: mujoco.MjModel, robot, names, traj) -> np.ndarray:
    data = mujoco.MjData(model)
    cols = []
    for d in range(model.nv):
        j = robot.joints[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT,
                                           model.dof_jntid[d])]
        leader, mult, off = (j.mimic.joint, j.mimic.multiplier, j.mimic.offset) \
            if j.mimic else (j.name, 1.0, 0.0)
        cols.append((names.index(leader), mult, off))
    out = np.zeros((len(traj.positions), len(names)))
    for k, (q, qd, qdd) in enumerate(zip(traj.positions, traj.velocities,
                                         traj.accelerations)):
        for d, (i, mult, off) in enumerate(cols):
            data.qpos[d] = mult * q[i] + off
            data.qvel[d] = mult * qd[i]
            data.qacc[d] = mult * qdd[i]
        mujoco.mj_inverse(model, data)
        for d, (i, mult, _) in enumerate(cols):
            out[k, i] += mult * data.qfrc_inverse[d]
    return out


@pytest.fixture(scope="module")
def shipped():
    return shipped_case()


@pytest.fixture(scope="module")
def course(course_ws):
    return CarryCase(load_description(course_ws.xacro, package_dirs=[course_ws.src], env={}),
                 load_description(env={}).tcp)


@pytest.fixture(params=["shipped", "course"])
def case(request):
    return request.getfixturevalue(request.param)


def test_the_direct_swing_is_free_without_the_box_and_not_with_it(case):
    bare = case.mp.context.world((case.table,))
    held = case.mp.context.world((case.table,), (case.attached(),))
    line = np.zeros((41, len(case.names)))
    line[:, 0] = np.linspace(-0.8, 0.8, 41)
    assert bare.first_invalid(line) == -1
    assert held.first_invalid(line) >= 0
    # the independent check agrees: the box sweeps through the table on the direct way
    assert _box_hits(case.d, case.names, line, case.box, case.link, case.table) > 0
    assert held.check(line[0]).valid and held.check(line[-1]).valid


def test_a_carried_box_is_planned_around_the_table(case):
    res = case.mp.solve(case.request([case.attached()]))
    traj = res.trajectory
    assert res.verification.ok
    assert np.allclose(traj.positions[-1][0], 0.8, atol=1e-3)
    assert _box_hits(case.d, case.names, np.asarray(traj.positions), case.box, case.link,
                     case.table) == 0
    # the same request for the bare arm swings straight through where the box would hit
    bare = case.mp.solve(case.request())
    assert _box_hits(case.d, case.names, np.asarray(bare.trajectory.positions), case.box,
                     case.link, case.table) > 0


@pytest.mark.parametrize("profile", ["jerk_limited", "time_optimal"])
def test_a_payload_is_within_the_effort_limit_by_mujoco_and_never_faster(case, profile):
    att = case.attached(PAYLOAD)
    res = case.mp.solve(case.request([att], profile=profile))
    light = case.mp.solve(case.request([case.attached()], profile=profile))
    p = att.payload()
    model = _with_payload(case.d.robot, case.link, p.mass, p.com, p.inertia)
    tau = _mujoco_efforts(model, case.d.robot, case.names, res.trajectory)
    effort = case.mp.context.limits(1.0, 1.0).effort
    assert np.all(np.abs(tau) <= effort * (1 + 1e-6)), np.abs(tau).max(0)
    # the payload is in the reply's efforts (they are MuJoCo's with the payload)
    assert np.allclose(np.asarray(res.trajectory.efforts), tau, atol=1e-6 * effort.max())
    assert res.trajectory.duration >= light.trajectory.duration - 1e-9


def test_a_heavy_payload_slows_the_motion_within_the_effort_limit(shipped):
    # heavy enough that the effort limit binds: slower, and MuJoCo agrees it is within
    free = MotionRequest(goal=JointGoal({"joint_1": 0.8, "joint_2": 0.6}),
                         start={"joint_1": -0.8}, profile="time_optimal", seed=3)
    held = AttachedObject(Obstacle("weight", "sphere", radius=0.05,
                                   xyz=shipped.tcp.xyz), shipped.link, mass=2.0)
    light = shipped.mp.solve(free)
    heavy = shipped.mp.solve(MotionRequest(**{**free.__dict__, "attached": (held,)}))
    p = held.payload()
    model = _with_payload(shipped.d.robot, shipped.link, p.mass, p.com, p.inertia)
    tau = _mujoco_efforts(model, shipped.d.robot, shipped.names, heavy.trajectory)
    effort = shipped.mp.context.limits(1.0, 1.0).effort
    assert np.all(np.abs(tau) <= effort * (1 + 1e-6))
    bare_tau = _mujoco_efforts(_with_payload(shipped.d.robot, shipped.link, p.mass, p.com,
                                             p.inertia), shipped.d.robot, shipped.names,
                               light.trajectory)
    if np.abs(bare_tau).max() > effort.max():  # the light timing would overload the servos
        assert heavy.trajectory.duration > light.trajectory.duration
    assert heavy.trajectory.duration >= light.trajectory.duration - 1e-9


def test_touch_links_default_to_the_end_effector_and_are_not_checked(shipped):
    touch = default_touch_links(shipped.d, "claw_support")
    assert set(touch) == {"claw_support", "gripper_right", "gripper_left"}
    w = shipped.mp.context.world((), (shipped.attached(),))
    pairs = {frozenset(p) for p in w.pair_names}
    assert not any(frozenset(("carried_box", t)) in pairs for t in touch)
    assert frozenset(("carried_box", "base_link")) in pairs


def test_bad_carried_objects_are_refused_naming_the_field(shipped):
    with pytest.raises(InvalidRequest) as e:
        shipped.mp.solve(shipped.request([AttachedObject(shipped.box, "no_such_link")]))
    assert e.value.field == "attached[0].link"
    with pytest.raises(InvalidRequest) as e:
        shipped.mp.solve(shipped.request([AttachedObject(shipped.box, shipped.link,
                                                         touch_links=("nope",))]))
    assert e.value.field == "attached[0].touch_links"
    clash = Obstacle("table", "sphere", radius=0.01)
    with pytest.raises(InvalidRequest) as e:
        shipped.mp.solve(shipped.request([AttachedObject(clash, shipped.link)]))
    assert e.value.field == "attached[0].object.id"
    with pytest.raises(InvalidRequest) as e:
        AttachedObject.from_mapping({"object": {"id": "b", "shape": "box",
                                                "size": [1, 1, 1]},
                                     "link": "claw_support", "mass": -1})
    assert e.value.field == "attached.mass"


def test_a_start_where_the_carried_box_is_in_the_table_is_refused(shipped):
    req = MotionRequest(goal=shipped.goal, start={"joint_1": 0.0}, obstacles=(shipped.table,),
                        attached=(shipped.attached(),), seed=1)
    with pytest.raises(StartInCollision) as e:
        shipped.mp.solve(req)
    assert {frozenset(p) for p in e.value.pairs} >= {frozenset(("carried_box", "table"))}


def test_a_plan_request_on_the_wire_carries_attached_for_itself(shipped):
    import json

    from arduinobot.contract import wire
    from arduinobot.service.plan.plan_io import plan_request, plan_response

    t = shipped.table
    item = shipped.attached(PAYLOAD).to_mapping()
    data = {"start": {"joint_1": -0.8}, "goal": {"joints": {"joint_1": 0.8}}, "seed": 3,
            "planning_time": 5.0,
            "obstacles": [{"id": t.id, "shape": "box", "size": list(t.size), "xyz": list(t.xyz)}],
            "attached": [item]}
    req = plan_request(shipped.d, wire.decode("plan", json.dumps(data)))
    (a,) = req.attached
    assert a.link == shipped.link and a.mass == PAYLOAD and a.id == "carried_box"
    assert set(a.touch_links) == {"claw_support", "gripper_right", "gripper_left"}
    body = plan_response(shipped.mp.solve(req))
    qs = np.array([p["positions"] for p in body["trajectory"]["points"]])
    assert _box_hits(shipped.d, shipped.names, qs, shipped.box, shipped.link, t) == 0
    bad = {**data, "attached": [{**item, "link": "no_such_link"}]}
    with pytest.raises(InvalidRequest) as e:
        plan_request(shipped.d, wire.decode("plan", json.dumps(bad)))
    assert e.value.field == "attached[0].link"
    with pytest.raises(InvalidRequest) as e:  # the schema: unknown keys are refused
        wire.decode("plan", json.dumps({**data, "attached": [{**item, "weight": 1}]}))


def test_a_check_reports_the_carried_box_pose_and_its_contact(shipped):
    import json

    from arduinobot.contract import wire
    from arduinobot.service.plan.handlers import Handlers

    t = shipped.table
    h = Handlers(shipped.d)
    data = {"joints": {"joint_1": 0.0},
            "obstacles": [{"id": t.id, "shape": "box", "size": list(t.size), "xyz": list(t.xyz)}],
            "attached": [shipped.attached().to_mapping()]}
    reply = h.check(wire.decode("check", json.dumps(data)))
    assert not reply["valid"]
    assert ["carried_box", "table"] in reply["pairs"] or ["table", "carried_box"] in reply["pairs"]
    pose = np.array(reply["carried"]["carried_box"]["matrix"])
    want = link_pose(shipped.d.robot, shipped.link, shipped.names,
                      np.zeros(len(shipped.names))) @ shipped.box.pose()
    assert np.allclose(pose, want, atol=1e-9)
    free = h.check(wire.decode("check", json.dumps({**data, "joints": {"joint_1": -0.8}})))
    assert free["valid"] and "carried_box" in free["carried"]
