"""Planning benchmark: a seeded problem suite in three scenes; prints figures and a JSON line.

The suite runs on the shipped meshes and on a variant whose large links (every link but
the fingers) are subdivided to at least 50k triangles each (same surfaces, finer
triangles): a temporary copy of the package loaded through ``package_dirs``.

Usage: ./dev bench planning [problems per scene]   (default 30)
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from arduinobot.contract.errors import PlanningError
from arduinobot.description import Description, load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
from bench._lib.args import problems_per_scene
from bench._lib.report import emit
from bench._lib.scenes import SCENES, problems


def fine_variant(tmp: Path, *, min_faces: int = 50_000) -> tuple[Description, dict[str, int]]:
    """The arduinobot with every non-finger mesh subdivided to >= ``min_faces`` triangles."""
    src = Path(__file__).resolve().parents[1] / "src" / "arduinobot" / "description" / "arduinobot_description"
    dst = tmp / "arduinobot_description"
    shutil.copytree(src, dst)
    faces = {}
    for f in sorted((dst / "meshes").glob("*.STL")):
        if "finger" in f.name:
            continue
        m = trimesh.load(f, force="mesh")
        while len(m.faces) < min_faces:
            m = m.subdivide()
        m.export(f)
        faces[f.name] = len(m.faces)
    return load_description(dst / "urdf" / "arduinobot.urdf.xacro", package_dirs=[tmp]), faces


def suite(d: Description, n: int) -> dict[str, dict]:
    summary = {}
    for name, obs in SCENES.items():
        w = CollisionWorld(d, obstacles=obs)
        pp = PathPlanner(w, d)
        rng = np.random.default_rng(0)
        probs = problems(w, n, rng)
        lim = d.robot.position_limits()
        qs = rng.uniform(lim[:, 0], lim[:, 1], size=(2000, 4))
        ts = []
        for q in qs:
            t = time.perf_counter()
            w.is_valid(q)
            ts.append(time.perf_counter() - t)
        tot, ok, lens, checks, bad = [], 0, [], [], 0
        stages: dict[str, list[float]] = {}
        for i, (a, b, _) in enumerate(probs):
            try:
                goal = JointGoal(dict(zip(w.kin.joint_names[:3], b[:3])))
                r = pp.solve(PathRequest(start=a, goal=goal, seed=i, planning_time=1.0))
            except PlanningError:
                continue
            ok += 1
            tot.append(sum(r.timings.values()))
            for k, v in r.timings.items():
                stages.setdefault(k, []).append(v)
            lens.append(r.length)
            checks.append(r.checks)
            bad += w.first_invalid(interpolate(r.path, 0.0005)) >= 0
        fig = {"problems": len(probs), "detours": int(sum(p[2] for p in probs)),
               "success": ok / len(probs), "median_ms": float(np.median(tot) * 1e3),
               "p95_ms": float(np.percentile(tot, 95) * 1e3),
               "stage_median_ms": {k: float(np.median(v) * 1e3) for k, v in stages.items()},
               "stage_p95_ms": {k: float(np.percentile(v, 95) * 1e3) for k, v in stages.items()},
               "length_median": float(np.median(lens)), "checks_median": float(np.median(checks)),
               "state_check_median_us": float(np.median(ts) * 1e6),
               "paths_in_collision": int(bad)}
        print(name, fig)
        summary[name] = fig
    return summary


def main(n: int = 30) -> None:
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    summary = suite(load_description(), n)
    with tempfile.TemporaryDirectory() as tmp:
        fine, faces = fine_variant(Path(tmp))
        print("fine variant triangles:", faces)
        summary["fine_50k"] = {"triangles": faces, "scenes": suite(fine, n)}
    emit("planning", summary)


if __name__ == "__main__":
    main(problems_per_scene(__doc__, 30))
