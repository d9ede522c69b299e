"""MotionBenchMaker-class problems in the peer benchmark: ``./dev bench peer --models panda``.

- ``panda``: VAMP's Panda (7 joints, its collision meshes and SRDF) on VAMP's MBM problems
  (bench/_lib/mbm.py): ``--mbm-n`` per scene (default 3 of each of the 7 = 21), drawn
  seeded; the ground off (box and table_under_pick reach under the base's plane);
- ``so101``: the SO-101 fixture (5 joints + gripper, STL meshes, tests/helpers/so101.py)
  on generated MBM-class scenes (tests/helpers/mbm_scenes.py: shelf, cage, boxes, table).

Each problem is run ``--repeat`` times (seeds differ) on each side so a p95 is a figure:

- ours: a real ``arduinobot serve`` (2 workers), ``--planning-time`` 5 s, one request at a
  time; the first two requests after the start (one per worker, concurrent, empty scene)
  are the cold start, reported apart; each problem's first request is its first plan in
  a new world (reported apart as ``cold_new_world``; the other worker may still build
  that world on a later repeat); wall at the client, the reply's stage split
  (``recheck`` is the proof), the max proof, the certified clearance;
- MPlib 0.2.1 (bench/_lib/mplib_runner.py) at its best settings for these problems:
  RRTConnect with ``rrt_range`` 1.0, the same budget, TOPP-RA; wall = plan + TOPP;
- HPP (bench/_lib/hpp_runner.py, its own venv) when ``--hpp``: BiRRT planner, whole
  edges validated by Progressive path validation (a small allowed penetration), a
  random-shortcut optimiser; wall = solve + optimise;
- every returned path re-checked independently (bench/_lib/recheck.py) at
  ``--recheck-step`` (0.002 rad) on the meshes: the count with any collision (target 0).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp_
import statistics
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.client.replies import PlanReply
from arduinobot.description import Description, load_description
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.obstacles import Obstacle
from arduinobot.service.process.disk_cache import DiskCache
from tests.helpers.serve import start_server

from .mplib_venv import MplibTiming, run_mplib
from .peer_models import plain_srdf
from .peer_report import STAGES
from .recheck import IndependentModel, Limits, recheck
from .sampled import SampledPositions
from .scenes import obstacle_dicts

DEEP = 1e-3  # [m] a re-check collision deeper than this is counted apart


@dataclass(frozen=True)
class Problem:
    """One problem: ``start``/``goal`` over the setup's joints [rad], its obstacles."""

    name: str
    scene: str
    start: tuple[float, ...]
    goal: tuple[float, ...]
    obstacles: tuple[Obstacle, ...]


@dataclass(frozen=True)
class Setup:
    """A robot and its problems as every side gets them."""

    name: str
    description: Description
    serve_args: tuple[str, ...]
    urdf: Path
    srdf: Path
    tip: str  # MPlib's move group ends at this link
    joints: tuple[str, ...]
    problems: tuple[Problem, ...]
    ground: bool
    source: str
    moved: tuple[str, ...] = ()  # the goal's joints (default: all of ``joints``)


def panda_setup(folder: Path, args: argparse.Namespace) -> Setup:
    from . import mbm
    vamp = mbm.vamp_dir(Path(args.vamp) if args.vamp else None)
    urdf, srdf = mbm.panda_files(vamp, folder / "panda")
    d = load_description(urdf, srdf=srdf)
    mp = MotionPlanner(d, cache=DiskCache(folder / "cache"))
    if mp.joint_names != mbm.JOINTS:
        raise RuntimeError(f"the Panda's joints {mp.joint_names} are not {mbm.JOINTS}")

    def valid(p: Any) -> bool:
        w = mp.world(p.obstacles, ground=False)
        return bool(w.is_valid(np.array(p.start)) and w.is_valid(np.array(p.goal)))

    picked, skipped = mbm.pick(mbm.read_problems(vamp), args.mbm_n, args.seed, valid)
    probs = tuple(Problem(p.name, p.scene, p.start, p.goal, p.obstacles) for p in picked)
    return Setup("panda", d, (str(urdf), "--srdf", str(srdf)), urdf,
                 plain_srdf(d, folder / "plain"), "panda_link8", mbm.JOINTS, probs, False,
                 f"VAMP's Panda and MBM problems ({vamp}); {args.mbm_n} per scene, seed "
                 f"{args.seed}; skipped as invalid on our meshes: {skipped}")


