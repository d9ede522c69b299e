"""An independent re-check of timed trajectories, for the benchmarks only.

It shares no code with the planner's checks (arduinobot.planner.timing.verify, arduinobot.planner.kinematics.dynamics,
arduinobot.planner.kinematics.chain, arduinobot.planner.collision, arduinobot.planner.collision.proof.motion_check): the URDF is parsed by
yourdfpy, forward kinematics is the few lines below, torques come from MuJoCo's inverse
dynamics on an MJCF built from the URDF's inertials and joints (the approach of
tests/planner/kinematics/test_dynamics.py; the mimic joint_5 is driven by joint_4 and its torque folds
into joint_4 with its multiplier), collisions are python-fcl on the link meshes
(loaded by trimesh) with the SRDF's disabled pairs read straight from the XML.

Only positions are taken from the trajectory under test (``positions(ts)``, e.g.
``JointTrajectory.at(t).positions``); every derivative is a finite difference on a
uniform grid of step ``h`` [s], padded by rest before and after (a trajectory must
start and end at rest, so a jump there shows up as a spike):

- velocity ``(q[i+1]-q[i])/h``, acceleration ``(q[i+1]-2q[i]+q[i-1])/h^2`` and jerk
  (third difference / h^3) are averages of the true derivative with positive weights
  (B-spline kernels of width 1, 2, 3 steps), so they never exceed its true peak: the
  bounds are not widened for discretisation, only for floating-point rounding of the
  differences (``4 * 2^k eps max|q| / h^k`` for the k-th difference) plus 1e-6 relative,
  the tolerance the product's verifier uses for limits met exactly.
- effort: MuJoCo's inverse dynamics at ``q[i]``, the central velocity and the second
  difference. The acceleration is the average over [t-h, t+h] while q and qd are taken
  at t. Torque is affine in qdd at fixed (q, qd), so that part is again a positive-weight
  average of true torques; what remains is q and qd moving over the +-h window, which
  moves the torque by under 1e-4 of the limit at h = 0.25 ms on these trajectories
  (measured), so effort passes at 1 + 1e-3.
- collisions: positions at states no more than ``step`` (0.0005 rad) apart in every
  joint (cumulative motion since the last kept state), each checked with fcl.collide on
  every enabled link/link and link/obstacle pair whose covering spheres overlap (eight
  spheres per mesh, each holding whole triangles; an obstacle's one bounding sphere).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import fcl
import mujoco
import numpy as np
import trimesh
import yourdfpy

EPS = np.finfo(float).eps
REL_TOL = 1e-6
EFFORT_TOL = 1e-3


@dataclass(frozen=True)
class Limits:
    """Per actuated joint: position [rad], velocity [rad/s], acceleration [rad/s^2],
    jerk [rad/s^3], effort [N m], each shape (dof,)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    effort: np.ndarray


@dataclass(frozen=True)
class RecheckReport:
    """Worst ratio to the limit per quantity, the violated ones, and collisions found."""

    worst: dict[str, float]
    violations: tuple[str, ...]
    colliding_states: int
    first_collision: tuple[float, str, str] | None
    checked_states: int
    max_step: float

    @property
    def ok(self) -> bool:
        return not self.violations


def _rpy_quat(rot: np.ndarray) -> str:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot, float).ravel())
    return " ".join(repr(float(v)) for v in q)


