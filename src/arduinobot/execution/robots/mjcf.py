"""A MuJoCo model (MJCF) of a loaded description, for the simulated twin.

From :class:`arduinobot.description.Robot`: one body per link (the root welded to the world), its
inertial as given, one hinge/slide per movable joint with the URDF position limits, a
mimic joint as an equality constraint on its leader (``q = offset + multiplier *
q_leader``), collision shapes as contact geoms (a mesh as up to 32 convex pieces, see
:func:`mesh_parts`: MuJoCo collides convex hulls, and one hull around a concave part
touches what the part does not), and per actuated joint a position servo
with velocity feed-forward (see :func:`servo_ctrl`) whose force is capped at the URDF
effort. Contacts between a link and its parent, and the SRDF's disabled pairs (what the
planner trusts never to touch), are excluded; every other pair is live, and so are
obstacles (box, sphere, cylinder, or a mesh file as convex pieces, in the world frame) and
carried objects: each a body welded inside its link's (``carried:<id>``, its mass and
inertia as :meth:`arduinobot.scene.obstacles.AttachedObject.payload` gives them), its contacts with its
link and touch links excluded, as the planner excludes them. The ground
(:mod:`arduinobot.scene.ground`) is a plane at z = 0, ``obstacle:ground``, unless opted
out: what is let go lands on it (the links welded to the world never collide with it).
A loose object (what a task picks up) the task gives no mass is simulated as a solid of
:data:`LOOSE_DENSITY` (:func:`loose_body`): a massless free body is not one MuJoCo can
keep at rest.

The physics is MuJoCo's semi-implicit Euler: unlike ``implicitfast``, the actuator force
it reports is the force it applies (the implicit integrators fold part of the damping
into the step), so peak forces are comparable with the effort limits; with the default
servos ``kv h / M = 2 w h`` stays far below Euler's stability bound.

The servo force is ``kp (q_ref - q) + kv (qd_ref - qd)``, clamped to +-effort: a
``general`` actuator with gain ``kp`` and affine bias ``(0, -kp, -kv)`` driven by
``ctrl = q_ref + kv / kp * qd_ref``.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from arduinobot.description.model import Joint, Robot, Shape, rpy_matrix
from arduinobot.execution.robots.twin_clouds import cloud_geoms
from arduinobot.planner.cache import ArtifactCache, content_key
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.ground import GROUND_ID
from arduinobot.scene.obstacles import Obstacle

log = logging.getLogger(__name__)

#: told what is being built, for a user waiting on a first twin: ``progress(message)``
Progress = Callable[[str], None]

TIMESTEP = 0.001  # [s]
COLLISION_PARTS = 32  # convex pieces per collision mesh (at most)
#: [kg/m^3] a loose object the task gives no mass is simulated as a solid this dense
#: (water's; printed PLA is 1240, pine 500): a 2.5 cm cube weighs 16 g
LOOSE_DENSITY = 1000.0
#: a loose object's body and free joint are named this and its id; its grasp weld,
#: ``GRASP_PREFIX`` and its id (the twin finds them by these names)
LOOSE_PREFIX = "loose:"
GRASP_PREFIX = "grasp:"


@dataclass(frozen=True)
class Gains:
    """A position servo's stiffness ``kp`` [N m/rad] and damping ``kv`` [N m s/rad]."""

    kp: float
    kv: float


def _f(v: Sequence[float] | np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(v))


def _quat(rot: np.ndarray) -> str:
    import mujoco
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot, float).ravel())
    return _f(q)


def _esc(name: str) -> str:
    return name.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")


