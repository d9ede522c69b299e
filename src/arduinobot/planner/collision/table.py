"""The body table: every collision body of a world, its kind, where it sits, and the
pairs that are checked.

A body is a link's mesh, an object the gripper carries, or a scene obstacle
(:class:`BodyKind`); its pose is its link's (a link), that link's times a fixed offset
(a carried object), or a fixed world pose (an obstacle). The kernels read the same
table as the Python code (:class:`Bodies`, :class:`Pairs`: NamedTuples of arrays numba
takes as one argument each), so a new kind of body is a new row, not a new index range.
Built once per world and frozen (the arrays are read-only).

In the kernels a body's pose is ``poses[frame[b]]`` (``pose[b]`` for an obstacle) with
no test of its kind: a carried object has a pose slot of its own after the links',
filled after each forward kinematics (:func:`place_carried`). A branch on the kind per
pair and step cost 5-25% of the walks (measured on the course model).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numba
import numpy as np
import numpy.typing as npt


class BodyKind(IntEnum):
    """What a body is (numba reads the members as ints)."""

    LINK = 0  # a link's collision mesh: posed by its link
    CARRIED = 1  # an object held by a link (the gripper's): posed by the link times an offset
    OBSTACLE = 2  # a scene obstacle: a fixed world pose


def checked_kinds(a: BodyKind, b: BodyKind) -> bool:
    """Whether a pair of these kinds can ever matter: two obstacles never move relative
    to each other, so their contact is the scene's, not the motion's."""
    return not (a == BodyKind.OBSTACLE and b == BodyKind.OBSTACLE)


class Bodies(NamedTuple):
    """Per body, for the kernels.

    Attributes:
        kind: :class:`BodyKind` values, shape (n,) int64.
        frame: the pose slot it takes its pose from: its link's index (into
            ``Kinematics.link_names``) for a link, a slot after the links' for a carried
            object, -1 for an obstacle; shape (n,) int64.
        link: the link that moves it (a link's own, a carried object's holder), -1 for
            an obstacle; shape (n,) int64.
        pose: shape (n, 4, 4): an obstacle's world pose; a carried object's pose in its
            link's frame; identity for a link (unused).
        carried: the carried bodies, shape (c,) int64.
    """

    kind: np.ndarray
    frame: np.ndarray
    link: np.ndarray
    pose: np.ndarray
    carried: np.ndarray


class Pairs(NamedTuple):
    """Per checked pair that motion changes, for the kernels.

    Attributes:
        index: the two bodies, shape (n_pairs, 2) int64.
        weight: [m/rad] how far one body can move relative to the other per unit of each
            actuated joint, shape (n_pairs, dof) (:func:`.advance.pair_weights`).
        mover: the body of the pair that moves by a static one (its local speed bounds
            its steps too, :mod:`.body_speed`), or -1, shape (n_pairs,) int64.
    """

    # numba takes the pairs as one NamedTuple; the field shadows tuple.index (a method
    # no code calls on Pairs), which mypy reports as an incompatible override
    index: np.ndarray  # type: ignore[assignment]
    weight: np.ndarray
    mover: np.ndarray


def _frozen(a: npt.ArrayLike, dtype: type) -> np.ndarray:
    out: np.ndarray = np.array(a, dtype=dtype, order="C")  # a copy: never freezes the caller's array
    out.flags.writeable = False
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def place_carried(frame: np.ndarray, link: np.ndarray, pose: np.ndarray, carried: np.ndarray,
                  poses: np.ndarray) -> None:
    """Fill the carried objects' pose slots of ``poses`` (n_slots, 4, 4), its links'
    poses just computed: each one's link's pose times its offset (``frame``, ``link``,
    ``pose``, ``carried``: a :class:`Bodies`' arrays, unpacked once by the kernel).
    Nothing to do when nothing is carried."""
    for i in range(carried.shape[0]):
        b = carried[i]
        t, o, out = poses[link[b]], pose[b], poses[frame[b]]
        for r in range(4):
            for c in range(4):
                out[r, c] = t[r, 0] * o[0, c] + t[r, 1] * o[1, c] + t[r, 2] * o[2, c] \
                    + t[r, 3] * o[3, c]


@dataclass(frozen=True, eq=False)
class BodyTable:
    """Every body of a world and its checked pairs; frozen.

    Attributes:
        names: each body's name (a link's, or an object's id).
        kinds: each body's :class:`BodyKind`.
        bodies: the per-body arrays (kind, frame, pose) the kernels read.
        pairs: the checked pairs some motion moves (index, weight, mover).
        pair_names: those pairs by name, (body, body).
        fixed: checked pairs of two bodies no motion moves (decided once), by index.
        fixed_hits: those of them in contact (every state then collides), by name.
        n_links: the robot's links (pose slots before the carried objects').
    """

    names: tuple[str, ...]
    kinds: tuple[BodyKind, ...]
    bodies: Bodies
    pairs: Pairs
    pair_names: tuple[tuple[str, str], ...]
    fixed: tuple[tuple[int, int], ...]
    fixed_hits: tuple[tuple[str, str], ...]
    n_links: int

    @classmethod
    def build(cls, names: Sequence[str], kinds: Sequence[BodyKind], links: Sequence[int],
              poses: np.ndarray, pairs: np.ndarray, weight: np.ndarray, mover: np.ndarray,
              *, n_links: int, fixed: Sequence[tuple[int, int]] = (),
              fixed_hits: Sequence[tuple[str, str]] = ()) -> BodyTable:
        """A table of bodies ``names`` (with ``kinds``, the ``links`` that move them,
        ``poses`` shape (n, 4, 4)) of a robot of ``n_links`` links, and checked ``pairs``
        (m, 2) with their ``weight`` (m, dof) and ``mover`` (m,); arrays are copied and
        frozen. Carried objects get pose slots ``n_links, n_links + 1, ...``."""
        n = len(names)
        if not (len(kinds) == len(links) == len(poses) == n):
            raise ValueError("names, kinds, links and poses differ in length")
        if len(pairs) != len(weight) or len(pairs) != len(mover):
            raise ValueError("pairs, weight and mover differ in length")
        for k, f in zip(kinds, links):
            if (f < 0) != (k == BodyKind.OBSTACLE) or f >= n_links:
                raise ValueError(f"a {BodyKind(k).name} body on link {f}")
        carried = [b for b, k in enumerate(kinds) if k == BodyKind.CARRIED]
        frames = list(links)
        for i, b in enumerate(carried):
            frames[b] = n_links + i
        index = _frozen(np.asarray(pairs).reshape(-1, 2), np.int64)
        return cls(tuple(names), tuple(BodyKind(k) for k in kinds),
                   Bodies(_frozen(np.asarray(kinds), np.int64), _frozen(frames, np.int64),
                          _frozen(links, np.int64),
                          _frozen(np.asarray(poses).reshape(n, 4, 4), np.float64),
                          _frozen(carried, np.int64).reshape(-1)),
                   Pairs(index, _frozen(_rows(weight, len(index)), np.float64),
                         _frozen(mover, np.int64)),
                   tuple((names[a], names[b]) for a, b in index),
                   tuple((int(a), int(b)) for a, b in fixed), tuple(fixed_hits), n_links)

    @property
    def slots(self) -> int:
        """Pose slots the kernels' pose buffers need: the links', then one per carried
        object."""
        return self.n_links + len(self.bodies.carried)

    def __len__(self) -> int:
        return len(self.names)

    def of_kind(self, kind: BodyKind) -> tuple[int, ...]:
        """The bodies of ``kind``, by index."""
        return tuple(b for b, k in enumerate(self.kinds) if k == kind)

    def pair_kinds(self, pair: int) -> tuple[BodyKind, BodyKind]:
        """The kinds of checked pair ``pair``'s two bodies."""
        a, b = self.pairs.index[pair]
        return self.kinds[a], self.kinds[b]


def _rows(values: object, m: int) -> np.ndarray:
    """``values`` as ``m`` rows; no pairs (a robot whose every pair is adjacent or
    disabled) is an empty (0, 0) block rather than numpy's "cannot reshape size 0"."""
    a = np.asarray(values, np.float64)
    return a.reshape(m, -1) if m else a.reshape(0, a.shape[-1] if a.ndim == 2 else 0)
