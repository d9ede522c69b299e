"""A kept point cloud in the MuJoCo twin: its cells as static boxes, so a plan and its
simulation see the same world.

The cells are joined into boxes exactly as the planner's tree joins them
(:func:`arduinobot.planner.collision.cloud_body.cell_boxes`: the same union, a third of
the boxes for a measured table, a hundredth for a pillar's sides). MuJoCo's model grows
with every geom (compiling tens of thousands takes seconds, and each step's broad phase
walks them), so at most :data:`MAX_TWIN_BOXES` boxes go in, those nearest the robot's
root first; the rest (the farthest: beyond the arm's reach for any real cloud) are left
out with a warning naming the cloud, how many and from what distance.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from arduinobot.scene.cloud import CloudObstacle

_log = logging.getLogger(__name__)

#: Most boxes all clouds together put in the twin.
MAX_TWIN_BOXES = 4000


def cloud_boxes(clouds: Sequence[CloudObstacle], *, cap: int = MAX_TWIN_BOXES
                ) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Each cloud's boxes as (cloud id, centres shape (b, 3) [m], half sizes (b, 3) [m]),
    world frame, the nearest to the root first, at most ``cap`` boxes in all (the
    nearest kept; a warning says what was left out)."""
    # imported here: mjcf imports this module in the serving process, which must never
    # load the planner's collision kernels (FCL, numba)
    from arduinobot.planner.collision.cloud_body import cell_boxes

    found = []
    for c in clouds:
        lo, size = cell_boxes(c.cells)
        half = size * (c.cells.resolution / 2)
        center = lo * c.cells.resolution + half
        # the box's nearest point to the root's origin: what a cap keeps first
        gap = np.linalg.norm(np.maximum(np.abs(center) - half, 0.0), axis=1)
        found.append((c.id, center, half, gap))
    if not found:
        return []
    gaps = np.concatenate([g for *_, g in found])
    keep = np.zeros(len(gaps), bool)
    keep[np.argsort(gaps, kind="stable")[:cap]] = True
    out, at = [], 0
    for cid, center, half, gap in found:
        mine = keep[at:at + len(gap)]
        at += len(gap)
        if not mine.all():
            _log.warning("twin: cloud '%s' as %d of its %d boxes (at most %d in the twin): "
                         "the %d from %.2f m of the root on are left out of the "
                         "simulation", cid, int(mine.sum()), len(mine), cap,
                         int((~mine).sum()), float(gap[~mine].min()))
        order = np.argsort(gap[mine], kind="stable")
        out.append((cid, center[mine][order], half[mine][order]))
    return out


def cloud_geoms(clouds: Sequence[CloudObstacle], *, cap: int = MAX_TWIN_BOXES,
                prefix: str = "obstacle") -> list[str]:
    """The MJCF box geoms of ``clouds`` (:func:`cloud_boxes`), named
    ``<prefix>:<id>/<i>`` (the twin reports a contact with one as an obstacle's),
    static in the world body."""
    out = []
    for cid, center, half in cloud_boxes(clouds, cap=cap):
        name = f"{prefix}:{cid}".replace("&", "&amp;").replace('"', "&quot;") \
            .replace("<", "&lt;")
        for i, (c, h) in enumerate(zip(center, half)):
            size = " ".join(repr(float(v)) for v in h)
            pos = " ".join(repr(float(v)) for v in c)
            out.append(f'<geom name="{name}/{i}" type="box" size="{size}" pos="{pos}" '
                       'contype="1" conaffinity="1" rgba="0.8 0.5 0.2 0.6"/>')
    return out