def so101_setup(folder: Path, args: argparse.Namespace) -> Setup:
    from tests.helpers.mbm_scenes import problems_for
    from tests.helpers.so101 import make_so101
    urdf = make_so101(folder / "so101")
    d = load_description(urdf)
    mp = MotionPlanner(d, cache=DiskCache(folder / "cache"))
    names = tuple(mp.joint_names)
    gen = problems_for(mp, names, n_per_scene=args.mbm_n, seed=args.seed, reach=0.4,
                       tip=d.tcp.parent_link, fixed={names[-1]: 0.0})  # the gripper held
    probs = tuple(Problem(p.name, p.scene, p.start, p.goal, p.obstacles) for p in gen)
    tip = d.robot.joints[names[-1]].child  # MPlib's group: the chain through the gripper
    return Setup("so101", d, (str(urdf),), urdf, plain_srdf(d, folder / "plain"), tip, names,
                 probs, True, f"SO-101 fixture (STL meshes), generated MBM-class scenes "
                 f"(tests/helpers/mbm_scenes.py), {args.mbm_n} per scene, seed {args.seed}, "
                 f"the gripper held at 0", moved=names[:-1])  # the arm group: no gripper


def body(s: Setup, p: Problem, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    goal = {n: v for n, v in zip(s.joints, p.goal) if n in (s.moved or s.joints)}
    return {"start": dict(zip(s.joints, p.start)), "goal": {"joints": goal},
            "obstacles": obstacle_dicts(list(p.obstacles)), "ground": s.ground,
            "planning_time": args.planning_time, "velocity_scaling": 1.0,
            "acceleration_scaling": 1.0, "seed": seed}


def run_ours(s: Setup, cache: Path, args: argparse.Namespace) -> dict[str, Any]:
    """Every problem ``args.repeat`` times through a real ``arduinobot serve``."""
    t0 = time.perf_counter()
    srv = start_server(["--workers", "2", *s.serve_args, "--cache-dir", str(cache)],
                       timeout=900)
    print(f"  serve ready in {time.perf_counter() - t0:.1f} s", flush=True)
    rows: dict[str, list[tuple[float, PlanReply | str]]] = {}
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            first = s.problems[0]
            empty = Problem("empty", "empty", first.start, first.start, ())
            warm = [body(s, empty, 90_000 + k, args) for k in range(2)]

            def timed(b: dict[str, Any]) -> tuple[float, PlanReply | str]:
                t = time.perf_counter()
                try:
                    res: PlanReply | str = c.plan(b)
                except errors.ServiceError as e:
                    res = type(e).__name__
                return time.perf_counter() - t, res

            with ThreadPoolExecutor(2) as ex:  # one per worker: both cold
                cold_start = list(ex.map(timed, warm))
            for i, p in enumerate(s.problems):
                rows[p.name] = [timed(body(s, p, 1000 * r + i, args))
                                for r in range(args.repeat)]
                ok = sum(not isinstance(r, str) for _, r in rows[p.name])
                print(f"  ours {p.name}: {ok}/{args.repeat}  walls "
                      + " ".join(f"{w:.2f}" for w, _ in rows[p.name]), flush=True)
    finally:
        srv.stop()
    return {"rows": rows, "cold_start_s": [w for w, _ in cold_start]}


def run_mplib_side(s: Setup, lim: Any, folder: Path, args: argparse.Namespace
                   ) -> dict[str, list[dict]]:
    spec = {"urdf": str(s.urdf), "srdf": str(s.srdf), "move_group": s.tip,
            "output": str(folder / "mplib-out.json"), "time_step": 0.01,
            "rrt_range": args.rrt_range,
            "velocity": [float(v) for v in lim.velocity],
            "acceleration": [float(v) for v in lim.acceleration],
            "scenes": {p.name: {"obstacles": obstacle_dicts(list(p.obstacles)),
                                "problems": [{"start": dict(zip(s.joints, p.start)),
                                              "goal": dict(zip(s.joints, p.goal)),
                                              "planning_time": args.planning_time}]
                                * args.repeat}
                       for p in s.problems}}
    out = run_mplib(spec)
    if tuple(out["move_group_joints"]) != s.joints:
        raise RuntimeError(f"MPlib's move group {out['move_group_joints']} is not {s.joints}")
    return out["scenes"]


class Polyline:
    """A geometric path as ``positions(ts)``: waypoints at unit speed in joint space."""

    def __init__(self, path: np.ndarray) -> None:
        self.q = np.asarray(path, float)
        self.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.q, axis=0),
                                                                  axis=1))])
        self.duration = float(self.s[-1])

    def __call__(self, ts: np.ndarray) -> np.ndarray:
        t = np.clip(np.atleast_1d(np.asarray(ts, float)), 0.0, self.duration)
        return np.stack([np.interp(t, self.s, self.q[:, j]) for j in range(self.q.shape[1])],
                        axis=1)


TASKS: list[tuple] = []
MODEL_FILES: tuple = ()


def _recheck_task(i: int) -> tuple[bool, Any]:
    global _MODEL
    if "_MODEL" not in globals():
        _MODEL = IndependentModel(*MODEL_FILES)
    positions, duration, limits, obstacles, step = TASKS[i]
    rep = recheck(_MODEL, positions, duration, limits, obstacles=obstacles,
                  enforce_jerk=False, step=step)
    return "collision" in rep.violations, rep.first_collision