def mesh_parts(path: Path, scale: Sequence[float], parts: int, *,
               cache: ArtifactCache | None = None,
               progress: Progress | None = None) -> list[np.ndarray]:
    """A mesh as up to ``parts`` convex pieces for MuJoCo, which collides convex hulls:
    each piece's vertices [m], shape (k_i, 3).

    V-HACD's approximate convex decomposition (``vhacdx``, trimesh's backend) when it is
    installed: its hulls follow the surface within its tolerance. It takes seconds per
    mesh, so the pieces are kept in ``cache`` (the caller's: the command line and the
    service pass their disk cache; None computes them afresh) keyed by the mesh's bytes
    and scale. Without V-HACD, :func:`cluster_parts`. ``progress`` hears of each mesh
    decomposed afresh (seconds each: a first twin of a new model takes a while)."""
    import trimesh
    try:
        import vhacdx  # noqa: F401 -- trimesh's decomposition backend
    except ImportError:
        return cluster_parts(path, scale, parts)
    key = content_key([Path(path).read_bytes(), np.asarray(scale, float),
                       f"vhacd:{parts}:v1"])
    hit = None if cache is None else cache.load("mujoco_hulls", key)
    if hit is not None:
        return np.split(hit["vertices"], np.cumsum(hit["counts"])[:-1])
    if progress is not None:
        progress(f"convex pieces of {Path(path).name} for MuJoCo (first use of this mesh)")
    m = cast("trimesh.Trimesh", trimesh.load(path, force="mesh"))  # force: one mesh
    m.apply_scale(np.asarray(scale, float))
    got: Any = m.convex_decomposition(maxConvexHulls=parts)  # meshes or vertex dicts
    pieces = got if isinstance(got, list) else [got]
    out = [_thick(np.asarray(p.vertices if hasattr(p, "vertices") else p["vertices"], float))
           for p in pieces]
    out = [p for p in out if len(p) >= 3]
    if cache is not None:
        cache.store("mujoco_hulls", key, {"vertices": np.vstack(out),
                                          "counts": np.array([len(p) for p in out])})
    return out


def _thick(p: np.ndarray) -> np.ndarray:
    """A flat piece has no hull: give it 10 um of thickness along its normal."""
    if len(p) < 3:
        return p
    _, sv, vt = np.linalg.svd(p - p.mean(axis=0), full_matrices=False)
    if len(sv) < 3 or sv[2] <= 1e-9 * max(sv[0], 1e-12):
        return np.vstack([p, p + 1e-5 * vt[-1]])
    return p


def cluster_parts(path: Path, scale: Sequence[float], parts: int) -> list[np.ndarray]:
    """Faces grouped by centroid (scipy's k-means from seeded face centroids, 12 centre
    updates), each piece the vertices of its group's faces [m]: each hull holds its
    whole triangles, so the union holds the surface; looser than V-HACD where a group
    spans a concavity."""
    import trimesh
    from scipy.cluster.vq import kmeans2
    m = cast("trimesh.Trimesh", trimesh.load(path, force="mesh"))  # force: one mesh
    v = np.asarray(m.vertices, dtype=float) * np.asarray(scale, dtype=float)
    f = np.asarray(m.faces)
    cen = v[f].mean(axis=1)
    k = max(1, min(parts, len(f)))
    start = cen[np.random.default_rng(0).choice(len(cen), size=k, replace=False)]
    with warnings.catch_warnings():  # a group left empty keeps its centre: not news
        warnings.filterwarnings("ignore", "One of the clusters is empty")
        # its labels are those of the centres before its last update: 13 steps, 12 updates
        _, lab = kmeans2(cen, start, iter=13, minit="matrix")
    groups = (np.unique(f[lab == i]) for i in range(k))
    return [_thick(v[idx]) for idx in groups if len(idx) >= 3]


def _geom(shape: Shape, name: str, assets: list[str], cache: ArtifactCache | None,
          progress: Progress | None) -> str | None:
    """A collision shape as contact geoms (a mesh as :data:`COLLISION_PARTS` pieces)."""
    g = shape.geometry
    pose = f'pos="{_f(shape.origin.xyz)}" quat="{_quat(rpy_matrix(shape.origin.rpy))}"'
    common = f'{pose} contype="1" conaffinity="1" group="3" rgba="0.5 0.5 0.5 0.4" mass="0"'
    geom = g.mjcf()
    if geom is not None:  # a primitive
        return f'<geom type="{geom[0]}" size="{geom[1]}" name="{_esc(name)}" {common}/>'
    if g.source is not None:  # a mesh file that resolved: its convex pieces
        out = []
        for i, vs in enumerate(mesh_parts(g.source, g.source_scale, COLLISION_PARTS,
                                          cache=cache, progress=progress)):
            assets.append(f'<mesh name="{_esc(name)}/{i}" vertex="{_f(vs)}"/>')
            out.append(f'<geom type="mesh" mesh="{_esc(name)}/{i}" name="{_esc(name)}/{i}" '
                       f'{common}/>')
        return " ".join(out)
    return None


