"""Runs HPP (hpp-python 9) on the peer benchmark's problems; JSON in (stdin), JSON out (file).

Runs inside .bench-venvs/hpp (cmeel wheels, their own pinocchio and coal), started by
bench/_lib/hpp_venv.py with ``LD_LIBRARY_PATH`` holding the venv's ``cmeel.prefix/lib``.
Uses only HPP's own stack: a ``pyhpp.pinocchio.Device`` loaded from our URDF and SRDF
(``urdf.loadModel``, root joint ``anchor``; mesh paths made absolute), the obstacles as a
second model of fixed links (boxes, spheres, cylinders) anchored in the same device, a
``pyhpp.core.Problem`` whose path validation is ``Progressive`` (continuous: a distance
lower bound and a velocity bound per link, with ``tolerance`` [m] of allowed penetration)
or ``Dichotomy``, ``BiRRTPlanner`` with the time budget, then ``RandomShortcut`` with
what is left of it, at most ``OPTIMISE_S`` (1 s: it shortcuts until its time out).
Timed: solve and optimise (the device and the problem are built before each run, untimed).

Input: {"urdf", "srdf", "joints": [name, ...], "validation": "Progressive" | "Dichotomy",
"tolerance", "optimise": bool, "problems": {name: {"obstacles": [{"id", "shape", "size" |
"radius" (, "length"), "xyz", "rpy"}], "runs": [{"start": [..], "goal": [..],
"planning_time"}]}}, "output": path}. Output: {"config_size", "problems": {name: [{"success",
"status", "solve_s", "optimise_s", "total_s", "path": [[..], ...] (the straight pieces'
ends)}]}}.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time

import numpy as np
from pinocchio import SE3
from pyhpp.core import BiRRTPlanner, Dichotomy, Problem, Progressive, RandomShortcut
from pyhpp.pinocchio import Device, urdf

OPTIMISE_S = 1.0  # [s] RandomShortcut's time out at most (it runs until then)


def _geometry(o: dict) -> str:
    if o["shape"] == "box":
        return '<box size="{} {} {}"/>'.format(*o["size"])
    if o["shape"] == "sphere":
        return f'<sphere radius="{o["radius"]}"/>'
    if o["shape"] == "cylinder":
        return f'<cylinder radius="{o["radius"]}" length="{o["length"]}"/>'
    raise ValueError(f"obstacle shape {o['shape']!r} not supported here")


def obstacles_urdf(obstacles: list[dict]) -> str:
    """The obstacles as links of one fixed model (each on a fixed joint at its pose)."""
    links, joints = ['<link name="env_root"/>'], []
    for i, o in enumerate(obstacles):
        name = f"obs{i}_{re.sub(r'[^A-Za-z0-9_]', '_', o['id'])}"
        g = _geometry(o)
        links.append(f'<link name="{name}"><collision><geometry>{g}</geometry></collision>'
                     f'<visual><geometry>{g}</geometry></visual></link>')
        joints.append(f'<joint name="{name}_joint" type="fixed"><parent link="env_root"/>'
                      f'<child link="{name}"/><origin xyz="{" ".join(map(str, o["xyz"]))}" '
                      f'rpy="{" ".join(map(str, o.get("rpy", (0, 0, 0))))}"/></joint>')
    return '<robot name="env">' + "".join(links + joints) + "</robot>"


def robot_urdf(path: str) -> str:
    """Our URDF with its relative mesh paths made absolute (pinocchio's parser would read
    them relative to the working folder)."""
    folder = os.path.dirname(os.path.abspath(path))
    text = open(path).read()
    return re.sub(r'filename="(?!/)([^"]+)"',
                  lambda m: f'filename="{os.path.join(folder, m.group(1))}"', text)


def build(spec: dict, obstacles: list[dict], robot_text: str) -> tuple[Device, Problem]:
    robot = Device("bench")
    urdf.loadModelFromString(robot, 0, "robot", "anchor", robot_text,
                             open(spec["srdf"]).read(), SE3.Identity())
    if obstacles:
        urdf.loadModelFromString(robot, 0, "env", "anchor", obstacles_urdf(obstacles),
                                 '<robot name="env"/>', SE3.Identity())
    problem = Problem(robot)
    kind = Progressive if spec.get("validation", "Progressive") == "Progressive" else Dichotomy
    problem.pathValidation(kind(robot, float(spec["tolerance"])))  # a setter, not a field
    return robot, problem


def waypoints(path: object) -> list[list[float]]:
    """The ends of the straight pieces of a path (vectors of vectors walked through)."""
    out: list[list[float]] = []

    def walk(p: object) -> None:
        if hasattr(p, "numberPaths"):
            for i in range(p.numberPaths()):
                walk(p.pathAtRank(i))
        else:
            out.append(list(map(float, p.initial())))  # type: ignore[attr-defined]

    walk(path)
    return out + [list(map(float, path.end()))]  # type: ignore[attr-defined]


def solve(spec: dict, obstacles: list[dict], run: dict, robot_text: str) -> dict:
    robot, problem = build(spec, obstacles, robot_text)
    problem.initConfig(np.array(run["start"], float))
    problem.addGoalConfig(np.array(run["goal"], float))
    planner = BiRRTPlanner(problem)
    planner.timeOut(float(run["planning_time"]))
    planner.maxIterations(10**9)
    t0 = time.perf_counter()
    try:
        path = planner.solve()
    except Exception as e:  # HPP reports a time-out or no path as an exception
        t1 = time.perf_counter()
        return {"success": False, "status": f"{type(e).__name__}: {str(e)[:200]}",
                "solve_s": t1 - t0, "optimise_s": 0.0, "total_s": t1 - t0}
    t1 = time.perf_counter()
    out = path
    if spec.get("optimise", True):
        opt = RandomShortcut(problem)
        # what is left of the budget, at most OPTIMISE_S: it shortcuts until its time out
        opt.timeOut(max(0.05, min(OPTIMISE_S, float(run["planning_time"]) - (t1 - t0))))
        out = opt.optimize(path)
    t2 = time.perf_counter()
    return {"success": True, "status": "solved", "solve_s": t1 - t0, "optimise_s": t2 - t1,
            "total_s": t2 - t0, "path": waypoints(out)}


def main() -> None:
    spec = json.load(sys.stdin)
    text = robot_urdf(spec["urdf"])
    robot, _ = build(spec, [], text)
    out: dict = {"config_size": int(robot.configSize()), "problems": {}}
    if out["config_size"] != len(spec["joints"]):
        raise RuntimeError(f"HPP's configuration has {out['config_size']} values, "
                           f"not one per joint of {spec['joints']}")
    for name, body in spec["problems"].items():
        out["problems"][name] = [solve(spec, body["obstacles"], r, text) for r in body["runs"]]
        print(name, [r["status"] for r in out["problems"][name]], file=sys.stderr, flush=True)
    with open(spec["output"], "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
