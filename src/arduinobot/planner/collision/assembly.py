"""Assembling a world's bodies: the robot's links (shared, :mod:`.bodies`), the objects
it carries and the scene's obstacles, in the body table's order, with what each needs (OBB tree, FCL
object, convex hull, how to get its part hulls, the points its motion bounds read), and
the pairs worth checking.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from itertools import combinations

import fcl
import numpy as np

from arduinobot.planner.collision.acm import AllowedCollisionMatrix
from arduinobot.planner.collision.bodies import RobotBodies, ShapeCache, bvh
from arduinobot.planner.collision.bounds.hulls import Hull, mesh_hull, primitive_hull
from arduinobot.planner.collision.bounds.obbtree import ObbTree, box_tree, build_tree
from arduinobot.planner.collision.bounds.parts import Parts
from arduinobot.planner.collision.cloud_tiles import CloudSurface, cell_geometry
from arduinobot.planner.collision.table import BodyKind, checked_kinds
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle

_Geometry = tuple[fcl.CollisionGeometry, ObbTree, Hull]


def _obstacle_geometry(o: Obstacle, shapes: ShapeCache) -> _Geometry:
    # by content (not id or pose): the same mesh under another name is built once
    return shapes.get(o.geometry.content_key(), lambda: _build_geometry(o))


def _build_geometry(o: Obstacle) -> _Geometry:
    g = o.geometry
    half = g.half_extents()
    if half is not None and g.hull_points() is not None:  # a primitive: no triangles read
        return g.collision_geometry(), box_tree(half), primitive_hull(o)
    mesh = g.triangles()
    return (bvh(mesh), build_tree(mesh.vertices, mesh.faces),
            mesh_hull(np.asarray(mesh.vertices, float)))


def _surface(o: Obstacle) -> fcl.BVHModel:
    surface = o.geometry.surface()
    assert surface is not None
    return bvh(surface)


def _enclosing_points(tree: ObbTree) -> np.ndarray:
    """The corners of a tree's root box (the shape's frame), which holds the whole
    shape: a point's greatest distance from an axis (what a motion bound reads,
    :func:`.advance.joint_reach`) is convex, so these corners bound every point of it."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    return tree.center[0] + (signs * tree.half[0]) @ tree.axes[0].T


def carried_touch(attached: Sequence[AttachedObject]) -> tuple[tuple[str, str], ...]:
    """The (object, link) pairs never checked: each carried object and its touch links
    (already resolved, :func:`arduinobot.scene.obstacles.resolve_attached`)."""
    return tuple((a.id, t) for a in attached for t in a.touch_links)