def recheck_all(s: Setup, tasks: list[tuple]) -> list[tuple]:
    """(collided, first collision) per task, in two forked processes."""
    global MODEL_FILES
    TASKS[:] = tasks
    MODEL_FILES = (s.urdf, s.srdf, s.joints)
    if not tasks:
        return []
    with mp_.get_context("fork").Pool(2) as pool:
        return pool.map(_recheck_task, range(len(tasks)))


def pct(xs: list[float]) -> dict[str, float | None]:
    """Median, p95 and max of seconds, in ms."""
    if not xs:
        return {"median_ms": None, "p95_ms": None, "max_ms": None}
    return {"median_ms": 1e3 * statistics.median(xs),
            "p95_ms": 1e3 * float(np.percentile(xs, 95)), "max_ms": 1e3 * max(xs)}


def run_mbm(name: str, folder: Path, args: argparse.Namespace) -> dict[str, Any]:
    s = (panda_setup if name == "panda" else so101_setup)(folder, args)
    print(f"  {len(s.problems)} problems x {args.repeat}: {s.source}", flush=True)
    mp = MotionPlanner(s.description, cache=DiskCache(folder / "cache"))
    lim = mp.limits(1.0, 1.0)
    rl = Limits(*(np.asarray(getattr(lim, k), float) for k in
                  ("lower", "upper", "velocity", "acceleration", "jerk", "effort")))
    ours = run_ours(s, folder / "cache", args)
    t0 = time.perf_counter()
    mplib = run_mplib_side(s, lim, folder, args)
    print(f"  MPlib done in {time.perf_counter() - t0:.0f} s", flush=True)
    hpp: dict[str, list[dict]] | None = None
    if args.hpp:
        from .hpp_venv import run_hpp
        t0 = time.perf_counter()
        hpp = run_hpp(s, folder, args)
        print(f"  HPP done in {time.perf_counter() - t0:.0f} s", flush=True)
    sides: dict[str, list[tuple[Problem, int, float, Any]]] = {"ours": [], "mplib": [],
                                                                "hpp": []}
    tasks: dict[str, list[tuple]] = {"ours": [], "mplib": [], "hpp": []}
    for p in s.problems:
        obs = obstacle_dicts(list(p.obstacles))
        for r, (w, res) in enumerate(ours["rows"][p.name]):
            sides["ours"].append((p, r, w, res))
            if not isinstance(res, str):
                tasks["ours"].append((SampledPositions(res.times, res.positions,
                                                       res.velocities, res.accelerations),
                                      res.duration, rl, obs, args.recheck_step))
        for r, m in enumerate(mplib[p.name]):
            sides["mplib"].append((p, r, m["total_s"], m))
            if m["success"]:
                t = MplibTiming(m, len(s.joints), np.zeros(len(s.joints)))
                tasks["mplib"].append((lambda ts, t=t: t.evaluate(ts)[0], t.duration, rl, obs,
                                       args.recheck_step))
        for r, h in enumerate(hpp[p.name] if hpp else []):
            sides["hpp"].append((p, r, h["total_s"], h))
            if h["success"]:
                line = Polyline(np.array(h["path"]))
                tasks["hpp"].append((line, line.duration, rl, obs, args.recheck_step))
    flat = tasks["ours"] + tasks["mplib"] + tasks["hpp"]
    t0 = time.perf_counter()
    checked = recheck_all(s, flat)
    print(f"  re-checked {len(flat)} paths in {time.perf_counter() - t0:.0f} s", flush=True)
    n_o, n_m = len(tasks["ours"]), len(tasks["mplib"])
    parts = {"ours": checked[:n_o], "mplib": checked[n_o:n_o + n_m], "hpp": checked[n_o + n_m:]}
    # how deep: the colliding paths again among obstacles shrunk by DEEP on every side
    hit = [(k, i) for k in parts for i, (c, _) in enumerate(parts[k]) if c]
    deep = recheck_all(s, [(*tasks[k][i][:3], shrunk(tasks[k][i][3], DEEP), tasks[k][i][4])
                           for k, i in hit])
    for (k, i), (c, _) in zip(hit, deep):
        parts[k][i] = (True, parts[k][i][1], c)
    return {"source": s.source, "problems": [p.name for p in s.problems],
            "repeat": args.repeat, "planning_time": args.planning_time,
            "recheck_step": args.recheck_step,
            "ours": ours_figures(sides["ours"], ours["cold_start_s"], parts["ours"]),
            "mplib": peer_figures(sides["mplib"], parts["mplib"], f"rrt_range {args.rrt_range}"),
            "hpp": peer_figures(sides["hpp"], parts["hpp"], "BiRRT, Progressive validation")
            if hpp else None}


