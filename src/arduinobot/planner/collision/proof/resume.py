"""The protocol between the certifier's compiled walk and its Python side.

The walk (:func:`arduinobot.planner.collision.proof.certify._advance`) runs in numba until a point needs a
bound it cannot compute there (a hull query through FCL, or FCL's exact distance); it
then stops, says why (:class:`Status`) and where (a :data:`WALK` record), and Python
computes the bound and calls it again from that point with the bound injected.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numpy as np


class Motion(NamedTuple):
    """The pieces of a motion (see :mod:`.certify`): ``starts``, ``u1``, ``u2``
    shape (n, dof), ``lengths`` (n,) [rad]."""

    starts: np.ndarray
    u1: np.ndarray
    u2: np.ndarray
    lengths: np.ndarray


class Proof(NamedTuple):
    """What one certification builds up per pair, across the walk's resumed calls.

    Attributes:
        best: the clearance [m] certified so far, shape (n_pairs,).
        directions: the pair's last hull direction (unit, world), shape (n_pairs, 3).
        warm: whether it has one, shape (n_pairs,) bool.
    """

    best: np.ndarray
    directions: np.ndarray
    warm: np.ndarray


class Status(IntEnum):
    """Why the walk returned (numba reads the members as ints)."""

    DONE = 0  # every pair was walked to the end of the motion: certified
    NEED_BOUND = 1  # the point in the record needs a bound from Python (hull, else exact)
    BUDGET = 2  # the distance bounds one certification may evaluate are spent


#: Where the walk stands: read by it when it starts (the point to resume from, and the
#: bound injected there, -1 for none), written when it stops (the point that needs a
#: bound), the bounds it evaluated so far, and among them how often it asked the trees
#: and the warm hulls (the ladder's first rungs, :mod:`.ladder`). One record (an array of
#: shape (1,)).
WALK = np.dtype([("pair", np.int64), ("piece", np.int64), ("sigma", np.float64),
                 ("injected", np.float64), ("bounds", np.int64), ("trees", np.int64),
                 ("warm", np.int64)])


def new_walk() -> np.ndarray:
    """A walk record at its start: pair 0, piece 0, sigma 0, nothing injected."""
    rec = np.zeros(1, dtype=WALK)
    rec[0]["injected"] = -1.0
    return rec


@dataclass(frozen=True)
class Stop:
    """Where a walk stopped, read from its record.

    Attributes:
        pair: the checked pair (an index into the world's pairs).
        piece: the piece of the motion.
        sigma: how far along it [rad].
        bounds: distance bounds evaluated so far.
    """

    pair: int
    piece: int
    sigma: float
    bounds: int

    @classmethod
    def read(cls, walk: np.ndarray) -> Stop:
        r = walk[0]
        return cls(int(r["pair"]), int(r["piece"]), float(r["sigma"]), int(r["bounds"]))