def obstacle_geoms(obstacles: Sequence[Mapping[str, Any] | Obstacle], *,
                   assets: list[str] | None = None, cache: ArtifactCache | None = None,
                   progress: Progress | None = None, prefix: str = "obstacle",
                   extra: str = "") -> list[str]:
    """Geoms for plain obstacles (:class:`Obstacle`, or one in the plan request's form, a
    mesh file as ``"mesh_path"`` in metres: the kept scene's form), named
    ``<prefix>:<id>``; a shape without an MJCF primitive (a mesh) as convex pieces of its
    file, which go to ``assets`` (needed then)."""
    out = []
    for i, form in enumerate(obstacles):
        o = obstacle_form(form, where=f"obstacles[{i}]")
        pose = f'pos="{_f(o.xyz)}" quat="{_quat(rpy_matrix(o.rpy))}"'
        name = _esc(f'{prefix}:{o.id}')
        common = f'{pose} contype="1" conaffinity="1" rgba="0.3 0.6 0.9 0.5"{extra}'
        geom = o.geometry.mjcf()
        if geom is not None:
            out.append(f'<geom name="{name}" type="{geom[0]}" size="{geom[1]}" {common}/>')
            continue
        source = o.geometry.source  # its convex pieces, as a link's mesh
        if source is None or assets is None:
            raise ValueError(f"obstacle '{o.id}' ({o.shape}) needs assets and a file for "
                             "its convex pieces")
        for j, vs in enumerate(mesh_parts(source, o.geometry.source_scale, COLLISION_PARTS,
                                          cache=cache, progress=progress)):
            assets.append(f'<mesh name="{name}/{j}" vertex="{_f(vs)}"/>')
            out.append(f'<geom name="{name}/{j}" type="mesh" mesh="{name}/{j}" {common}/>')
    return out


def obstacle_form(o: Any, *, where: str = "obstacle") -> Obstacle:
    """An :class:`arduinobot.scene.obstacles.Obstacle` as is, or one in the requests' form
    (a mapping) as one."""
    return o if isinstance(o, Obstacle) else Obstacle.from_mapping(o, where=where)


def carried_body(a: Any, assets: list[str], cache: ArtifactCache | None,
                 progress: Progress | None, *, prefix: str = "carried",
                 head: str = "") -> list[str]:
    """The MJCF lines of a carried object (a :class:`arduinobot.scene.obstacles.AttachedObject`): a
    body in its link's frame, no joint (welded), its payload's mass and inertia, its
    shape as contact geoms (massless: the inertial says the mass). ``head`` goes into
    the body's tag (a pose), its first line inside (a joint)."""
    lines = [f'<body name="{_esc(prefix + ":" + a.id)}"{head}>']
    p = a.payload()
    if p.mass > 0:
        t = np.asarray(p.inertia, float)
        lines.append(f'  <inertial pos="{_f(p.com)}" mass="{p.mass!r}" fullinertia="'
                     f'{_f([t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])}"/>')
    lines += ["  " + g for g in obstacle_geoms([a.shape], assets=assets,
                                                cache=cache, progress=progress,
                                                prefix=prefix, extra=' mass="0"')]
    lines.append("</body>")
    return lines


def _joint_element(j: Joint) -> str:
    """The ``<joint>`` of a revolute, continuous or prismatic URDF joint, its range
    limited where the URDF gives both bounds (a continuous joint never is)."""
    kind = "slide" if j.type == "prismatic" else "hinge"
    lim = j.limit
    if j.type != "continuous" and lim is not None and lim.lower is not None \
            and lim.upper is not None:
        rng = f'limited="true" range="{lim.lower!r} {lim.upper!r}"'
    else:
        rng = 'limited="false"'
    return f'<joint name="{_esc(j.name)}" type="{kind}" axis="{_f(j.axis)}" {rng}/>'


def _mimic_equalities(robot: Robot) -> list[str]:
    """The ``<equality>`` joint couplings of the URDF's mimic joints."""
    eq = []
    for n in robot.mimic_joints:
        m = robot.joints[n].mimic
        eq.append(f'<joint joint1="{_esc(n)}" joint2="{_esc(m.joint)}" '  # type: ignore
                  f'polycoef="{m.offset!r} {m.multiplier!r} 0 0 0"/>')  # type: ignore
    return eq


