"""A point cloud's cells as one collision body, and the robot's surface for its self-filter.

A cloud of 50,000 cells is one body, not 50,000 (as VAMP keeps a cloud apart from its
primitives): one more pair per link, so a state check and a proof cost about what a scene
of a few boxes does. Its three geometries are each exact or conservative for the union of
the cell boxes:

- its OBB tree (:func:`cell_tree`) has one leaf per cell, the cell's own box (axis-aligned
  in the world): the trees' distance bound at the leaves is a bound to the boxes
  themselves, so a clearance the certifier proves holds for every point inside a cell;
- its FCL geometry is the union's boundary (:func:`exposed_faces`: the faces of a cell
  with no occupied neighbour across them, two triangles each), in tiles whose BVHs are
  built on first use (:mod:`.cloud_tiles`); the distance from a body outside the union
  to it is the distance to the union (FCL's OcTree would measure the same, but costs
  12-83 ms per mesh distance, too slow inside a proof);
- its convex hull holds every cell's corners (a bound far from the cloud; near it the
  certifier asks FCL).

As for a mesh obstacle, a link state is decided by its surface against the union's: a
link wholly inside a cell, or a cell wholly inside a link, is not seen at a state. Neither
can be reached from a free state by a certified motion (the surfaces would cross), and the
self-filter removes the cells in and near the robot at the state the cloud was taken.
"""

from __future__ import annotations

import math

import fcl
import numpy as np

from arduinobot.planner.collision.bounds.hulls import Hull, mesh_hull
from arduinobot.planner.collision.bounds.obbtree import ObbTree
from arduinobot.planner.collision.cloud_tree import build_box_tree
from arduinobot.scene.cloud import Cells

# the six face directions and, per direction, its square's corners (unit cell, as
# offsets from the cell's lower corner) wound outward
_DIRS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                 np.int64)
_FACES = np.array([
    [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
    [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]],
    [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]],
    [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
    [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]],
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
], float)
# cells along each axis of a tree leaf at most: joined cells make fewer leaves (a faster
# build), but long leaves (a pillar's side in one 3 m box) make loose nodes above them:
# plans took 2.7x as long with unbounded ones (bench/cloud.py)
TREE_LEAF_CELLS = 2
# [m] grown into every cell box of the tree against rounding (as box_tree's)
_SLACK = 1e-9


def _keys(index: np.ndarray, lo: np.ndarray) -> np.ndarray:
    rel = index - lo
    return (rel[:, 0] << 42) | (rel[:, 1] << 21) | rel[:, 2]


def _runs(base: np.ndarray, axis: int, corners: np.ndarray) -> np.ndarray:
    # open faces (their cells' lower corners, shape (m, 3)) facing along ``axis``, merged
    # into one quad per run of neighbours along the next axis: the same surface in ~1/20
    # the triangles (a 1 cm table's top: 240 quads, not 57,600), and FCL's BVH build is
    # per triangle (7 s for 532k, measured)
    if len(base) == 0:
        return np.empty((0, 4, 3))
    run, other = (axis + 1) % 3, (axis + 2) % 3
    b = base[np.lexsort((base[:, run], base[:, other], base[:, axis]))]
    new = np.ones(len(b), bool)
    new[1:] = (b[1:, axis] != b[:-1, axis]) | (b[1:, other] != b[:-1, other]) | \
        (b[1:, run] != b[:-1, run] + 1)
    starts = np.flatnonzero(new)
    length = np.diff(np.append(starts, len(b)))
    scale = np.ones((len(starts), 1, 3))
    scale[:, 0, run] = length
    return b[starts].astype(float)[:, None, :] + corners[None] * scale


