"""What a worker does with one validated request: fk, ik, check or plan (and the
execute wing's ``recheck``: :mod:`arduinobot.service.plan.recheck`).

A :class:`Handlers` owns everything built from the description once per process (the
kinematics, the obstacle-free collision world, the motion planner), so a request pays
only for its own work. Results are JSON-ready dicts; failures raise
:class:`arduinobot.contract.errors.PlanningError` subclasses whose ``code`` goes on the wire.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import Description
from arduinobot.description.model import rpy_of
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.checks import joint_values
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik import position_ik
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.tcp_goals import tcp_joints
from arduinobot.scene.ground import with_ground
from arduinobot.scene.state import SceneSnapshot, with_scene
from arduinobot.service.plan.requests import obstacles

_log = logging.getLogger(__name__)

_SCENE_CACHE = 4


class Handlers:
    """The request handlers of one worker process, for one robot description."""

    def __init__(self, description: Description, *, cache: ArtifactCache | None = None
                 ) -> None:
        self.description = description
        self.cache = cache
        self.kin = Kinematics(description.robot)
        # Padded scenes are not the planner's (it caches unpadded worlds): keep a few here.
        self._padded_scene = functools.lru_cache(_SCENE_CACHE)(self._padded)
        self._planner: Any = None
        self._frames: Any = None  # the kept scene's attach and detach (built on first use)
        # (world, its Certifier) of the last recheck (arduinobot.service.plan.recheck)
        self.recheck_certifier: tuple[Any, Any] | None = None

    def warm_up(self) -> None:
        """Build the planner (and its obstacle-free world) and plan one short motion now,
        not on the first request: every compiled kernel is loaded (or, on a machine's
        first start, compiled and cached) before the service says it is ready."""
        from arduinobot.planner.planning.pipeline import (
            MotionRequest,  # the heaviest import: only if used
        )

        mp = self._motion_planner()
        desc = self.description
        joints = desc.group_joints()[desc.default_group()]
        if not joints:
            return
        name = joints[0]
        lo, hi = desc.robot.position_limits((name,))[0]
        step = 0.05 if hi >= 0.05 else -0.05
        if not lo <= step <= hi:
            return
        try:
            mp.solve(MotionRequest(goal=JointGoal({name: step}), group="all", seed=0))
        except PlanningError as e:
            # e.g. the robot collides at all zeros: nothing to warm with, not a failure
            _log.info("warm-up motion not planned (%s: %s)", e.code, e.message)

    def _motion_planner(self) -> Any:
        if self._planner is None:
            from arduinobot.planner.planning.pipeline import (
                MotionPlanner,  # the heaviest import: only if used
            )
            self._planner = MotionPlanner(self.description, cache=self.cache)
        return self._planner

    def _q(self, values: Mapping[str, float] | None, field: str) -> np.ndarray:
        vals = joint_values(self.description, values, field=field)
        return np.array([vals[n] for n in self.kin.joint_names])

    def handle(self, kind: str, data: Mapping[str, Any], *,
               scene: SceneSnapshot | None = None) -> dict[str, Any]:
        """Dispatch one request of ``kind`` (``fk``, ``ik``, ``check``, ``plan``); plans and
        checks add the kept ``scene``'s objects to their own obstacles, fk reports where
        its carried objects are."""
        if kind in ("check", "plan", "fk"):
            return {"check": self.check, "plan": self.plan, "fk": self.fk}[kind](
                data, scene=scene)
        if kind == "recheck":  # a running motion's rest (the execute wing's)
            if "pieces" in data:  # a task's: each step's piece in that step's world
                from arduinobot.service.plan.task_recheck import recheck_task
                return recheck_task(self, data, scene=scene)
            from arduinobot.service.plan.recheck import recheck
            return recheck(self, data, scene=scene)
        fn = {"ik": self.ik}.get(kind)
        if fn is None:
            raise InvalidRequest(f"unknown request kind '{kind}'")
        return fn(data)

    def fk(self, data: Mapping[str, Any], *, scene: SceneSnapshot | None = None
           ) -> dict[str, Any]:
        """Link poses in the world frame: xyz [m], rpy [rad], 4x4 matrix; tcp position [m];
        and the world pose of each object the kept ``scene`` carries (``carried``)."""
        q = self._q(data.get("joints"), "joints")
        links = list(data.get("links") or self.kin.link_names)
        for i, link in enumerate(links):
            if link not in self.kin.link_index:
                raise InvalidRequest(f"no link '{link}'; links: {', '.join(self.kin.link_names)}",
                                     field=f"links[{i}]")
        poses = self.kin.link_poses(q)
        out = {link: {"xyz": [float(v) for v in poses[self.kin.link_index[link]][:3, 3]],
                      "rpy": list(rpy_of(poses[self.kin.link_index[link]][:3, :3])),
                      "matrix": poses[self.kin.link_index[link]].tolist()} for link in links}
        tcp = self.description.tcp
        tcp_xyz = None if tcp is None else [
            float(v) for v in self.kin.point_position(q, tcp.parent_link, tcp.xyz)]
        carried = tuple(scene.attached) if scene is not None else ()
        return {"joints": dict(zip(self.kin.joint_names, map(float, q))), "links": out,
                "tcp": tcp_xyz,
                **({"carried": self._carried_poses(q, carried, scene)} if carried else {})}

    def ik(self, data: Mapping[str, Any]) -> dict[str, Any]:
        """Every tcp position IK branch within the joint limits (GOAL_OUT_OF_REACH if none)."""
        desc = self.description
        if desc.tcp is None:
            raise InvalidRequest("this description has no tcp (config/tcp.yaml)")
        # the default group's joints that move the tcp
        joints = tcp_joints(desc, desc.group_joints()[desc.default_group()])
        sols = position_ik(self.kin, desc.tcp, [float(v) for v in data["position"]],
                           joints=joints)
        return {"solutions": [{"joints": dict(zip(self.kin.joint_names, map(float, s.q))),
                               "branch": s.branch} for s in sols]}

    def check(self, data: Mapping[str, Any], *, scene: SceneSnapshot | None = None
              ) -> dict[str, Any]:
        """Validity of one state: colliding pairs, clearance [m] and the closest pair;
        a carried object resting on something (touching it) is named in ``resting``,
        with the ``hint`` a plan from there would give."""
        q = self._q(data.get("joints"), "joints")
        obs, revision = with_scene(scene, data, obstacles(self.description,
                                                          data.get("obstacles")))
        from arduinobot.service.plan.plan_io import attached
        carried = attached(self.description, data.get("attached"), scene=scene,
                           obstacles=obs)
        clouds = scene.clouds if scene is not None else ()
        world = self.scene_world(obs, float(data.get("padding", 0.0)), clouds,
                            ground=bool(data.get("ground", True)))
        if carried:  # the scene's and the request's carried objects, contacts and poses
            world = world.with_scene(world.obstacles, attached=carried)  # the ground's too
        res = world.check(q, clearance=True)
        clearance = res.clearance if res.clearance is not None and math.isfinite(
            res.clearance) else None
        resting = self._resting(world, carried, res.pairs, q) if carried and \
            not res.valid else {}
        return {"valid": bool(res.valid), "pairs": [list(p) for p in res.pairs],
                "clearance": clearance,
                "closest": list(res.closest) if res.closest else None,
                "joints": dict(zip(self.kin.joint_names, map(float, q))),
                "scene_revision": revision,
                **({"clouds": scene.assumptions()} if scene is not None and scene.unknown
                   else {}),
                **({"carried": self._carried_poses(q, carried, scene)} if carried else {}),
                **resting}

    @staticmethod
    def _resting(world: CollisionWorld, carried: tuple[Any, ...],
                 pairs: Any, q: np.ndarray) -> dict[str, Any]:
        # a carried object only touching what it rests on: the state stays invalid (a
        # plan from it is refused but for a line that lifts it off), the reply says so
        from arduinobot.planner.planning.resting import hint, resting_pairs
        found = resting_pairs(world.kin, carried, world.obstacles, pairs, q)
        return {"resting": [list(p) for p in found], "hint": hint(found)} if found else {}

    def _carried_poses(self, q: Any, carried: tuple[Any, ...], scene: SceneSnapshot | None
                       ) -> dict[str, Any]:
        # each carried object's world pose: its link's times its pose in that link; those
        # added in a link's frame say so (fixed there, not picked up)
        poses = self.kin.link_poses(q)
        fixed = scene.fixed if scene is not None else frozenset()
        out = {}
        for a in carried:
            t = poses[self.kin.link_index[a.link]] @ a.shape.pose()
            out[a.id] = {"link": a.link, "xyz": [float(v) for v in t[:3, 3]],
                         "rpy": list(rpy_of(t[:3, :3])), "matrix": t.tolist(),
                         **({"fixed": True} if a.id in fixed else {})}
        return out

    def scene_world(self, obs: tuple[Any, ...], padding: float,
                    clouds: tuple[Any, ...] = (), *, ground: bool = True,
                    attached: tuple[Any, ...] = (),
                    allowed: tuple[tuple[str, str], ...] = ()) -> CollisionWorld:
        """The collision world of ``obs`` (and ``clouds``, the ground unless ``ground`` is
        false) with ``padding`` [m], built once per distinct set; ``attached`` and
        ``allowed`` (a task's step's carried objects and pairs allowed to touch) only
        without padding."""
        if padding == 0.0:
            return self._motion_planner().world(obs, attached, clouds, ground=ground,
                                                allowed=allowed)
        if attached or allowed:
            raise InvalidRequest("carried objects and allowed pairs are checked without "
                                 "padding", field="padding")
        return self._padded_scene(obs, padding, clouds, ground)

    def _padded(self, obs: tuple[Any, ...], padding: float,
                clouds: tuple[Any, ...] = (), ground: bool = True) -> CollisionWorld:
        return self._motion_planner().world(()).with_scene(
            with_ground(obs, ground), padding=padding, clouds=clouds)

    def plan(self, data: Mapping[str, Any], *, scene: SceneSnapshot | None = None
             ) -> dict[str, Any]:
        """A v1 plan request (validated by the schema) -> the v1 response body."""
        from arduinobot.service.plan.plan_io import plan_response
        return {**plan_response(self.solve(data, scene=scene),
                                trajectory_format=data.get("trajectory_format", "points")),
                "scene_revision": scene.revision if scene is not None else 0,
                **({"clouds": scene.assumptions()} if scene is not None and scene.unknown
                   else {})}

    def frames(self, data: Mapping[str, Any]) -> dict[str, Any]:
        """A ``frames`` job: a link's pose or a carried object's contacts for the kept
        scene's attach and detach (see :class:`arduinobot.service.scene.carry.PooledFrames`)."""
        from arduinobot.planner.frames import RobotFrames
        from arduinobot.service.scene.carry import answer_frames, answer_mesh
        if data["op"] == "mesh":  # the scene's inline mesh: no robot needed
            return answer_mesh(data)
        if self._frames is None:  # the planner's robot geometry, not a second build
            base = self._motion_planner().world(())
            self._frames = RobotFrames(self.description, kin=base.kin, bodies=base.bodies)
        return answer_frames(self._frames, data)

    def task(self, data: Mapping[str, Any], *, scene: SceneSnapshot | None = None) -> Any:
        """A ``task`` job (see :func:`arduinobot.service.task.task_service.answer_task`) planned with this
        worker's planner -> its :class:`~arduinobot.service.messages.Success`."""
        from arduinobot.service.task.task_service import answer_task
        return answer_task(self._motion_planner(), data, scene=scene)

    def solve(self, data: Mapping[str, Any], *, scene: SceneSnapshot | None = None) -> Any:
        """A v1 plan request (validated) against ``scene`` -> the planner's MotionResult,
        which :func:`arduinobot.service.plan.plan_io.plan_response` (or, encoded at once, ``plan_reply``)
        answers."""
        from arduinobot.service.plan.plan_io import plan_request
        return self._motion_planner().solve(plan_request(self.description, data, scene=scene))