@dataclass(frozen=True, eq=False)
class SceneBodies:
    """Every body of a world, in the table's order (the links, the carried objects, then
    the obstacles).

    Attributes:
        names, kinds: each body's name and :class:`.table.BodyKind`.
        links: the link index that moves each (a carried object's: its holder's), -1
            for an obstacle.
        trees: OBB trees (body frame).
        objects: FCL objects (an obstacle's placed, a link's moved per state); None for
            a cloud, measured by its tiles (``clouds``).
        clouds: a cloud's boundary in tiles (:mod:`.cloud_tiles`), by body index.
        surfaces: a box obstacle's surface as 12 triangles, by body index, for distances
            at free states only (FCL's mesh-box distance is 2.5x slower than mesh-mesh on
            CAD links, measured).
        statics: whether a body never moves.
        points: (link name or None, vertices in its frame) for the motion bounds.
        hulls: convex hulls (body frame).
        parts: how to get each body's part hulls (body frame): a link's built on first
            use (:meth:`.RobotBodies.parts_of`), an obstacle's or carried object's its
            hull alone.
        poses: shape (n, 4, 4): an obstacle's world pose, a carried object's pose in
            its link's frame, identity for a link.
    """

    names: tuple[str, ...]
    kinds: tuple[BodyKind, ...]
    links: tuple[int, ...]
    trees: tuple[ObbTree, ...]
    objects: tuple[fcl.CollisionObject | None, ...]
    surfaces: dict[int, fcl.CollisionObject]
    clouds: dict[int, CloudSurface]
    statics: tuple[bool, ...]
    points: tuple[tuple[str | None, np.ndarray], ...]
    hulls: tuple[Hull, ...]
    parts: tuple[Callable[[], Parts], ...]
    poses: np.ndarray

    @classmethod
    def assemble(cls, robot: RobotBodies, obstacles: Sequence[Obstacle],
                 attached: Sequence[AttachedObject] = (), *,
                 link_index: dict[str, int] | None = None,
                 clouds: Sequence[CloudObstacle] = ()) -> SceneBodies:
        """The robot's links (geometry shared, FCL objects new), the ``attached`` objects
        (each on its link, ``link_index`` its index in ``Kinematics.link_names``),
        ``obstacles`` and ``clouds`` (each one body: :mod:`.cloud_body`)."""
        names, links = list(robot.names), list(robot.frames)
        kinds = [BodyKind.LINK] * len(names)
        trees, statics = list(robot.trees), list(robot.statics)
        points: list[tuple[str | None, np.ndarray]] = list(robot.points)
        hulls = list(robot.hulls)
        parts: list[Callable[[], Parts]] = [partial(robot.parts_of, i)
                                            for i in range(len(robot.names))]
        objs: list[fcl.CollisionObject | None] = [
            fcl.CollisionObject(g, fcl.Transform()) for g in robot.geometries]
        surfaces: dict[int, fcl.CollisionObject] = {}
        tiled: dict[int, CloudSurface] = {}
        poses = np.tile(np.eye(4), (len(names) + len(attached) + len(obstacles) + len(clouds),
                                    1, 1))
        static_link = dict(zip(robot.names, robot.statics))
        for a in attached:
            if link_index is None or a.link not in link_index:
                raise ValueError(f"carried object '{a.id}' on unknown link '{a.link}'")
            geom, tree, hull = _obstacle_geometry(a.shape, robot.shapes)
            offset = a.shape.pose()  # in the link's frame
            poses[len(names)] = offset
            names.append(a.id)
            links.append(link_index[a.link])
            kinds.append(BodyKind.CARRIED)
            trees.append(tree)
            objs.append(fcl.CollisionObject(geom, fcl.Transform()))  # moved per state
            statics.append(static_link.get(a.link, False))
            # its motion bound is its link's, over its own extent in that link's frame
            local = _enclosing_points(tree)
            points.append((a.link, local @ offset[:3, :3].T + offset[:3, 3]))
            hulls.append(hull)
            parts.append(partial(Parts.of_hull, hull))
        for o in obstacles:
            geom, tree, hull = _obstacle_geometry(o, robot.shapes)
            pose = o.pose()
            poses[len(names)] = pose
            names.append(o.id)
            links.append(-1)
            kinds.append(BodyKind.OBSTACLE)
            trees.append(tree)
            objs.append(fcl.CollisionObject(geom, fcl.Transform(pose[:3, :3], pose[:3, 3])))
            if o.geometry.has_surface:
                surfaces[len(objs) - 1] = fcl.CollisionObject(
                    robot.shapes.get(("surface", o.geometry.content_key()),
                                     partial(_surface, o)),
                    fcl.Transform(pose[:3, :3], pose[:3, 3]))
            statics.append(True)
            points.append((None, np.zeros((1, 3))))
            hulls.append(hull)
            parts.append(partial(Parts.of_hull, hull))
        for c in clouds:  # world-frame cells: the identity pose
            surface, tree, hull = robot.shapes.get(c.key(), partial(cell_geometry, c.cells))
            tiled[len(names)] = surface
            names.append(c.id)
            links.append(-1)
            kinds.append(BodyKind.OBSTACLE)
            trees.append(tree)
            objs.append(None)
            statics.append(True)
            points.append((None, np.zeros((1, 3))))
            hulls.append(hull)
            parts.append(partial(Parts.of_hull, hull))
        return cls(tuple(names), tuple(kinds), tuple(links), tuple(trees), tuple(objs),
                   surfaces, tiled, tuple(statics), tuple(points), tuple(hulls), tuple(parts), poses)

    def checked_pairs(self, acm: AllowedCollisionMatrix,
                      touch: Sequence[tuple[str, str]] = ()
                      ) -> tuple[np.ndarray, tuple[tuple[int, int], ...]]:
        """The pairs to check, (a, b) with a < b: those some motion moves, shape (m, 2),
        and those of two bodies that never move (decided once). Skipped: pairs whose
        kinds never matter (:func:`.table.checked_kinds`), the allowed ones and a
        carried object with its ``touch`` links ((object, link) pairs)."""
        moving: list[tuple[int, int]] = []
        fixed: list[tuple[int, int]] = []
        skip = {frozenset(p) for p in touch}
        for a, b in combinations(range(len(self.names)), 2):
            if not checked_kinds(self.kinds[a], self.kinds[b]):
                continue
            if acm.allowed(self.names[a], self.names[b]) or \
                    frozenset((self.names[a], self.names[b])) in skip:
                continue
            (fixed if self.statics[a] and self.statics[b] else moving).append((a, b))
        return np.array(moving, dtype=np.int64).reshape(-1, 2), tuple(fixed)