def _actuators(robot: Robot, gains: Mapping[str, Gains]) -> list[str]:
    """One position servo per actuated joint (``kp``, ``kv`` as an affine bias), its
    force within the URDF's effort (unbounded-ish 1e6 where none is given)."""
    act = []
    for n in robot.actuated_joints:
        g, lim = gains[n], robot.joints[n].limit
        effort = lim.effort if lim is not None and lim.effort > 0 else 1e6
        act.append(f'<general name="{_esc(n)}" joint="{_esc(n)}" gainprm="{g.kp!r}" '
                   f'biastype="affine" biasprm="0 {-g.kp!r} {-g.kv!r}" ctrllimited="false" '
                   f'forcelimited="true" forcerange="{-effort!r} {effort!r}"/>')
    return act


def loose_body(a: Any, assets: list[str], cache: ArtifactCache | None,
               progress: Progress | None) -> list[str]:
    """A loose object (an :class:`arduinobot.scene.obstacles.AttachedObject` whose shape is posed in
    the world): a free body ``loose:<id>`` where its shape is, with its mass, under
    gravity until :func:`to_mjcf`'s weld ``grasp:<id>`` to its link is switched on.

    An object of no mass (a pick step gives 0 kg unless told) is simulated as a uniform
    solid of :data:`LOOSE_DENSITY`: MuJoCo would make it a 1 mg body of 1e-9 kg m^2
    (``boundmass``/``boundinertia``), which its contact with the table it rests on
    spins and throws about (the SO-101's 2.5 cm cube slid 10 cm off its spot in the
    first 0.3 s, before the arm came near it)."""
    from dataclasses import replace
    if a.mass <= 0:
        mass = LOOSE_DENSITY * solid_volume(a.shape)
        log.info("twin: '%s' has no mass; simulated as %.4f kg (%g kg/m^3)", a.id, mass,
                 LOOSE_DENSITY)
        a = replace(a, mass=mass)
    pose = (f' pos="{_f(a.shape.xyz)}" '
            f'quat="{_quat(rpy_matrix(tuple(a.shape.rpy)))}"')
    at_origin = replace(a, shape=replace(a.shape, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)),
                        com=None)
    lines = carried_body(at_origin, assets, cache, progress, prefix="loose", head=pose)
    lines.insert(1, f'  <freejoint name="{_esc(LOOSE_PREFIX + a.id)}"/>')
    return lines


def solid_volume(shape: Obstacle) -> float:
    """[m^3] ``shape``'s volume as a solid (a mesh that is not closed: its bounding
    box's, as :meth:`arduinobot.scene.obstacles.AttachedObject.payload` takes its inertia)."""
    m = shape.geometry.triangles()
    if m.is_watertight and m.volume > 0:
        return float(m.volume)
    return float(np.prod(m.bounds[1] - m.bounds[0]))