def _collisions(checked: list[tuple]) -> dict[str, Any]:
    return {"checked": len(checked), "with_collision": sum(c[0] for c in checked),
            "deeper_than_mm": DEEP * 1e3,
            "with_deep_collision": sum(len(c) > 2 and bool(c[2]) for c in checked),
            "first": [c[1] for c in checked if c[0]][:3]}


def shrunk(obstacles: list[dict], by: float) -> list[dict]:
    """``obstacles`` with every face moved inwards by ``by`` [m] (a collision found among
    them is deeper than ``by`` into the real one, or a self-collision)."""
    out = []
    for o in obstacles:
        o = dict(o)
        if o["shape"] == "box":
            o["size"] = [max(1e-6, v - 2 * by) for v in o["size"]]
        else:
            o["radius"] = max(1e-6, o["radius"] - by)
            if o["shape"] == "cylinder":
                o["length"] = max(1e-6, o["length"] - 2 * by)
        out.append(o)
    return out


def ours_figures(rows: list[tuple[Problem, int, float, Any]], cold_start: list[float],
                 checked: list[tuple[bool, Any]]) -> dict[str, Any]:
    ok = [(p, r, w, res) for p, r, w, res in rows if not isinstance(res, str)]
    warm = [w for _, r, w, _ in rows if r > 0] or [w for _, _, w, _ in rows]
    fails: dict[str, int] = {}
    for p, _, _, res in rows:
        if isinstance(res, str):
            fails[f"{p.name} {res}"] = fails.get(f"{p.name} {res}", 0) + 1
    proofs = [res.timing["recheck"] for *_, res in ok]
    clear = [res.verification.min_clearance for *_, res in ok
             if res.verification.min_clearance is not None]
    per_scene: dict[str, Any] = {}
    for scene in dict.fromkeys(p.scene for p, *_ in rows):
        mine = [(w, res) for p, _, w, res in rows if p.scene == scene]
        good = [res for _, res in mine if not isinstance(res, str)]
        per_scene[scene] = {"solved": len(good), "runs": len(mine),
                            **pct([w for w, _ in mine]),
                            "stage_median_ms": {k: 1e3 * statistics.median(
                                res.timing[k] for res in good) if good else None
                                for k in STAGES},
                            "proof_max_ms": 1e3 * max((res.timing["recheck"] for res in good),
                                                      default=0.0),
                            **proof_rungs(good)}
    return {"solved": len(ok), "runs": len(rows), "failures": fails,
            "wall_all": pct([w for *_, w, _ in rows]), "wall_warm": pct(warm),
            "cold_start_s": cold_start,
            "cold_new_world": pct([w for _, r, w, _ in rows if r == 0]),
            "stage_median_ms": {k: 1e3 * statistics.median(res.timing[k] for *_, res in ok)
                                if ok else None for k in STAGES},
            "proof": pct(proofs),
            "certified": sum(res.verification.certified for *_, res in ok),
            "clearance_mm": {"min": 1e3 * min(clear) if clear else None,
                             "median": 1e3 * statistics.median(clear) if clear else None},
            "recheck": _collisions(checked), "scenes": per_scene}


def proof_rungs(replies: list[Any]) -> dict[str, Any]:
    """The replies' proof ladder use summed (``verification.rungs``: trees, warm, hulls,
    parts, exact, still, one_dim) and how many paths each planner found."""
    rungs: dict[str, int] = {}
    found: dict[str, int] = {}
    for res in replies:
        for k, v in (res.raw["verification"].get("rungs") or {}).items():
            rungs[k] = rungs.get(k, 0) + int(v)
        found[res.planner] = found.get(res.planner, 0) + 1
    return {"rungs": rungs, "found_by": found}


def peer_figures(rows: list[tuple[Problem, int, float, Any]],
                 checked: list[tuple[bool, Any]], settings: str) -> dict[str, Any]:
    ok = [w for _, _, w, m in rows if m["success"]]
    fails: dict[str, int] = {}
    for p, _, _, m in rows:
        if not m["success"]:
            fails[f"{p.name} {m['status']}"] = fails.get(f"{p.name} {m['status']}", 0) + 1
    per_scene = {scene: {"solved": sum(m["success"] for p, _, _, m in rows if p.scene == scene),
                         "runs": sum(p.scene == scene for p, *_ in rows),
                         **pct([w for p, _, w, _ in rows if p.scene == scene])}
                 for scene in dict.fromkeys(p.scene for p, *_ in rows)}
    return {"settings": settings, "solved": len(ok), "runs": len(rows), "failures": fails,
            "wall_all": pct([w for _, _, w, _ in rows]), "wall_solved": pct(ok),
            "recheck": _collisions(checked), "scenes": per_scene}
