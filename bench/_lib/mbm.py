"""VAMP's Panda and its MotionBenchMaker (MBM) problems, read from a VAMP checkout.

Nothing of VAMP's or Franka's is shipped here: the files are read from a VAMP checkout
(``--vamp DIR``; default :func:`vamp_dir`: a copy extracted from a local mirror of the
repository into ``~/.cache/arduinobot/bench/vamp``, or a ``git clone`` when online).

- the robot: ``resources/panda/panda.urdf`` (its collision meshes converted to STL in a
  folder of ours, the URIs made relative paths to them, so our loader, MPlib, HPP and the
  independent re-check all read the same triangles) and ``panda.srdf``; the fingers are fixed joints at VAMP's 6.5 cm opening;
- the problems: ``resources/panda/problems.tar.bz2`` holds, per scene
  (bookshelf_small/tall/thin, box, cage, table_pick, table_under_pick), 100 MoveIt
  ``sceneNNNN.yaml`` (collision objects: box, sphere or cylinder primitives with a pose) and
  ``requestNNNN.yaml`` (start state, one joint goal): read as VAMP's
  ``resources/problem_tar_to_pkl_json.py`` reads them (the object pose times its
  primitive's pose; a cylinder's dimensions are (length, radius)).

:func:`pick` draws ``n`` per scene, seeded, keeping problems whose start and goal our
checker calls valid (MBM's were validated on VAMP's spheres, not on the meshes).
"""

from __future__ import annotations

import logging
import re
import shutil
import subprocess
import tarfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from arduinobot.scene.obstacles import Obstacle

log = logging.getLogger(__name__)

MIRROR = Path("/work/.mirror/KavrakiLab+vamp/repo")
CACHE = Path.home() / ".cache" / "arduinobot" / "bench" / "vamp"
URL = "https://github.com/KavrakiLab/vamp"
SCENES = ("bookshelf_small", "bookshelf_tall", "bookshelf_thin", "box", "cage",
          "table_pick", "table_under_pick")
JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))


@dataclass(frozen=True)
class MbmProblem:
    """One MBM problem in our request form.

    Attributes:
        scene: the MBM scene (``cage``, ...).
        index: the problem's number in its scene (1-100).
        start: the arm's start [rad], VAMP's joint order (:data:`JOINTS`).
        goal: the arm's goal [rad].
        obstacles: the scene's obstacles, world frame.
    """

    scene: str
    index: int
    start: tuple[float, ...]
    goal: tuple[float, ...]
    obstacles: tuple[Obstacle, ...]

    @property
    def name(self) -> str:
        return f"{self.scene}#{self.index}"