def to_mjcf(robot: Robot, *, gains: Mapping[str, Gains],
            excluded: Sequence[tuple[str, str]] = (),
            obstacles: Sequence[Mapping[str, Any] | Obstacle] = (),
            attached: Sequence[Any] = (), loose: Sequence[Any] = (),
            cache: ArtifactCache | None = None, progress: Progress | None = None,
            ground: bool = True) -> str:
    """The MJCF text of ``robot`` (see the module doc).

    Args:
        gains: per actuated joint.
        excluded: link pairs whose contacts are ignored (besides parent/child pairs).
        obstacles: world obstacles, as in a plan request, or :class:`Obstacle` objects;
            a kept cloud (:class:`CloudObstacle`) as static boxes (:mod:`.twin_clouds`).
        attached: carried objects (:class:`arduinobot.scene.obstacles.AttachedObject`, touch links
            resolved), each welded inside its link.
        loose: objects free in the world (:func:`loose_body`, touch links resolved), each
            with an inactive weld ``grasp:<id>`` to its link for the twin to switch on
            while it is carried; what holds it never collides with it (as in the planner).
        cache, progress: the meshes' convex pieces (:func:`mesh_parts`).
        ground: a floor at z = 0 (the planner's ground), unless ``obstacles`` has one.
    """
    assets: list[str] = []
    held: dict[str, list[Any]] = {}
    for a in attached:
        held.setdefault(a.link, []).append(a)

    def body(link: str, indent: str) -> list[str]:
        out = []
        lk = robot.links[link]
        inertial = lk.inertial
        if inertial is not None and inertial.mass > 0 and link != "world":
            rot = rpy_matrix(inertial.origin.rpy)
            t = rot @ inertial.tensor() @ rot.T
            out.append(f'{indent}<inertial pos="{_f(inertial.origin.xyz)}" '
                       f'mass="{inertial.mass!r}" fullinertia="'
                       f'{_f([t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])}"/>')
        for i, s in enumerate(lk.collisions):
            g = _geom(s, f"{link}/collision/{i}", assets, cache, progress)
            if g:
                out.append(indent + g)
        for a in held.get(link, ()):
            out.extend(indent + line for line in carried_body(a, assets, cache, progress))
        for j in robot.child_joints[link]:
            out.append(f'{indent}<body name="{_esc(j.child)}" pos="{_f(j.origin.xyz)}" '
                       f'quat="{_quat(rpy_matrix(j.origin.rpy))}">')
            if j.type in ("revolute", "continuous", "prismatic"):
                out.append(f"{indent}  {_joint_element(j)}")
            out.extend(body(j.child, indent + "  "))
            out.append(f"{indent}</body>")
        return out

    root = robot.root
    if root == "world":  # URDF's conventional world link is MuJoCo's worldbody
        tree = body(root, "    ")
    else:
        tree = [f'    <body name="{_esc(root)}">', *body(root, "      "), "    </body>"]
    pairs = {frozenset((j.parent, j.child)) for j in robot.joints.values()
             if "world" not in (j.parent, j.child)}
    pairs |= {frozenset(p) for p in excluded if p[0] != p[1]}
    for a in attached:  # what holds it may touch it, as in the planner
        pairs |= {frozenset((f"carried:{a.id}", t)) for t in {a.link, *a.touch_links}}
    for a in loose:  # the grasp is the weld, not friction of the fingers
        pairs |= {frozenset((LOOSE_PREFIX + a.id, t)) for t in {a.link, *a.touch_links}}
    exclude = [f'    <exclude body1="{_esc(a)}" body2="{_esc(b)}"/>'
               for a, b in sorted(tuple(sorted(p)) for p in pairs if len(p) == 2)]
    eq = [f"    {e}" for e in _mimic_equalities(robot)]
    act = [f"    {e}" for e in _actuators(robot, gains)]
    world = obstacle_geoms([o for o in obstacles if not isinstance(o, CloudObstacle)],
                           assets=assets, cache=cache, progress=progress)
    world += cloud_geoms([o for o in obstacles if isinstance(o, CloudObstacle)])
    if ground and not any(not isinstance(o, CloudObstacle) and obstacle_form(o).id == GROUND_ID
                          for o in obstacles):
        # an infinite plane (size 0 0: unbounded): the planner's box is 20 m wide only
        # because FCL wants a finite shape
        world.insert(0, f'<geom name="obstacle:{GROUND_ID}" type="plane" size="0 0 1" '
                     'pos="0 0 0" contype="1" conaffinity="1" rgba="0.5 0.5 0.5 0.3"/>')
    free = [line for a in loose for line in loose_body(a, assets, cache, progress)]
    parts = [f'<mujoco model="{_esc(robot.name)}">',
             '  <compiler angle="radian" inertiafromgeom="false" balanceinertia="false" '
             'boundmass="1e-6" boundinertia="1e-9"/>',
             f'  <option timestep="{TIMESTEP!r}" integrator="Euler" '
             'gravity="0 0 -9.81"/>',
             "  <asset>", *("    " + a for a in assets), "  </asset>",
             "  <worldbody>", *("    " + g for g in world), *tree,
             *("    " + line for line in free),
             "  </worldbody>",
             "  <contact>", *exclude, "  </contact>"]
    for a in loose:
        eq.append(f'    <weld name="{_esc(GRASP_PREFIX + a.id)}" body1="{_esc(a.link)}" '
                  f'body2="{_esc(LOOSE_PREFIX + a.id)}" active="false"/>')
    if eq:
        parts += ["  <equality>", *eq, "  </equality>"]
    parts += ["  <actuator>", *act, "  </actuator>", "</mujoco>"]
    return "\n".join(parts) + "\n"


def servo_ctrl(q_ref: np.ndarray, qd_ref: np.ndarray | None, gains: Sequence[Gains]
               ) -> np.ndarray:
    """The ``ctrl`` that makes the actuators' force ``kp (q_ref - q) + kv (qd_ref - qd)``."""
    q_ref = np.asarray(q_ref, float)
    if qd_ref is None:
        return q_ref.copy()
    ratio = np.array([g.kv / g.kp for g in gains], float)
    return q_ref + ratio * np.asarray(qd_ref, float)
