"""Your own robot: a course-like ROS 2 workspace, as users bring it.

The workspace (tests/helpers/course_workspace.py): millimetre CAD meshes with open edges,
a camera on a fixed joint, a separate MoveIt package with a stale SRDF and default
scaling 0.1. Prints, then one JSON line:

1. start-up through a real ``arduinobot serve --moveit-config`` (2 workers): seconds
   from launch to the first plan answered: fresh (a machine just set up by ``./dev``,
   whose install step compiled the numba kernels, with an empty result cache), next
   (the same cache again), and without any compiled kernels (a bare ``pip install``);
2. with no SRDF at all (the MoveIt package removed), 3 scenes x N seeded problems
   in-process through the whole pipeline (plan, time, verify): success on feasible
   problems, median / p95 ms, and an independent re-check of every trajectory
   (bench/_lib/recheck.py: yourdfpy + FCL at 0.0005 rad, finite differences, MuJoCo)
   with only joint-connected link pairs allowed.

Usage: ./dev bench own_robot [N]   (default 40 problems per scene)
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import tempfile
import time
from pathlib import Path

import numpy as np

from arduinobot.client.client import PlannerClient
from arduinobot.contract.errors import PlanningError
from arduinobot.description import Description, load_description
from arduinobot.description.loader import read_model_text
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from bench._lib.args import problems_per_scene
from bench._lib.recheck import IndependentModel, Limits, recheck
from bench._lib.report import emit
from bench._lib.scenes import SCENES, obstacle_dicts, problems
from tests.helpers.course_workspace import make_course_workspace
from tests.helpers.serve import start_server

ARM = ("joint_1", "joint_2", "joint_3")


def time_to_first_plan(args: list[str], env: dict[str, str], *, limit: float = 300.0
                       ) -> float:
    """Seconds from launching ``arduinobot serve ARGS`` to its first plan answered."""
    t0 = time.perf_counter()
    srv = start_server(["--workers", "2", *args], env=env, timeout=limit)
    try:
        with PlannerClient(srv.endpoint, timeout=limit) as c:
            c.plan(goal={"named": "home"}, group="arm",
                   start={"joint_1": 0.3, "joint_2": 0.2, "joint_3": 0.1})
        return time.perf_counter() - t0
    finally:
        srv.stop(signal.SIGTERM, timeout=30)


def independent_files(d: Description, folder: Path) -> tuple[Path, Path]:
    """The expanded URDF with absolute mesh paths, and an SRDF allowing only the link
    pairs a joint connects (read from the URDF, not from the planner)."""
    text, _ = read_model_text(d.robot.source, packages=d.packages)
    text = re.sub(r"package://([^/]+)/",
                  lambda m: str(d.packages.find(m.group(1))) + "/", text)
    folder.mkdir(parents=True, exist_ok=True)
    urdf, srdf = folder / "robot.urdf", folder / "joint_connected.srdf"
    urdf.write_text(text)
    pairs = "".join(f'<disable_collisions link1="{j.parent}" link2="{j.child}" '
                    'reason="Adjacent"/>' for j in d.robot.joints.values())
    srdf.write_text(f'<robot name="{d.robot.name}">{pairs}</robot>')
    return urdf, srdf


def no_srdf_suite(d: Description, n: int, folder: Path) -> dict[str, dict]:
    mp = MotionPlanner(d)
    names = mp.joint_names
    lim = mp.limits(*mp.scaling(MotionRequest(goal=JointGoal({"joint_1": 0.0}))))
    rl = Limits(*(np.asarray(getattr(lim, k), float) for k in
                  ("lower", "upper", "velocity", "acceleration", "jerk", "effort")))
    model = IndependentModel(*independent_files(d, folder), names)
    out = {}
    for scene, obs in SCENES.items():
        obs = tuple(obs)
        world = mp.world(obs)
        probs = problems(world, n, np.random.default_rng(11))
        times, ok, bad, failures = [], 0, 0, []
        for i, (a, b, _) in enumerate(probs):
            req = MotionRequest(goal=JointGoal(dict(zip(ARM, map(float, b[:3])))),
                                start=dict(zip(names, map(float, a))), obstacles=obs,
                                planning_time=5.0, seed=i)
            t0 = time.perf_counter()
            try:
                res = mp.solve(req)
            except PlanningError as e:
                failures.append(f"{type(e).__name__}: {e}")
                continue
            times.append(time.perf_counter() - t0)
            ok += 1
            traj = res.trajectory
            rep = recheck(model, lambda ts, t=traj: np.array([t.at(x).positions for x in ts]),
                          traj.duration, rl, obstacles=obstacle_dicts(list(obs)))
            if rep.violations:
                bad += 1
                failures.append(f"re-check {rep.violations} first collision "
                                f"{rep.first_collision}")
        row = {"problems": len(probs), "success": ok / len(probs),
               "median_ms": float(np.median(times) * 1e3) if times else None,
               "p95_ms": float(np.percentile(times, 95) * 1e3) if times else None,
               "recheck_violations": bad, "failures": failures[:5]}
        print(f"no SRDF, {scene}: {row}", flush=True)
        out[scene] = row
    return out


def main(n: int = 40) -> None:
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    tmp = Path(tempfile.mkdtemp(prefix="bench-own-robot-"))
    t0 = time.perf_counter()
    ws = make_course_workspace(tmp / "ws")
    print(f"workspace generated in {time.perf_counter() - t0:.1f} s: {ws.src}")
    serve_args = [str(ws.xacro), "--package-dir", str(ws.src), "--moveit-config",
                  str(ws.moveit_pkg), "--cache-dir", str(tmp / "cache")]
    cold = time_to_first_plan(serve_args, dict(os.environ))
    warm = time_to_first_plan(serve_args, dict(os.environ))
    bare = [*serve_args[:-1], str(tmp / "cache-bare")]
    no_jit = time_to_first_plan(bare, {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "numba")})
    print(f"start to first plan: fresh {cold:.1f} s (set up by ./dev, empty result cache), "
          f"next {warm:.1f} s, with no compiled kernels at all {no_jit:.1f} s")
    bare_src = tmp / "bare" / "src"
    shutil.copytree(ws.src, bare_src, ignore=shutil.ignore_patterns("arduinobot_moveit"))
    d = load_description(bare_src / ws.xacro.relative_to(ws.src), package_dirs=[bare_src])
    if d.srdf is not None:
        raise RuntimeError("the bare workspace still has an SRDF")
    suite = no_srdf_suite(d, n, tmp / "independent")
    emit("own_robot", {"startup_s": {"fresh": cold, "next": warm,
                                     "no_compiled_kernels": no_jit}, "no_srdf": suite})
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main(problems_per_scene(__doc__, 40))
