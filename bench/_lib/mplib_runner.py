"""Runs MPlib 0.2 on the trajectory benchmark's problems; JSON in (stdin), JSON out (stdout).

Runs inside .bench-venvs/mplib (MPlib pins numpy 1.x), started by bench/_lib/mplib_venv.py.
Uses only MPlib's own stack: ``mplib.Planner`` on our expanded URDF and SRDF, its OMPL
RRTConnect (``planner.planner.plan``, default range and simplification) with the given
time budget, and its TOPP-RA parameterisation (``Planner.TOPP``, velocity and
acceleration limits only) at the sample step we use (10 ms). This is the body of
``Planner.plan_qpos`` split in two so plan and parameterisation are timed separately.

Not timed, afterwards: toppra is run again on the same input exactly as ``TOPP`` does, to
return its gridpoints and path velocities, from which the caller rebuilds the continuous
trajectory (toppra's ``ParametrizeConstAccel`` on its ``SplineInterpolator``) for the
verifiers; MPlib's own samples are returned too, to confirm the rebuild matches.

Input: {"urdf", "srdf", "move_group", "velocity": [..], "acceleration": [..],
"time_step", "warmup": bool, optionally "rrt_range" (OMPL RRTConnect's range, default 0.1),
"scenes": {name: {"obstacles": [{"id", "shape": "box" | "sphere" | "cylinder", "size" |
"radius" (, "length"), "xyz", "rpy"}], "problems": [{"start": {joint: rad}, "goal": {joint: rad},
"planning_time"}]}}, "output": path}, optionally "state_checks": [{"joints": {joint:
rad}}] (MPlib's own collision check of single states, no obstacles). Output, written to
``output`` (MPlib's C++ code prints to stdout): {"joint_names", "move_group_joints",
"scenes": {name: [result, ...]}}, and with state_checks "state_checks": [[[link, link],
...] per state] (the colliding link pairs MPlib reports).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import sys
import time

import mplib
import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint
from mplib.collision_detection import fcl


def _quat(rpy: list[float]) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r / 2), math.sin(r / 2), math.cos(p / 2),
                              math.sin(p / 2), math.cos(y / 2), math.sin(y / 2))
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def _objects(obstacles: list[dict]) -> list:
    out = []
    for o in obstacles:
        if o["shape"] == "box":
            geom = fcl.Box(*o["size"])
        elif o["shape"] == "sphere":
            geom = fcl.Sphere(o["radius"])
        elif o["shape"] == "cylinder":  # along its z axis, as ours
            geom = fcl.Cylinder(o["radius"], o["length"])
        else:
            raise ValueError(f"obstacle shape {o['shape']!r} not supported here")
        shape = fcl.CollisionObject(geom)
        pose = mplib.Pose(p=np.array(o["xyz"], float), q=_quat(o.get("rpy", [0, 0, 0])))
        out.append(fcl.FCLObject(o["id"], pose, [shape], [mplib.Pose()]))
    return out


def _toppra_data(planner: mplib.Planner, path: np.ndarray) -> tuple[list, list]:
    """What ``Planner.TOPP`` computes, kept: (gridpoints, sd) of its toppra instance."""
    ss = np.linspace(0, 1, path.shape[0])
    spline = ta.SplineInterpolator(ss, path)
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(planner.joint_vel_limits),
                        constraint.JointAccelerationConstraint(planner.joint_acc_limits)],
                       spline, parametrizer="ParametrizeConstAccel")
    inst.compute_trajectory()
    return inst.problem_data.gridpoints.tolist(), inst.problem_data.sd_vec.tolist()


def solve(planner: mplib.Planner, names: list[str], prob: dict, step: float,
          rrt_range: float = 0.1) -> dict:
    full = np.array([prob["start"].get(n, 0.0) for n in names])
    goal = np.array([prob["goal"].get(n, 0.0) for n in names])
    idx = planner.move_group_joint_indices
    quiet = io.StringIO()
    t0 = time.perf_counter()
    full = np.clip(full, planner.joint_limits[:, 0], planner.joint_limits[:, 1])
    planner.robot.set_qpos(full, True)
    with contextlib.redirect_stdout(quiet):
        start_ok = len(planner.planning_world.check_collision()) == 0
        status, path = planner.planner.plan(full[idx], [goal[idx]],
                                            time=prob["planning_time"], range=rrt_range,
                                            simplify=True)
    t1 = time.perf_counter()
    res = {"status": status, "start_valid": start_ok, "plan_s": t1 - t0}
    if status != "Exact solution":
        res.update(success=False, param_s=0.0, total_s=t1 - t0)
        return res
    ta.setup_logging("WARNING")
    try:
        ts, pos, vel, acc, dur = planner.TOPP(path, step)
    except RuntimeError as e:  # MPlib's own failure report for toppra's None
        t2 = time.perf_counter()
        res.update(success=False, status=f"TOPP: {e}", param_s=t2 - t1, total_s=t2 - t0)
        return res
    t2 = time.perf_counter()
    grid, sd = _toppra_data(planner, path)
    res.update(success=True, param_s=t2 - t1, total_s=t2 - t0, duration=float(dur),
               path=path.tolist(), gridpoints=grid, sd=sd, sample_times=ts.tolist(),
               sample_positions=pos.tolist())
    return res


def state_checks(spec: dict) -> list[list[list[str]]]:
    """MPlib's colliding link pairs at each of ``spec["state_checks"]`` (robot only)."""
    with contextlib.redirect_stdout(io.StringIO()):
        planner = mplib.Planner(spec["urdf"], spec["move_group"], srdf=spec["srdf"])
    names = list(planner.user_joint_names)
    out = []
    for check in spec["state_checks"]:
        planner.robot.set_qpos(np.array([check["joints"].get(n, 0.0) for n in names]), True)
        with contextlib.redirect_stdout(io.StringIO()):
            found = planner.planning_world.check_collision()
        out.append([[c.link_name1, c.link_name2] for c in found])
    return out


def main() -> None:
    spec = json.load(sys.stdin)
    out: dict = {"scenes": {}}
    for scene, body in spec["scenes"].items():
        with contextlib.redirect_stdout(io.StringIO()):
            planner = mplib.Planner(spec["urdf"], spec["move_group"], srdf=spec["srdf"],
                                    joint_vel_limits=spec["velocity"],
                                    joint_acc_limits=spec["acceleration"],
                                    objects=_objects(body["obstacles"]))
        names = list(planner.user_joint_names)
        out["joint_names"] = names
        out["move_group_joints"] = [names[i] for i in planner.move_group_joint_indices]
        probs = body["problems"]
        rrt_range = spec.get("rrt_range", 0.1)
        if spec.get("warmup") and probs:
            solve(planner, names, probs[0], spec["time_step"], rrt_range)  # not reported
        out["scenes"][scene] = [solve(planner, names, p, spec["time_step"], rrt_range)
                                for p in probs]
    if spec.get("state_checks"):
        out["state_checks"] = state_checks(spec)
    with open(spec["output"], "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
