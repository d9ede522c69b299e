"""The peer benchmark: ours through the real service against MPlib 0.2.1, same problems.

Two robots (bench/_lib/peer_models.py): the course workspace (millimetre CAD meshes of 2k-54k
triangles, a camera on a fixed joint, a separate MoveIt package) and the shipped
arduinobot; and ``course_fingers``, the course workspace with a matrix that disables only
joint-connected pairs (the fingers checked against each other). Three scenes each (bench/_lib/scenes.py: self, table, pillars) with seeded
problems (at least half needing a detour). Per robot:

- ours: a real ``arduinobot serve`` (2 workers, 127.0.0.1 on a free port, multicast
  scouting off); each problem is a plan request with the scene's obstacles sent over
  Zenoh by the Python client, with its own seed; wall clock at the client. Per scene two
  concurrent warm-up requests (one per worker, each builds its scene world) not counted.
- MPlib 0.2.1 (OMPL RRTConnect, FCL, TOPP-RA) in its own venv through
  bench/_lib/mplib_runner.py, on the same problems with the same planning budget and the
  velocity/acceleration limits the service reports at ``/description`` times the
  scaling both sides use (``--scaling``, default 1.0, sent explicitly in every request:
  the course's joint_limits.yaml would default to 0.1); one warm-up per scene.
  MPlib gets the model's SRDF plus the joint-connected pairs (the service's matrix).
  Before planning, MPlib and our checker judge the same random states (half colliding by
  ours): agreement shows MPlib reads the mesh ``scale`` (a millimetre mesh read
  unscaled would be 1000 times too big and collide everywhere).
- figures: success; wall median/p95 ms; ours/MPlib median; our stage split (the reply's
  ``timing``) and verification's share; the certified minimum clearance (the reply's
  ``verification.min_clearance``); trajectory durations: ours (jerk-limited, returned),
  toppra's time-optimal on the same reply path (in-process, ``MotionPlanner.time_path``
  on the reply's waypoints), their ratio (issue target <= 1.2), MPlib's; and the jerk
  floor (:func:`jerk_floor`), a lower bound on any jerk-limited motion of the path: where
  it is itself over 1.2x toppra, no jerk-limited timing can meet the target;
- near contact: the share of our motions whose certified clearance is under 0.1 mm (a
  pair within microns somewhere), and the proof's time (the reply's ``recheck`` stage)
  median for those and for the others;
- ``--group all``: the arm and the gripper move together (the gripper's start and goal
  drawn across its range; the request's group ``all``; the left finger, the mimic joint_5,
  follows joint_4 throughout). MPlib 0.2.1 cannot be given that problem: it loads the
  URDF's ``<mimic>`` joint_5 as a joint of its own (its pinocchio model has five, joint_5
  a plain ``JointModelRZ``, no mimic in its URDF parser, collision checker or OMPL state
  space: checked on course_fingers), and a move group is the chain to one link, so
  joint_4 (right finger) and joint_5 (left finger) are never in one group. Its column is
  the nearest problem it takes, labelled "MPlib, joints 1-4, left finger held": the move
  group ends at the right finger (joints 1-4 planned, to our goal's joints 1-4), joint_5
  set to the mimic of joint_4's start value (so its start is ours) and held there: along
  the motion and at the goal its left finger is not where ours is (other contacts, other
  free space; its goal can be colliding for it where ours is free, or the reverse). Its
  trajectories are re-checked on our model with the mimic applied (the left finger where
  the robot would put it): the collisions found there are reported as they are, beside
  the same re-check on MPlib's own problem (our URDF without joint_5's ``<mimic>``, the
  left finger held where MPlib held it);
- every returned trajectory, ours and MPlib's, re-checked independently
  (bench/_lib/recheck.py) at 0.002 rad: ours from the reply's samples (bench/_lib/sampled.py),
  MPlib's from its toppra data; the count with any collision (target 0).

``--models panda`` (VAMP's Panda on MotionBenchMaker problems) and ``--models so101`` (the
SO-101 fixture on generated MBM-class scenes) run bench/_lib/peer_mbm.py instead: each
problem ``--repeat`` times on each side (ours, MPlib with ``--rrt-range`` 1.0, and HPP with
``--hpp``), 5 s budget, the cold start and first plan in a new world apart, every path
re-checked at 0.002 rad.

Usage: ./dev bench peer [--n 40] [--models course,shipped] [--scaling 1.0] [--group arm]
       ./dev bench peer --models panda --hpp [--mbm-n 3] [--repeat 3] [--vamp DIR]
       ./dev bench peer --n 10     (a quick look)
       ./dev bench peer --models course_fingers --group all   (arm and gripper, fingers checked)
Prints a block per robot and scene, then one JSON line of all figures.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp_
import shutil
import statistics
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.client.replies import PlanReply
from arduinobot.contract.errors import PlanningError
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.planner.timing.curve import build_curve
from arduinobot.service.process.disk_cache import DiskCache
from bench._lib.peer_models import PeerModel, make_model
from bench._lib.peer_mplib import held_model, mplib_rows, scale_check
from bench._lib.peer_report import NEAR, STAGES, report, report_mbm
from bench._lib.recheck import IndependentModel, Limits, recheck
from bench._lib.report import emit
from bench._lib.sampled import SampledPositions
from bench._lib.scenes import SCENES, obstacle_dicts, problems
from tests.helpers.serve import start_server

ARM = ("joint_1", "joint_2", "joint_3")


def ms(xs: list[float]) -> dict[str, float | None]:
    """Median and p95 of seconds, in ms."""
    if not xs:
        return {"median_ms": None, "p95_ms": None}
    return {"median_ms": 1e3 * statistics.median(xs), "p95_ms": 1e3 * float(np.percentile(xs, 95))}


def median(xs: list[float]) -> float | None:
    return statistics.median(xs) if xs else None


def plan_body(names: tuple[str, ...], a: np.ndarray, b: np.ndarray, obstacles: list[dict],
              seed: int, args: argparse.Namespace) -> dict[str, Any]:
    moved = names if args.group == "all" else ARM
    return {"start": dict(zip(names, map(float, a))),
            "goal": {"joints": dict(zip(moved, map(float, b[:len(moved)])))},
            **({"group": "all"} if args.group == "all" else {}),
            "obstacles": obstacles, "planning_time": args.planning_time,
            "velocity_scaling": args.scaling, "acceleration_scaling": args.scaling,
            "seed": seed}


def run_service(model: PeerModel, probs_of: dict[str, list], names: tuple[str, ...],
                cache: Path, args: argparse.Namespace
                ) -> tuple[dict[str, list], dict[str, Any]]:
    """Every problem through a real ``arduinobot serve``: per scene [(wall s, PlanReply
    or the error's class name)], and the service's ``/description``."""
    t0 = time.perf_counter()
    srv = start_server(["--workers", "2", *model.serve_args, "--cache-dir", str(cache)],
                       timeout=600)
    print(f"  serve ready in {time.perf_counter() - t0:.1f} s on {srv.endpoint}", flush=True)
    out: dict[str, list] = {}
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            desc = c.description()
            for scene, probs in probs_of.items():
                obs = obstacle_dicts(list(SCENES[scene]))
                warm = [plan_body(names, a, b, obs, 10_000 + k, args)
                        for k, (a, b, _) in enumerate(probs[:2])]
                with ThreadPoolExecutor(2) as ex:  # one per worker: both build the world
                    for f in [ex.submit(c.plan, w) for w in warm]:
                        try:
                            f.result()
                        except errors.ServiceError as e:
                            print(f"  warm-up {scene}: {type(e).__name__}: {e}")
                rows = []
                for i, (a, b, _) in enumerate(probs):
                    body = plan_body(names, a, b, obs, i, args)
                    t = time.perf_counter()
                    try:
                        res: PlanReply | str = c.plan(body)
                    except errors.ServiceError as e:
                        res = type(e).__name__
                    rows.append((time.perf_counter() - t, res))
                out[scene] = rows
                print(f"  ours {scene}: {sum(not isinstance(r, str) for _, r in rows)}"
                      f"/{len(rows)} planned", flush=True)
    finally:
        srv.stop()
    return out, desc


def jerk_floor(path: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray,
               jerk: np.ndarray) -> float:
    """A lower bound [s] on any jerk-limited motion along ``path`` (shape (k, dof)), rest
    to rest: each joint covers at least its total travel along the path within its own
    velocity, acceleration and jerk limits; the slowest joint's fastest such move
    (ruckig's time-optimal 1-DOF profile, computed offline) bounds the whole motion.
    Effort and the joints' coupling along the path only make motions slower."""
    from ruckig import InputParameter, Result, Ruckig, Trajectory
    travel = np.sum(np.abs(np.diff(np.asarray(path, float), axis=0)), axis=0)
    otg, floor = Ruckig(1), 0.0
    for j, d in enumerate(travel):
        if d <= 0.0:
            continue
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [0.0], [float(d)]
        inp.max_velocity = [float(velocity[j])]
        inp.max_acceleration = [float(acceleration[j])]
        inp.max_jerk = [float(jerk[j])]
        traj = Trajectory(1)
        if otg.calculate(inp, traj) != Result.Working:
            raise RuntimeError(f"ruckig found no 1-DOF profile for joint {j}")
        floor = max(floor, traj.duration)
    return floor


def toppra_durations(mp: MotionPlanner, replies: dict[str, list], scaling: float
                     ) -> dict[str, list[float | None]]:
    """Toppra's time-optimal duration [s] on each reply's path (None: no timing passed)."""
    lim = mp.limits(scaling, scaling)
    out: dict[str, list[float | None]] = {}
    for scene, rows in replies.items():
        world = mp.world(tuple(SCENES[scene]))
        durs: list[float | None] = []
        for _, res in rows:
            if isinstance(res, str):
                continue
            curve = build_curve(res.path, Certifier(world))  # as the pipeline blends it
            try:
                traj, _, _, _ = mp.time_path(curve, res.path, world, lim,
                                             profile="time_optimal")
                durs.append(traj.duration)
            except PlanningError as e:
                print(f"  toppra on a reply path of {scene}: {type(e).__name__}: {e}")
                durs.append(None)
        out[scene] = durs
    return out


# re-check tasks, read by forked workers (no pickling of trajectories)
TASKS: list[tuple] = []
MODEL_FILES: tuple = ()


def _recheck_task(i: int) -> Any:
    global _MODEL
    if "_MODEL" not in globals():
        _MODEL = IndependentModel(*MODEL_FILES)
    positions, duration, limits, obstacles, step = TASKS[i]
    return recheck(_MODEL, positions, duration, limits, obstacles=obstacles,
                   enforce_jerk=False, step=step)


def recheck_all(model: PeerModel, names: tuple[str, ...], tasks: list[tuple], *,
                urdf: Path | None = None) -> list[Any]:
    """Re-check ``tasks`` in two forked processes, each loading the model (``urdf``
    instead of the model's, if given) once."""
    global MODEL_FILES
    TASKS[:] = tasks
    MODEL_FILES = (model.urdf if urdf is None else urdf, model.srdf, names)
    if not tasks:
        return []
    with mp_.get_context("fork").Pool(2) as pool:
        return pool.map(_recheck_task, range(len(tasks)))


def summarise(reports: list[Any]) -> dict[str, Any]:
    """Collisions, other findings and the worst ratio to each limit over ``reports``."""
    kinds: dict[str, int] = {}
    for r in reports:
        for k in r.violations:
            kinds[k] = kinds.get(k, 0) + 1
    worst = {k: max(r.worst[k] for r in reports) for k in reports[0].worst} if reports else {}
    return {"checked": len(reports),
            "with_collision": sum("collision" in r.violations for r in reports),
            "kinds": kinds, "worst_ratio": worst,
            "first_collisions": [r.first_collision for r in reports if r.first_collision][:3]}


def run_model(model: PeerModel, folder: Path, args: argparse.Namespace) -> dict[str, Any]:
    d = model.description
    cache = folder / "cache"
    mp = MotionPlanner(d, cache=DiskCache(cache))
    names = mp.joint_names
    probs_of = {s: problems(mp.world(tuple(obs)), args.n, np.random.default_rng(args.seed),
                            gripper=args.group == "all")
                for s, obs in SCENES.items()}
    replies, desc = run_service(model, probs_of, names, cache, args)
    lim = mp.limits(args.scaling, args.scaling)
    for k in ("velocity", "acceleration"):  # the service's figures are the in-process ones
        served = np.array([desc["limits"][n][k] for n in names], float) * args.scaling
        if not np.allclose(served, getattr(lim, k), rtol=1e-12):
            raise RuntimeError(f"{k} limits: service {served} vs in-process {getattr(lim, k)}")
    rl = Limits(*(np.asarray(getattr(lim, k), float) for k in
                  ("lower", "upper", "velocity", "acceleration", "jerk", "effort")))
    toppra = toppra_durations(mp, replies, args.scaling)
    scale = scale_check(model, mp, names, folder, args.state_checks)
    mplib, mplib_tasks, mplib_held = mplib_rows(model, names, probs_of, lim, folder, args, rl)
    rows: dict[str, Any] = {}
    ours_tasks: dict[str, list[tuple]] = {}
    for scene, rows_ in replies.items():
        ok = [r for _, r in rows_ if not isinstance(r, str)]
        fails: dict[str, int] = {}
        for _, r in rows_:
            if isinstance(r, str):
                fails[r] = fails.get(r, 0) + 1
        walls = [w for w, _ in rows_]
        stage = {k: 1e3 * statistics.median(r.timing[k] for r in ok) if ok else None
                 for k in STAGES}
        share = median([r.timing["verify"] / r.timing["total"] for r in ok])
        overhead = median([w - r.timing["total"] for w, r in rows_ if not isinstance(r, str)])
        clear = [r.verification.min_clearance for r in ok
                 if r.verification.min_clearance is not None]
        near = [r for r in ok if r.verification.min_clearance is not None
                and r.verification.min_clearance < NEAR]
        near_ids = {id(r) for r in near}  # (replies hold arrays: by identity)
        far = [r for r in ok if id(r) not in near_ids]
        durs = [r.duration for r in ok]
        ratios = [r.duration / t for r, t in zip(ok, toppra[scene]) if t]
        floors = [jerk_floor(r.path, lim.velocity, lim.acceleration, lim.jerk) for r in ok]
        floor_ratios = [f / t for f, t in zip(floors, toppra[scene]) if t]
        obs = obstacle_dicts(list(SCENES[scene]))
        ours_tasks[scene] = [(SampledPositions(r.times, r.positions, r.velocities,
                                               r.accelerations), r.duration, rl, obs,
                              args.recheck_step) for r in ok]
        m = mplib[scene]
        rows[scene] = {
            "problems": len(rows_),
            "ours": {"success": len(ok) / len(rows_), "failures": fails, **ms(walls),
                     "stage_median_ms": stage, "verify_share_median": share,
                     "wire_overhead_ms_median": None if overhead is None else 1e3 * overhead,
                     "certified_all": all(r.verification.certified for r in ok),
                     "near_contact_share": len(near) / len(ok) if ok else None,
                     "proof_ms_median": {
                         "all": median([1e3 * r.timing["recheck"] for r in ok]),
                         "near": median([1e3 * r.timing["recheck"] for r in near]),
                         "others": median([1e3 * r.timing["recheck"] for r in far])},
                     "wall_ms_median_near": median([1e3 * w for w, r in rows_
                                                    if id(r) in near_ids]),
                     "min_clearance_m": {"min": min(clear) if clear else None,
                                         "median": median(clear)},
                     "duration_s_median": median(durs),
                     "toppra_duration_s_median": median([t for t in toppra[scene] if t]),
                     "jerk_limited_over_toppra_median": median(ratios),
                     "jerk_limited_over_toppra_max": max(ratios) if ratios else None,
                     # no jerk-limited timing can beat the floor: where it is over 1.2x
                     # toppra, so is every jerk-limited motion of that path
                     "jerk_floor_over_toppra_median": median(floor_ratios),
                     "jerk_limited_over_floor_median": median(
                         [r.duration / f for r, f in zip(ok, floors) if f])},
            "mplib": m,
            "ours_over_mplib_median": ms(walls)["median_ms"] / m["median_ms"]
            if m["median_ms"] else None,
        }
    flat = [t for s in SCENES for t in ours_tasks[s]] + [t for s in SCENES for t in mplib_tasks[s]]
    t0 = time.perf_counter()
    reports = recheck_all(model, names, flat)
    print(f"  re-checked {len(flat)} trajectories in {time.perf_counter() - t0:.0f} s",
          flush=True)
    counts = [len(ours_tasks[s]) for s in SCENES] + [len(mplib_tasks[s]) for s in SCENES]
    parts = _split(reports, counts)
    for i, scene in enumerate(SCENES):
        rows[scene]["ours"]["recheck"] = summarise(parts[i])
        rows[scene]["mplib"]["recheck"] = summarise(parts[len(SCENES) + i])
    if args.group == "all":  # MPlib's trajectories on its own problem (left finger held)
        urdf, held_names = held_model(model, names)
        held = recheck_all(model, held_names, [t for s in SCENES for t in mplib_held[s]],
                           urdf=urdf)
        for scene, part in zip(SCENES, _split(held, [len(mplib_held[s]) for s in SCENES])):
            rows[scene]["mplib"]["recheck_own_problem"] = summarise(part)
    return {"source": model.source, "group": args.group, "scaling": args.scaling,
            "recheck_step": args.recheck_step,
            "default_scaling": desc.get("default_scaling"),
            "limits_velocity": [float(v) for v in lim.velocity],
            "limits_acceleration": [float(v) for v in lim.acceleration],
            "scale_check": scale, "scenes": rows}


def _split(items: list[Any], counts: list[int]) -> list[list[Any]]:
    """``items`` cut into consecutive runs of ``counts`` (the re-checks, per scene)."""
    out, at = [], 0
    for k in counts:
        out.append(items[at:at + k])
        at += k
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40, help="problems per scene (default 40)")
    ap.add_argument("--models", default="course,shipped",
                    help="course,course_fingers,shipped,panda,so101 (comma-separated)")
    ap.add_argument("--group", choices=("arm", "all"), default="arm",
                    help="arm: the arm moves, the gripper closed; all: arm and gripper "
                         "together (MPlib: joints 1-4, its left finger held)")
    ap.add_argument("--scaling", type=float, default=1.0,
                    help="velocity and acceleration scaling, both sides (default 1.0)")
    ap.add_argument("--planning-time", type=float, default=None,
                    help="budget [s], every side (default 1.0; 5.0 for panda and so101)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="panda, so101: runs of each problem per side, seeds differ (default 3)")
    ap.add_argument("--mbm-n", type=int, default=3,
                    help="panda, so101: problems per scene (default 3: 21 for the Panda)")
    ap.add_argument("--vamp", default=None,
                    help="panda: a VAMP checkout (default: extracted to ~/.cache/arduinobot/"
                         "bench/vamp from a local mirror, or cloned)")
    ap.add_argument("--rrt-range", type=float, default=1.0,
                    help="panda, so101: MPlib's RRTConnect range (default 1.0, its best here)")
    ap.add_argument("--hpp", action="store_true",
                    help="panda, so101: HPP too (its own venv .bench-venvs/hpp)")
    ap.add_argument("--hpp-validation", choices=("Progressive", "Dichotomy"),
                    default="Progressive", help="HPP's continuous path validation")
    ap.add_argument("--hpp-tolerance", type=float, default=1e-3,
                    help="HPP's allowed penetration [m] (default 0.001)")
    ap.add_argument("--seed", type=int, default=7, help="problem draws (7: bench/trajectory's)")
    ap.add_argument("--recheck-step", type=float, default=0.002, help="[rad]")
    ap.add_argument("--state-checks", type=int, default=40,
                    help="random states MPlib and our checker both judge (per model)")
    args = ap.parse_args(argv)
    mbm_models = {"panda", "so101"}
    if args.planning_time is None:
        args.planning_time = 5.0 if set(args.models.split(",")) <= mbm_models else 1.0
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    tmp = Path(tempfile.mkdtemp(prefix="bench-peer-"))
    out: dict[str, Any] = {"n": args.n, "planning_time": args.planning_time}
    try:
        for name in args.models.split(","):
            t0 = time.perf_counter()
            print(f"{name}:", flush=True)
            if name in mbm_models:
                from bench._lib.peer_mbm import run_mbm
                out[name] = run_mbm(name, tmp / name, args)
            else:
                model = make_model(name, tmp / name)  # type: ignore[arg-type]
                out[name] = run_model(model, tmp / name, args)
            print(f"  done in {time.perf_counter() - t0:.0f} s", flush=True)
        for name in args.models.split(","):
            (report_mbm if name in mbm_models else report)(name, out[name])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    emit("peer", out)


if __name__ == "__main__":
    main()