def _axis_rotations(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axis`` by angles ``q`` (m,), shape (m, 3, 3) (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(q)[:, None, None], np.cos(q)[:, None, None]
    return np.eye(3)[None] + s * kx[None] + (1 - c) * (kx @ kx)[None]


class IndependentModel:
    """The robot as yourdfpy, MuJoCo and FCL see it.

    Args:
        urdf: an expanded URDF with absolute mesh paths.
        srdf: its SRDF (only ``disable_collisions`` is read).
        actuated: the joint order of every q, qd, qdd, tau array.
    """

    def __init__(self, urdf: Path, srdf: Path, actuated: Sequence[str]) -> None:
        self.urdf = yourdfpy.URDF.load(str(urdf), build_scene_graph=False, load_meshes=False,
                                       load_collision_meshes=False)
        self.actuated = tuple(actuated)
        self.folder = Path(urdf).parent  # relative mesh paths are relative to the URDF
        self.joints = {j.name: j for j in self.urdf.robot.joints}
        self.links = {lk.name: lk for lk in self.urdf.robot.links}
        children = {j.child for j in self.joints.values()}
        self.root = next(n for n in self.links if n not in children)
        self.order = []  # joints in topological order
        frontier = [self.root]
        while frontier:
            parent = frontier.pop(0)
            for j in self.joints.values():
                if j.parent == parent:
                    self.order.append(j)
                    frontier.append(j.child)
        self._mujoco()
        self._collision(srdf)

    # -- kinematics ---------------------------------------------------------------------
    def joint_values(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        """Every movable joint's value per state (mimics from their leaders)."""
        out = {n: qs[:, i] for i, n in enumerate(self.actuated)}
        for j in self.order:
            if j.mimic is not None and j.type != "fixed":  # a fixed one (Panda fingers) stays
                out[j.name] = j.mimic.multiplier * out[j.mimic.joint] + j.mimic.offset
        return out

    def link_poses(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        """World pose of every link, shape (m, 4, 4) each."""
        qs = np.atleast_2d(qs)
        m = len(qs)
        vals = self.joint_values(qs)
        poses = {self.root: np.broadcast_to(np.eye(4), (m, 4, 4)).copy()}
        for j in self.order:
            origin = j.origin if j.origin is not None else np.eye(4)
            t = poses[j.parent] @ origin
            if j.type in ("revolute", "continuous"):
                r = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
                r[:, :3, :3] = _axis_rotations(np.asarray(j.axis, float), vals[j.name])
                t = t @ r
            elif j.type == "prismatic":
                r = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
                r[:, :3, 3] = np.asarray(j.axis, float)[None] * vals[j.name][:, None]
                t = t @ r
            poses[j.child] = t
        return poses

    # -- dynamics -----------------------------------------------------------------------
    def mjcf(self) -> str:
        def body(link: str, indent: str) -> str:
            out = []
            inertial = self.links[link].inertial
            # the root is MuJoCo's world body: fixed, its inertia moves nothing (and
            # MuJoCo refuses one there, as the Panda's link0 has); a "massless" frame's
            # placeholder (the SO-101's 1e-9 kg, zero inertia, which MuJoCo refuses) adds
            # no torque the effort check could see
            if link != self.root and inertial is not None and inertial.mass \
                    and inertial.mass > 1e-6:
                o = inertial.origin if inertial.origin is not None else np.eye(4)
                t = o[:3, :3] @ np.asarray(inertial.inertia, float) @ o[:3, :3].T
                full = " ".join(repr(float(v)) for v in
                                (t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]))
                pos = " ".join(repr(float(v)) for v in o[:3, 3])
                out.append(f'{indent}<inertial pos="{pos}" mass="{float(inertial.mass)!r}" '
                           f'fullinertia="{full}"/>')
            for j in self.order:
                if j.parent != link:
                    continue
                o = j.origin if j.origin is not None else np.eye(4)
                pos = " ".join(repr(float(v)) for v in o[:3, 3])
                out.append(f'{indent}<body name="{j.child}" pos="{pos}" '
                           f'quat="{_rpy_quat(o[:3, :3])}">')
                if j.type in ("revolute", "continuous", "prismatic"):
                    kind = "slide" if j.type == "prismatic" else "hinge"
                    axis = " ".join(repr(float(v)) for v in j.axis)
                    out.append(f'{indent}  <joint name="{j.name}" type="{kind}" axis="{axis}" '
                               'limited="false" damping="0" armature="0"/>')
                out.append(body(j.child, indent + "  "))
                out.append(f"{indent}</body>")
            return "\n".join(x for x in out if x)

        return ('<mujoco model="recheck">\n  <option gravity="0 0 -9.81"/>\n'
                '  <compiler angle="radian" balanceinertia="false" boundmass="0" '
                f'boundinertia="0"/>\n  <worldbody>\n{body(self.root, "    ")}\n'
                '  </worldbody>\n</mujoco>\n')

    def _mujoco(self) -> None:
        self.mj = mujoco.MjModel.from_xml_string(self.mjcf())
        self.mjd = mujoco.MjData(self.mj)
        self._dof_map = []  # mujoco dof -> (actuated index, multiplier, offset)
        for d in range(self.mj.nv):
            name = mujoco.mj_id2name(self.mj, mujoco.mjtObj.mjOBJ_JOINT, self.mj.dof_jntid[d])
            j = self.joints[name]
            if j.mimic is not None:
                self._dof_map.append((self.actuated.index(j.mimic.joint),
                                      float(j.mimic.multiplier), float(j.mimic.offset)))
            else:
                self._dof_map.append((self.actuated.index(name), 1.0, 0.0))

    def torques(self, qs: np.ndarray, qds: np.ndarray, qdds: np.ndarray) -> np.ndarray:
        """MuJoCo inverse dynamics, mimic torques folded into leaders, shape (m, dof)."""
        idx = np.array([a for a, _, _ in self._dof_map])
        mult = np.array([m for _, m, _ in self._dof_map])
        off = np.array([o for _, _, o in self._dof_map])
        qpos, qvel, qacc = mult * qs[:, idx] + off, mult * qds[:, idx], mult * qdds[:, idx]
        frc = np.empty_like(qpos)
        d = self.mjd
        for k in range(len(qs)):
            d.qpos[:] = qpos[k]
            d.qvel[:] = qvel[k]
            d.qacc[:] = qacc[k]
            mujoco.mj_inverse(self.mj, d)
            frc[k] = d.qfrc_inverse
        out = np.zeros((len(qs), len(self.actuated)))
        for i in range(len(idx)):
            out[:, idx[i]] += mult[i] * frc[:, i]
        return out

    # -- collision ----------------------------------------------------------------------
    def _collision(self, srdf: Path) -> None:
        self.geoms: dict[str, tuple[fcl.CollisionObject, np.ndarray, np.ndarray, float]] = {}
        for name, link in self.links.items():
            parts = []
            for c in link.collisions:
                mesh = c.geometry.mesh
                if mesh is None:
                    raise ValueError(f"link {name}: only mesh collision geometry is supported")
                f = Path(mesh.filename)
                tm = trimesh.load(f if f.is_absolute() else self.folder / f, force="mesh")
                scale = np.ones(3) if mesh.scale is None else np.broadcast_to(
                    np.asarray(mesh.scale, float), 3)
                o = c.origin if c.origin is not None else np.eye(4)
                v = (np.asarray(tm.vertices) * scale) @ o[:3, :3].T + o[:3, 3]
                parts.append((v, np.asarray(tm.faces) + sum(len(p[0]) for p in parts)))
            if not parts:
                continue
            v = np.vstack([p[0] for p in parts])
            f = np.vstack([p[1] for p in parts])
            bvh = fcl.BVHModel()
            bvh.beginModel(len(v), len(f))
            bvh.addSubModel(v, f)
            bvh.endModel()
            centres, radii = _sphere_cover(v, f)
            self.geoms[name] = (fcl.CollisionObject(bvh, fcl.Transform()), v, centres, radii)
        disabled = set()
        for e in ET.parse(srdf).getroot().iter("disable_collisions"):
            disabled.add(frozenset((e.get("link1"), e.get("link2"))))
        names = sorted(self.geoms)
        self.self_pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]
                           if frozenset((a, b)) not in disabled]

    def colliding(self, qs: np.ndarray, obstacles: Sequence[dict]) -> list[tuple[int, str, str]]:
        """(state index, name, name) of every colliding pair at each state."""
        poses = self.link_poses(qs)
        # sphere centres in the world, (m, k, 3) per link
        centres = {n: np.einsum("mij,kj->mki", poses[n][:, :3, :3], g[2]) + poses[n][:, None, :3, 3]
                   for n, g in self.geoms.items()}
        obs = []
        for o in obstacles:
            shape, xyz = o["shape"], np.asarray(o.get("xyz", (0, 0, 0)), float)
            rpy = o.get("rpy", (0, 0, 0))
            rot = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")[:3, :3]
            if shape == "box":
                geom, r = fcl.Box(*o["size"]), 0.5 * float(np.linalg.norm(o["size"]))
            elif shape == "sphere":
                geom, r = fcl.Sphere(o["radius"]), float(o["radius"])
            elif shape == "cylinder":
                geom = fcl.Cylinder(o["radius"], o["length"])
                r = math.hypot(o["radius"], 0.5 * o["length"])
            else:
                raise ValueError(f"obstacle shape {shape!r} not supported")
            obs.append((o["id"], fcl.CollisionObject(geom, fcl.Transform(rot, xyz)), xyz, r))
        pairs = [(a, b, centres[b], self.geoms[b][3]) for a, b in self.self_pairs]
        pairs += [(a, oid, np.broadcast_to(xyz, (len(qs), 1, 3)), np.array([r]))
                  for a in self.geoms for oid, _, xyz, r in obs]
        objs = {oid: ob for oid, ob, _, _ in obs}
        hits = []
        req = fcl.CollisionRequest()
        for a, b, cb, rb in pairs:
            # broad phase: any sphere of a's cover meets any sphere of b's
            gap = (np.linalg.norm(centres[a][:, :, None] - cb[:, None], axis=3)
                   - self.geoms[a][3][None, :, None] - rb[None, None, :])
            near = np.nonzero(gap.min(axis=(1, 2)) <= 0.0)[0]
            oa = self.geoms[a][0]
            ob = self.geoms[b][0] if b in self.geoms else objs[b]
            for k in near:
                oa.setTransform(fcl.Transform(poses[a][k, :3, :3], poses[a][k, :3, 3]))
                if b in self.geoms:
                    ob.setTransform(fcl.Transform(poses[b][k, :3, :3], poses[b][k, :3, 3]))
                if fcl.collide(oa, ob, req, fcl.CollisionResult()) > 0:
                    hits.append((int(k), a, b))
        return hits


def _sphere_cover(v: np.ndarray, f: np.ndarray, k: int = 8
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``k`` spheres covering every triangle: faces grouped by centroid (a few
    k-means steps, seeded), each sphere holds all vertices of its faces, so it holds the
    whole triangles (a ball is convex). Centres (k, 3), radii (k,) [m]."""
    cen = v[f].mean(axis=1)
    rng = np.random.default_rng(0)
    c = cen[rng.choice(len(cen), size=min(k, len(cen)), replace=False)]
    for _ in range(10):
        lab = np.argmin(np.linalg.norm(cen[:, None] - c[None], axis=2), axis=1)
        c = np.array([cen[lab == i].mean(axis=0) if np.any(lab == i) else c[i]
                      for i in range(len(c))])
    lab = np.argmin(np.linalg.norm(cen[:, None] - c[None], axis=2), axis=1)
    used = [i for i in range(len(c)) if np.any(lab == i)]
    radii = np.array([np.linalg.norm(v[f[lab == i]].reshape(-1, 3) - c[i], axis=1).max()
                      for i in used])
    return c[used], radii


def dense_positions(positions: Callable[[np.ndarray], np.ndarray], ts: np.ndarray,
                    qs: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """States along the trajectory with every joint's cumulative motion between kept
    states <= ``step`` [rad]: refine the time grid until each interval moves < step / 2,
    then keep a state whenever the next would pass ``step``."""
    for _ in range(12):
        inc = np.max(np.abs(np.diff(qs, axis=0)), axis=1)
        bad = np.nonzero(inc > 0.5 * step)[0]
        if not len(bad):
            break
        extra = np.concatenate([np.linspace(ts[i], ts[i + 1],
                                            int(math.ceil(2 * inc[i] / (0.5 * step))) + 1)[1:-1]
                                for i in bad])
        ts = np.concatenate([ts, extra])
        order = np.argsort(ts, kind="stable")
        ts = ts[order]
        qs = np.concatenate([qs, positions(extra)])[order]
    else:
        raise RuntimeError("positions do not converge under refinement (a jump?)")
    keep, acc = [0], np.zeros(qs.shape[1])
    for i in range(1, len(qs)):
        d = np.abs(qs[i] - qs[i - 1])
        if np.any(acc + d > step):
            keep.append(i - 1)
            acc = np.zeros_like(acc)
        acc += d
    keep.append(len(qs) - 1)
    keep = np.unique(keep)
    return ts[keep], qs[keep]


def recheck(model: IndependentModel, positions: Callable[[np.ndarray], np.ndarray],
            duration: float, limits: Limits, *, obstacles: Sequence[dict] = (),
            enforce_jerk: bool = True, h: float = 2.5e-4, step: float = 5e-4
            ) -> RecheckReport:
    """Re-derive every limit and collision from positions alone (see the module doc).

    ``positions(ts)``: actuated joint positions [rad] at times ``ts`` [s] in [0, duration],
    shape (m, dof).
    """
    n = max(1, int(math.ceil(duration / h)))
    hh = duration / n if duration > 0 else h
    grid = np.arange(-3, n + 4) * hh
    inside = positions(np.clip(grid[3:-3], 0.0, duration))
    # rest before the start and after the end
    q = np.vstack([np.repeat(inside[:1], 3, axis=0), inside, np.repeat(inside[-1:], 3, axis=0)])
    scale = max(1.0, float(np.max(np.abs(q))))
    v = np.diff(q, axis=0) / hh
    a = (q[2:] - 2 * q[1:-1] + q[:-2]) / hh**2
    j = (q[3:] - 3 * q[2:-1] + 3 * q[1:-2] - q[:-3]) / hh**3
    tol = {k: 4 * 2**k * EPS * scale / hh**k for k in (1, 2, 3)}
    mid, half = 0.5 * (limits.lower + limits.upper), 0.5 * (limits.upper - limits.lower)
    worst = {
        "position": float(np.max(np.abs(inside - mid) / half)),
        "velocity": float(np.max((np.abs(v) - tol[1]) / limits.velocity)),
        "acceleration": float(np.max((np.abs(a) - tol[2]) / limits.acceleration)),
        "jerk": float(np.max((np.abs(j) - tol[3]) / limits.jerk)),
    }
    qd_c = (q[2:] - q[:-2]) / (2 * hh)
    tau = model.torques(q[1:-1], qd_c, a)
    worst["effort"] = float(np.max(np.abs(tau) / limits.effort))
    bounds = {"position": 1 + REL_TOL,
              "velocity": 1 + REL_TOL, "acceleration": 1 + REL_TOL, "jerk": 1 + REL_TOL,
              "effort": 1 + EFFORT_TOL}
    kinds = [k for k in bounds if enforce_jerk or k != "jerk"]
    violations = [k for k in kinds if worst[k] > bounds[k]]
    ts, qs = dense_positions(positions, np.clip(grid[3:-3], 0.0, duration), inside, step)
    hits = model.colliding(qs, obstacles)
    first = None
    if hits:
        k, a_, b_ = min(hits)
        first = (float(ts[k]), a_, b_)
        violations.append("collision")
    max_step = float(np.max(np.abs(np.diff(qs, axis=0)))) if len(qs) > 1 else 0.0
    return RecheckReport(worst=worst, violations=tuple(violations),
                         colliding_states=len({h_[0] for h_ in hits}), first_collision=first,
                         checked_states=len(qs), max_step=max_step)