def exposed_faces(cells: Cells, subset: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The boundary of the union of ``cells`` as triangles: vertices shape (v, 3) [m]
    and faces shape (f, 3), two per run of cell faces without an occupied neighbour.
    ``subset`` (indices into the cells): only those cells' faces (their neighbours are
    still looked up among all the cells), as a tile of :mod:`.cloud_tiles` needs."""
    idx = cells.index
    lo = idx.min(axis=0) - 1  # a neighbour one below the lowest cell keys too
    keys = _keys(idx, lo)  # the cells are sorted by row, so by key
    own = idx if subset is None else idx[subset]
    quads = []
    for d, corners in zip(_DIRS, _FACES):
        nb = _keys(own + d, lo)
        pos = np.minimum(np.searchsorted(keys, nb), len(keys) - 1)
        open_ = keys[pos] != nb
        quads.append(_runs(own[open_], int(np.flatnonzero(d)[0]), corners))
    q = np.concatenate(quads) * cells.resolution  # (m, 4, 3)
    vertices = q.reshape(-1, 3)
    first = 4 * np.arange(len(q))
    faces = np.concatenate([np.column_stack([first, first + 1, first + 2]),
                            np.column_stack([first, first + 2, first + 3])])
    return vertices, faces


def surface_bvh(vertices: np.ndarray, faces: np.ndarray) -> fcl.BVHModel:
    """An FCL BVH of triangles (vertices (v, 3) [m], faces (f, 3))."""
    m = fcl.BVHModel()
    m.beginModel(len(vertices), len(faces))
    m.addSubModel(vertices, faces.astype(np.int32))
    m.endModel()
    return m


def _merged(lo: np.ndarray, size: np.ndarray, axis: int, longest: int
            ) -> tuple[np.ndarray, np.ndarray]:
    # boxes (lower corners and sizes in cells, (n, 3) int; one cell along ``axis``)
    # joined with their neighbours along ``axis`` where both have the same extent on the
    # other two axes and touch, at most ``longest`` cells in one box
    a, b = (axis + 1) % 3, (axis + 2) % 3
    order = np.lexsort((lo[:, axis], size[:, b], size[:, a], lo[:, b], lo[:, a]))
    lo, size = lo[order], size[order]
    new = np.ones(len(lo), bool)
    new[1:] = (lo[1:, a] != lo[:-1, a]) | (lo[1:, b] != lo[:-1, b]) | \
        (size[1:, a] != size[:-1, a]) | (size[1:, b] != size[:-1, b]) | \
        (lo[1:, axis] != lo[:-1, axis] + size[:-1, axis])
    run = np.cumsum(new) - 1
    rank = np.arange(len(lo)) - np.flatnonzero(new)[run]
    new |= rank % longest == 0
    starts = np.flatnonzero(new)
    out_lo, out_size = lo[starts], size[starts].copy()
    out_size[:, axis] = np.add.reduceat(size[:, axis], starts)
    return out_lo, out_size


def cell_boxes(cells: Cells, *, longest: int = 2**21) -> tuple[np.ndarray, np.ndarray]:
    """The cells joined into fewer boxes, exactly their union (each cell in one box):
    runs along z, then along y of runs with the same section, then along x, each at
    most ``longest`` cells. Lower corners and sizes in cells, shape (b, 3) int64 each
    (times ``cells.resolution``: metres). A measured table's two ragged layers of 1 cm
    cells: ~1/3 the boxes; a pillar's sides: ~1/100."""
    lo, size = cells.index, np.ones_like(cells.index)
    for axis in (2, 1, 0):
        lo, size = _merged(lo, size, axis, longest)
    return lo, size


def cell_tree(cells: Cells) -> ObbTree:
    """An OBB tree (world axes) whose leaves are the cells joined into boxes
    (:func:`cell_boxes`): the same union in fewer leaves, so built and walked faster;
    split by the surface-area heuristic (:mod:`.cloud_tree`)."""
    corner, size = cell_boxes(cells, longest=TREE_LEAF_CELLS)
    lo = np.ascontiguousarray(corner * cells.resolution, float)
    hi = lo + size * cells.resolution
    cap = 2 * len(lo)
    center, half = np.empty((cap, 3)), np.empty((cap, 3))
    left, right = np.empty(cap, np.int64), np.empty(cap, np.int64)
    n = build_box_tree(lo, hi, center, half, left, right)
    axes = np.ascontiguousarray(np.broadcast_to(np.eye(3), (n, 3, 3)))
    return ObbTree(center[:n].copy(), axes, half[:n].copy(), left[:n].copy(),
                   right[:n].copy())


def cell_hull(cells: Cells) -> Hull:
    """A convex hull holding every cell's box."""
    from scipy.spatial import ConvexHull, QhullError

    centers = cells.centers
    try:  # the hull of the centres first: its vertices' cells hold the hull's corners
        far = centers[ConvexHull(centers).vertices]
    except QhullError:  # flat or too few cells: every centre
        far = centers
    r = cells.resolution / 2
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    return mesh_hull((far[:, None, :] + r * signs[None]).reshape(-1, 3))


