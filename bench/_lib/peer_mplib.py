"""MPlib's side of the peer benchmark (bench/peer.py): its plans and a check of its model.

MPlib 0.2.1 runs in its own venv (numpy 1.x) through bench/_lib/mplib_runner.py
(bench/_lib/mplib_venv.py creates the venv on demand); its trajectories are rebuilt from its
toppra data by ``MplibTiming`` for the re-check.
"""

from __future__ import annotations

import argparse
import re
import statistics
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.planner.kinematics.limits import JointLimits
from arduinobot.planner.planning.pipeline import MotionPlanner

from .mplib_venv import MplibTiming, run_mplib
from .peer_models import PeerModel
from .recheck import Limits
from .scenes import SCENES, obstacle_dicts

ARM = ("joint_1", "joint_2", "joint_3")
# --group all: MPlib's move group is the chain to one link; the nearest to ours ends at the
# right finger (joint_4's child), the left finger (the mimic joint_5) held at its start
ALL = ("joint_1", "joint_2", "joint_3", "joint_4")
PROBLEM = {"arm": "MPlib, joints 1-3, gripper closed (ours too)",
           "all": "MPlib, joints 1-4, left finger held at its start (ours: it follows joint_4)"}


def base_spec(model: PeerModel, output: Path, *, group: str = "arm") -> dict[str, Any]:
    return {"urdf": str(model.urdf), "srdf": str(model.srdf),
            "move_group": move_group_link(model, group), "output": str(output), "scenes": {}}


def move_group_link(model: PeerModel, group: str) -> str:
    """The link MPlib's move group ends at: the arm's end for ``arm``, the right finger
    (joint_4's child) for ``all``."""
    return "claw_support" if group == "arm" else model.description.robot.joints["joint_4"].child


def mplib_start(model: PeerModel, names: tuple[str, ...], a: np.ndarray) -> dict[str, float]:
    """Our start ``a`` (over ``names``) as MPlib's joints: with each mimic joint (MPlib
    loads it as a joint of its own) at its leader's value through the mimic, so MPlib's
    start is ours."""
    start = dict(zip(names, map(float, a)))
    for j in model.description.robot.joints.values():
        if j.mimic is not None and j.mimic.joint in start:
            start[j.name] = j.mimic.multiplier * start[j.mimic.joint] + j.mimic.offset
    return start