def vamp_dir(given: Path | None = None) -> Path:
    """A VAMP checkout holding ``resources/panda``: ``given``, else the cache (extracted
    from the local mirror, or cloned)."""
    if given is not None:
        if not (given / "resources" / "panda" / "panda.urdf").is_file():
            raise FileNotFoundError(f"--vamp {given}: no resources/panda/panda.urdf there")
        return given
    if (CACHE / "resources" / "panda" / "problems.tar.bz2").is_file():
        return CACHE
    CACHE.mkdir(parents=True, exist_ok=True)
    if (MIRROR / "HEAD").exists() or (MIRROR / "objects").is_dir():
        log.info("extracting VAMP's resources/panda from %s", MIRROR)
        archive = subprocess.run(["git", "-C", str(MIRROR), "archive", "HEAD", "resources/panda"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "x", "-C", str(CACHE)], input=archive, check=True)
    else:
        tmp = CACHE.with_name("vamp-clone")
        shutil.rmtree(tmp, ignore_errors=True)
        subprocess.run(["git", "clone", "--depth", "1", URL, str(tmp)], check=True)
        shutil.copytree(tmp / "resources" / "panda", CACHE / "resources" / "panda",
                        dirs_exist_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
    return vamp_dir(CACHE)


def panda_files(vamp: Path, folder: Path) -> tuple[Path, Path]:
    """VAMP's Panda URDF and SRDF in ``folder``, its collision meshes converted to STL in
    ``folder/meshes`` (the visual ones dropped).

    MPlib 0.2.1 (assimp) refuses VAMP's ``link6.obj`` ("a face with 2 vertices"); trimesh
    reads it (dropping that degenerate face), so every side is given the same STL
    triangles.
    """
    import trimesh
    src = vamp / "resources" / "panda"
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    text = (src / "panda.urdf").read_text()
    text = re.sub(r"<visual>.*?</visual>", "", text, flags=re.S)

    def convert(m: re.Match[str]) -> str:
        out = meshes / (Path(m.group(1)).stem + ".stl")
        if not out.exists():
            mesh = trimesh.load(src / "meshes" / m.group(1), force="mesh")
            mesh.export(out)
        return f'filename="meshes/{out.name}"'

    text = re.sub(r'filename="package://meshes/([^"]+)"', convert, text)
    if "package://" in text:
        raise ValueError("a package:// URI outside meshes/ is left in VAMP's panda.urdf")
    urdf, srdf = folder / "panda.urdf", folder / "panda.srdf"
    urdf.write_text(text)
    srdf.write_text((src / "panda.srdf").read_text())
    return urdf, srdf


def _quat_matrix(q: Sequence[float]) -> np.ndarray:
    """Rotation of a ROS quaternion (x, y, z, w)."""
    x, y, z, w = (float(v) for v in q)
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw of rotation ``r`` (r = Rz(yaw) Ry(pitch) Rx(roll))."""
    pitch = float(np.arcsin(-np.clip(r[2, 0], -1.0, 1.0)))
    if abs(r[2, 0]) < 1 - 1e-9:
        return float(np.arctan2(r[2, 1], r[2, 2])), pitch, float(np.arctan2(r[1, 0], r[0, 0]))
    return 0.0, pitch, float(np.arctan2(-r[0, 1], r[1, 1]))  # gimbal lock: roll folded in


def _pose(p: dict | None) -> np.ndarray:
    t = np.eye(4)
    if p:
        t[:3, :3] = _quat_matrix(p.get("orientation", (0, 0, 0, 1)))
        t[:3, 3] = np.asarray(p.get("position", (0, 0, 0)), float)
    return t


def scene_obstacles(data: dict) -> tuple[Obstacle, ...]:
    """A MoveIt scene YAML's collision objects as obstacles (first primitive of each)."""
    out = []
    for co in data["world"]["collision_objects"]:
        prim = co["primitives"][0]
        t = _pose(co.get("pose")) @ _pose(co["primitive_poses"][0])
        kind, dims = prim["type"], [float(v) for v in prim["dimensions"]]
        xyz, rpy = tuple(t[:3, 3]), matrix_rpy(t[:3, :3])
        if kind == "box":
            out.append(Obstacle(co["id"], "box", size=tuple(dims), xyz=xyz, rpy=rpy))
        elif kind == "sphere":
            out.append(Obstacle(co["id"], "sphere", radius=dims[0], xyz=xyz, rpy=rpy))
        elif kind == "cylinder":  # MoveIt: (height, radius)
            out.append(Obstacle(co["id"], "cylinder", length=dims[0], radius=dims[1],
                                xyz=xyz, rpy=rpy))
        else:
            raise ValueError(f"{co['id']}: primitive type {kind!r} unknown")
    return tuple(out)


def request_ends(data: dict) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A MoveIt request YAML's start and (first) joint goal, :data:`JOINTS` order."""
    js = data["start_state"]["joint_state"]
    start = tuple(float(js["position"][js["name"].index(j)]) for j in JOINTS)
    goal_of = {c["joint_name"]: float(c["position"])
               for c in data["goal_constraints"][0]["joint_constraints"]}
    return start, tuple(goal_of[j] for j in JOINTS)


def read_problems(vamp: Path, scenes: Sequence[str] = SCENES) -> dict[str, list[MbmProblem]]:
    """Every problem of ``scenes`` in VAMP's ``problems.tar.bz2``, by scene, in index order."""
    found: dict[str, dict[int, dict[str, dict]]] = {s: {} for s in scenes}
    with tarfile.open(vamp / "resources" / "panda" / "problems.tar.bz2", "r:bz2") as tar:
        for m in tar.getmembers():
            if not m.isfile():
                continue
            _, folder, filename = m.name.split("/")
            scene = folder.removesuffix("_panda")
            if scene not in found:
                continue
            f = tar.extractfile(m)
            assert f is not None
            kind = "scene" if "scene" in filename else "request"
            index = int(re.findall(r"\d+", filename)[0])
            found[scene].setdefault(index, {})[kind] = yaml.load(f.read(), Loader=yaml.CSafeLoader)
    out: dict[str, list[MbmProblem]] = {}
    for scene, by_index in found.items():
        out[scene] = []
        for i in sorted(by_index):
            start, goal = request_ends(by_index[i]["request"])
            out[scene].append(MbmProblem(scene, i, start, goal,
                                         scene_obstacles(by_index[i]["scene"])))
    return out


def pick(problems: dict[str, list[MbmProblem]], n: int, seed: int,
         valid: Callable[[MbmProblem], bool]) -> tuple[list[MbmProblem], dict[str, int]]:
    """``n`` problems per scene drawn in a seeded order, keeping those ``valid`` accepts
    (start and goal collision-free on our checker); and per scene how many were skipped."""
    rng = np.random.default_rng(seed)
    out, skipped = [], {}
    for scene, probs in problems.items():
        kept, skipped[scene] = 0, 0
        for i in rng.permutation(len(probs)):
            if kept == n:
                break
            if valid(probs[i]):
                out.append(probs[i])
                kept += 1
            else:
                skipped[scene] += 1
    return out, skipped