def _triangle_samples(tri: np.ndarray, spacing: float) -> np.ndarray:
    # points on triangles (t, 3, 3) no farther than ``spacing`` from any point of them:
    # a barycentric grid of steps no longer than spacing / 2, then one point per cube of
    # edge spacing / (2 sqrt 3) (each point dropped is within spacing / 2 of one kept;
    # CAD meshes gave 12M points at 5 mm unthinned, measured on the shipped arm)
    step = spacing / 2
    edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    steps = np.maximum(1, np.ceil(edges / step)).astype(np.int64)
    cube = spacing / (2 * math.sqrt(3))
    lo = tri.reshape(-1, 3).min(axis=0)

    def thinned(p: np.ndarray) -> np.ndarray:
        key = np.floor((p - lo) / cube).astype(np.int64)  # >= 0; < 2^21 for a 2.9 km link
        _, first = np.unique((key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2],
                             return_index=True)
        return p[first]

    out = []
    for n in np.unique(steps):
        sel = tri[steps == n]
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        a = (i[keep] / n)[None, :, None]
        b = (j[keep] / n)[None, :, None]
        for part in np.array_split(sel, max(1, len(sel) * int(keep.sum()) // 2_000_000)):
            out.append(thinned((part[:, None, 0] * (1 - a - b) + part[:, None, 1] * a
                                + part[:, None, 2] * b).reshape(-1, 3)))
    return thinned(np.concatenate(out))


def _link_samples(world: object, spacing: float) -> list[np.ndarray]:
    # each link's surface samples in its own frame, kept on the robot's geometry
    bodies = world.bodies  # type: ignore[attr-defined]
    key = f"cloud-surface-{spacing:.6g}"
    local = bodies.proofs.get(key)
    if local is None:
        local = []
        for (_link, verts), faces in zip(bodies.points, bodies.faces):
            local.append(_triangle_samples(np.asarray(verts, float)[faces], spacing))
        bodies.proofs[key] = local
    return local


def robot_surface(world: object, q: np.ndarray, *, spacing: float) -> np.ndarray:
    """Points on every link's collision surface at state ``q`` (shape (dof,) [rad]),
    world frame, shape (k, 3) [m]: every surface point lies within ``spacing`` [m] of
    one (the link-frame samples are kept on the robot's geometry, per spacing)."""
    bodies = world.bodies  # type: ignore[attr-defined]
    local = _link_samples(world, spacing)
    poses = world.kin.link_poses(q)  # type: ignore[attr-defined]
    out = []
    for frame, pts in zip(bodies.frames, local):
        t = poses[frame]
        out.append(pts @ t[:3, :3].T + t[:3, 3])
    return np.concatenate(out) if out else np.empty((0, 3))


def near_robot(world: object, q: np.ndarray, cells: Cells, padding: float, *,
               spacing: float) -> np.ndarray:
    """Which cells (shape (n,) bool) may come within ``padding`` [m] of the robot's
    surface samples at ``q`` (shape (dof,) [rad]): the same cells as
    ``near_surface(cells, robot_surface(world, q, spacing=spacing), padding)``, found in
    each link's frame: only the cells near a link's box are moved into its frame and
    asked of its samples' KD-tree (built once per link and spacing), instead of moving
    the robot's ~700k samples at 1 cm and building their tree at every apply."""
    from scipy.spatial import cKDTree

    bodies = world.bodies  # type: ignore[attr-defined]
    local = _link_samples(world, spacing)
    key = f"cloud-surface-trees-{spacing:.6g}"
    trees = bodies.proofs.get(key)
    if trees is None:
        trees = [cKDTree(p) if len(p) else None for p in local]
        bodies.proofs[key] = trees
    poses = world.kin.link_poses(q)  # type: ignore[attr-defined]
    reach = padding + cells.resolution * math.sqrt(3) / 2
    centers = cells.centers
    out = np.zeros(len(cells), bool)
    signs = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    for frame, pts, tree in zip(bodies.frames, local, trees):
        if tree is None:
            continue
        t = poses[frame]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        corners = (lo + signs * (hi - lo)) @ t[:3, :3].T + t[:3, 3]
        near = np.flatnonzero(((centers >= corners.min(axis=0) - reach)
                               & (centers <= corners.max(axis=0) + reach)).all(axis=1))
        if not len(near):
            continue
        d, _ = tree.query((centers[near] - t[:3, 3]) @ t[:3, :3], k=1,
                          distance_upper_bound=reach)
        out[near[d <= reach]] = True
    return out


def surface_spacing(resolution: float) -> float:
    """[m] how dense the self-filter's surface samples are for cells of ``resolution``:
    a cell, at least 5 mm (finer costs memory and time and buys less than the padding;
    the filter's reach grows by it)."""
    return max(resolution, 0.005) if math.isfinite(resolution) else 0.005