def scale_check(model: PeerModel, mp: MotionPlanner, names: tuple[str, ...], folder: Path,
                n: int) -> dict[str, Any]:
    """``n`` random states (half colliding by our checker, gripper closed) judged by MPlib
    too: agreement shows MPlib reads the meshes at the size we do (their ``scale``)."""
    world = mp.world(())
    lim = model.description.robot.position_limits(names)
    rng = np.random.default_rng(3)
    hit, free = [], []
    for _ in range(100 * n):
        if len(hit) >= n // 2 and len(free) >= n - n // 2:
            break
        q = rng.uniform(lim[:, 0], lim[:, 1])
        q[3] = 0.0
        bucket = free if world.is_valid(q) else hit
        if len(bucket) < (n // 2 if bucket is hit else n - n // 2):
            bucket.append(q)
    states = hit + free
    spec = {**base_spec(model, folder / "mplib-states.json"),
            "state_checks": [{"joints": dict(zip(names, map(float, q)))} for q in states]}
    found = run_mplib(spec)["state_checks"]
    ours = [True] * len(hit) + [False] * len(free)
    agree = sum(o == bool(f) for o, f in zip(ours, found))
    return {"states": len(states), "agree": agree, "ours_colliding": len(hit),
            "mplib_colliding": sum(bool(f) for f in found),
            "disagreeing": [{"q": [float(v) for v in q], "ours_colliding": o, "mplib": f}
                            for q, o, f in zip(states, ours, found) if o != bool(f)][:3]}


def held_model(model: PeerModel, names: tuple[str, ...]) -> tuple[Path, tuple[str, ...]]:
    """MPlib's own robot for ``--group all``: our URDF with joint_5's ``<mimic>`` taken
    out (next to ours: the mesh paths are relative), and its actuated joints (``names``,
    ours, then joint_5)."""
    text = model.urdf.read_text()
    held, n = re.subn(r'(<joint name="joint_5".*?)<mimic [^>]*/>', r"\1", text, flags=re.S)
    if n != 1:
        raise ValueError("joint_5's <mimic> not found in the URDF")
    urdf = model.urdf.with_name(model.urdf.stem + "-left-finger-held.urdf")
    urdf.write_text(held)
    return urdf, (*names, "joint_5")


def _held(task: tuple, a: np.ndarray, names: tuple[str, ...], model: PeerModel) -> tuple:
    # ``task`` (on our robot) as on MPlib's own: joint_5 at the mimic of joint_4's start,
    # held (its limits joint_5's position range, joint_4's others)
    positions, duration, rl, obs, step = task
    j5 = model.description.robot.joints["joint_5"]
    assert j5.mimic is not None
    v5 = j5.mimic.multiplier * float(a[names.index(j5.mimic.joint)]) + j5.mimic.offset
    lo, hi = model.description.robot.position_limits(("joint_5",))[0]
    k = names.index(j5.mimic.joint)
    held = Limits(np.append(rl.lower, lo), np.append(rl.upper, hi),
                  *(np.append(getattr(rl, f), getattr(rl, f)[k])
                    for f in ("velocity", "acceleration", "jerk", "effort")))
    return (lambda ts, f=positions: np.column_stack([f(ts), np.full(len(np.atleast_1d(ts)),
                                                                    v5)]),
            duration, held, obs, step)


def mplib_rows(model: PeerModel, names: tuple[str, ...], probs_of: dict[str, list],
               lim: JointLimits, folder: Path, args: argparse.Namespace, rl: Limits
               ) -> tuple[dict[str, dict[str, Any]], dict[str, list[tuple]],
                          dict[str, list[tuple]]]:
    """MPlib on every problem: figures per scene, and re-check tasks per scene
    (positions(ts), duration [s], limits, obstacles, step [rad]) on our robot, and with
    ``--group all`` the same on MPlib's own (:func:`held_model`; else none).

    ``args.group`` ``arm``: MPlib plans joints 1-3 (the gripper closed, as ours). ``all``:
    joints 1-4 (the group to the right finger), the left finger (joint_5) at its start
    value, the mimic of joint_4's start, throughout: MPlib 0.2.1 cannot make it follow.
    Its trajectory is re-checked on our model, where joint_5 follows joint_4."""
    planned = ARM if args.group == "arm" else ALL
    spec = {**base_spec(model, folder / "mplib.json", group=args.group),
            "velocity": [float(lim.velocity[names.index(j)]) for j in planned],
            "acceleration": [float(lim.acceleration[names.index(j)]) for j in planned],
            "time_step": 0.01, "warmup": True}
    for scene, probs in probs_of.items():
        spec["scenes"][scene] = {
            "obstacles": obstacle_dicts(list(SCENES[scene])),
            "problems": [{"start": mplib_start(model, names, a),
                          "goal": dict(zip(planned, map(float, b[:len(planned)]))),
                          "planning_time": args.planning_time} for a, b, _ in probs]}
    out = run_mplib(spec)
    k = len(planned)
    if tuple(out["move_group_joints"]) != planned or tuple(out["joint_names"][:k]) != planned:
        raise RuntimeError(f"MPlib plans for {out['move_group_joints']}, not {planned}")
    rows, tasks, held = {}, {}, {}
    for scene, results in out["scenes"].items():
        obs = obstacle_dicts(list(SCENES[scene]))
        ok = [(a, r) for (a, _, _), r in zip(probs_of[scene], results) if r["success"]]
        status: dict[str, int] = {}
        for r in results:
            if not r["success"]:
                status[r["status"]] = status.get(r["status"], 0) + 1
        rebuild, scene_tasks = 0.0, []
        for a, r in ok:
            timing = MplibTiming(r, len(names), np.asarray(a, float))
            rebuild = max(rebuild, float(np.max(np.abs(
                timing.evaluate(np.array(r["sample_times"]))[0][:, :k]
                - np.array(r["sample_positions"])))))
            scene_tasks.append((lambda ts, tm=timing: tm.evaluate(ts)[0], timing.duration,
                                rl, obs, args.recheck_step))
        tasks[scene] = scene_tasks
        held[scene] = [_held(t, a, names, model) for t, (a, _) in zip(scene_tasks, ok)] \
            if args.group == "all" else []
        totals = [r["total_s"] for r in results]
        rows[scene] = {
            "problem": PROBLEM[args.group],
            "success": len(ok) / len(results), "failures": status,
            "start_valid": sum(r["start_valid"] for r in results),
            "median_ms": 1e3 * statistics.median(totals),
            "p95_ms": 1e3 * float(np.percentile(totals, 95)),
            "plan_ms_median": 1e3 * statistics.median(r["plan_s"] for r in results),
            "topp_ms_median": 1e3 * statistics.median([r["param_s"] for _, r in ok] or [0.0]),
            "duration_s_median": statistics.median([r["duration"] for _, r in ok])
            if ok else None,
            "rebuild_max_diff_rad": rebuild}
    return rows, tasks, held
