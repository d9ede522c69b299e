"""A 7-joint arm with millimetre CAD-like meshes (tests/helpers/seven_joint.py) in
generated clutter (tests/helpers/mbm_scenes.py: a shelf and a cage), planned through a real
``arduinobot serve``: solved, certified, and re-checked collision-free by an independent
check (scipy forward kinematics over the URDF, python-fcl on the STL meshes read by
trimesh, the obstacles as FCL primitives) at 0.002 rad along the returned samples."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import fcl
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.obstacles import Obstacle
from arduinobot.service.process.disk_cache import DiskCache
from tests.helpers.fk import link_pose
from tests.helpers.mbm_scenes import problems_for
from tests.helpers.serve import start_server
from tests.helpers.seven_joint import make_seven_joint

STEP = 0.002  # [rad] the re-check's largest joint step


class IndependentCheck:
    """Colliding pairs of the arm's meshes and the obstacles (and the ground, for links
    that move), without the planner's collision code."""

    def __init__(self, description, names, urdf: Path, obstacles: tuple[Obstacle, ...]):
        self.robot, self.names = description.robot, names
        pkg = urdf.parent.parent
        self.links = {}
        for link in ET.parse(urdf).getroot().iter("link"):
            mesh = link.find("collision/geometry/mesh")
            if mesh is None:
                continue
            m = trimesh.load(pkg / "meshes" / Path(mesh.get("filename", "")).name)
            m.apply_scale(float(mesh.get("scale", "1 1 1").split()[0]))
            bvh = fcl.BVHModel()
            bvh.beginModel(len(m.vertices), len(m.faces))
            bvh.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int32))
            bvh.endModel()
            self.links[link.get("name")] = fcl.CollisionObject(bvh, fcl.Transform())
        srdf = pkg / "config" / "seven_bot.srdf"
        off = {frozenset((e.get("link1"), e.get("link2")))
               for e in ET.parse(srdf).getroot().iter("disable_collisions")}
        ls = list(self.links)
        self.self_pairs = [(a, b) for i, a in enumerate(ls) for b in ls[i + 1:]
                           if frozenset((a, b)) not in off]
        self.obstacles = {o.id: self._primitive(o) for o in obstacles}
        self.obstacles["ground"] = fcl.CollisionObject(
            fcl.Box(20.0, 20.0, 0.2), fcl.Transform(np.eye(3), np.array([0, 0, -0.1])))

    @staticmethod
    def _primitive(o: Obstacle) -> fcl.CollisionObject:
        geom = {"box": lambda: fcl.Box(*o.size), "sphere": lambda: fcl.Sphere(o.radius),
                "cylinder": lambda: fcl.Cylinder(o.radius, o.length)}[o.shape]()
        rot = Rotation.from_euler("xyz", o.rpy).as_matrix()
        return fcl.CollisionObject(geom, fcl.Transform(rot, np.asarray(o.xyz, float)))

    def colliding(self, q) -> list[tuple[str, str]]:
        for name, obj in self.links.items():
            t = link_pose(self.robot, name, self.names, q)
            obj.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
        req, hits = fcl.CollisionRequest(), []
        pairs = [(a, b, self.links[b]) for a, b in self.self_pairs]
        pairs += [(a, oid, obj) for a in self.links if a != "link0"
                  for oid, obj in self.obstacles.items()]
        for a, b, obj in pairs:
            if fcl.collide(self.links[a], obj, req, fcl.CollisionResult()):
                hits.append((a, b))
        return hits

    def along(self, positions: np.ndarray) -> list[tuple[int, tuple[str, str]]]:
        """(state, pair) of every collision along ``positions``, densified to STEP."""
        out = []
        for i in range(len(positions) - 1):
            a, b = positions[i], positions[i + 1]
            k = max(1, int(np.ceil(np.max(np.abs(b - a)) / STEP)))
            for s in np.arange(k) / k:
                out += [(i, p) for p in self.colliding(a + s * (b - a))]
        return out + [(len(positions) - 1, p) for p in self.colliding(positions[-1])]


@pytest.mark.slow
def test_a_seven_joint_arm_reaches_into_a_shelf_and_a_cage_certified_and_rechecked(tmp_path):
    urdf = make_seven_joint(tmp_path)
    d = load_description(urdf)
    mp = MotionPlanner(d, cache=DiskCache(tmp_path / "cache"))
    names = mp.joint_names
    assert len(names) == 7
    probs = problems_for(mp, names, n_per_scene=1, seed=3, reach=0.85, tip="tool0",
                         kinds=("shelf", "cage"))
    srv = start_server(["--workers", "1", str(urdf), "--cache-dir", str(tmp_path / "cache")],
                       timeout=900)
    try:
        with PlannerClient(srv.endpoint, timeout=600) as c:
            for p in probs:
                check = IndependentCheck(d, names, urdf, p.obstacles)
                start, goal = np.array(p.start), np.array(p.goal)
                assert check.colliding(start) == [] and check.colliding(goal) == [], p.name
                # the straight motion is blocked: the check finds it, the planner must detour
                assert check.along(np.array([start, goal])), p.name
                reply = c.plan({"start": dict(zip(names, p.start)),
                                "goal": {"joints": dict(zip(names, p.goal))},
                                "obstacles": [{"id": o.id, "shape": o.shape, "size": list(o.size),
                                               "xyz": list(o.xyz), "rpy": list(o.rpy)}
                                              for o in p.obstacles],
                                "planning_time": 10.0, "seed": 1})
                assert reply.verification.certified, p.name
                assert np.allclose(reply.positions[0], start, atol=1e-9)
                assert np.allclose(reply.positions[-1], goal, atol=1e-6)
                assert check.along(np.asarray(reply.positions)) == [], p.name
    finally:
        srv.stop()
