"""The geometric curve both time parameterisations follow: straight edges, blended corners.

A planner's path is a polyline in joint space whose edges were collision-checked. A spline
through its waypoints can bulge out of that checked corridor, so we never use one. Instead
each corner is rounded by a blend that starts on the incoming edge at distance ``r`` before
the waypoint and ends on the outgoing edge ``r`` after it::

    q(sigma) = p + u1 sigma + (u2 - u1) L H(sigma / L),   L = 2 r,  H(x) = x^3 - x^4 / 2

Its tangent turns from ``u1`` to ``u2`` by a smoothstep, so the curve is C2 (curvature is
zero where a blend meets an edge) and every blend point lies in the triangle
(edge point, waypoint, edge point) -- close to the checked corridor but not inside it, so
each blend is certified free over its whole length (:mod:`arduinobot.planner.collision.proof.certify`);
a colliding blend is shrunk, and after ``max_shrinks`` halvings the corner becomes a hard
stop: the curve is split there and the motion comes to rest at the waypoint (each edge is
a straight line, so that is exact).

A line is the same formula with ``u1 == u2``, so one vectorised evaluator serves both.
The parameter ``s`` is arc length in joint space [rad] along lines; inside blends
``|q'(s)| <= 1``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np
import toppra

from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.checks import CHECK_STEP

if TYPE_CHECKING:
    from arduinobot.planner.collision.proof.certificate import Certificate

log = logging.getLogger(__name__)


class _Checker(Protocol):
    def first_invalid(self, qs: np.ndarray) -> int: ...


class _Certifier(Protocol):
    def pieces(self, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
               lengths: np.ndarray) -> Certificate: ...


@dataclass(frozen=True)
class CornerReport:
    """What happened at one interior waypoint: passed straight, blended or stopped at.

    ``radius`` [rad] is the blend radius kept (0 unless blended); ``shrinks`` counts halvings.
    ``certificate``: the kept blend's proof when a certifier checked it
    (:class:`arduinobot.planner.collision.proof.certificate.Certificate`), else None.
    """

    index: int
    kind: Literal["straight", "blend", "stop"]
    radius: float
    shrinks: int
    certificate: Certificate | None = None


class PathCurve(toppra.interpolator.AbstractGeometricPath):
    """One smooth section of the curve (rest at both ends), ``s`` in [0, length].

    Args:
        starts: piece start points, shape (n, dof).
        u1, u2: unit tangents at each piece's start and end, shape (n, dof).
        lengths: piece parameter lengths [rad], shape (n,).
        kinds: 'line' or 'blend' per piece.
    """

    def __init__(self, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                 lengths: np.ndarray, kinds: Sequence[str]) -> None:
        self.starts = np.asarray(starts, float)
        self.u1 = np.asarray(u1, float)
        self.u2 = np.asarray(u2, float)
        self.lengths = np.asarray(lengths, float)
        self.kinds = tuple(kinds)
        self.s0 = np.concatenate(([0.0], np.cumsum(self.lengths)[:-1]))
        self.length = float(self.lengths.sum())
        self._blend = np.array([k == "blend" for k in self.kinds])

    @property
    def dof(self) -> int:
        return int(self.starts.shape[1])

    @property
    def path_interval(self) -> np.ndarray:
        return np.array([0.0, self.length])

    @property
    def end(self) -> np.ndarray:
        return self(np.array([self.length]))[0]

    def __call__(self, path_positions: float | np.ndarray, order: int = 0) -> np.ndarray:
        """``order``-th derivative (0..3) at ``path_positions``: shape (m, dof) or (dof,)."""
        scalar = np.ndim(path_positions) == 0
        out = self.in_piece(*self.locate(np.atleast_1d(path_positions)), order)
        return out[0] if scalar else out

    def locate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(piece, position into it [rad]) of each ``s`` (shape (m,), clamped to the
        curve): the arguments of :meth:`in_piece` and :meth:`jet`."""
        s = np.clip(np.asarray(s, float), 0.0, self.length)
        k = np.clip(np.searchsorted(self.s0, s, side="right") - 1, 0, len(self.lengths) - 1)
        return k, s - self.s0[k]

    def in_piece(self, k: np.ndarray, sigma: np.ndarray, order: int = 0) -> np.ndarray:
        """``order``-th derivative (0..3) at ``sigma`` [rad] into piece ``k`` (each shape
        (m,), sigma clamped to the piece), shape (m, dof): a piece's end stays its own."""
        return self.jet(k, sigma, (order,))[0]

    def jet(self, k: np.ndarray, sigma: np.ndarray, orders: Sequence[int] = (0, 1, 2, 3)
            ) -> tuple[np.ndarray, ...]:
        """The derivatives of the given ``orders`` (each 0..3) at ``sigma`` [rad] into
        piece ``k``, as in :meth:`in_piece` but sharing the piece lookups (what
        evaluating a timing needs); only those orders are computed."""
        bad = [o for o in orders if not 0 <= o <= 3]
        if bad:
            raise InvalidRequest(f"order {bad[0]} not supported (0..3)", field="order")
        L = self.lengths[k]
        sigma = np.clip(sigma, 0.0, L)
        x = np.where(L > 0, sigma / np.where(L > 0, L, 1.0), 0.0)[:, None]
        Lc = L[:, None]
        # a zero-length piece (start == goal) has no curvature: its derivatives are 0
        inv_l = np.where(Lc > 0, 1.0 / np.where(Lc > 0, Lc, 1.0), 0.0)
        u1 = self.u1[k]
        du = self.u2[k] - u1

        def derivative(order: int) -> np.ndarray:
            if order == 0:
                return self.starts[k] + u1 * sigma[:, None] + du * Lc * (x**3 - 0.5 * x**4)
            if order == 1:
                return u1 + du * (3 * x**2 - 2 * x**3)
            if order == 2:
                return du * (6 * x - 6 * x**2) * inv_l
            return du * (6 - 12 * x) * inv_l**2
        return tuple(derivative(o) for o in orders)

    def dense(self, step: float, s_from: float = 0.0, s_to: float | None = None) -> np.ndarray:
        """States along [s_from, s_to] no more than ``step`` [rad] apart per joint, (m, dof)."""
        s_to = self.length if s_to is None else s_to
        # |q'_i| <= 1 everywhere, so a parameter step of ``step`` is a joint step <= step.
        n = max(2, int(np.ceil((s_to - s_from) / step)) + 1)
        return self(np.linspace(s_from, s_to, n))


@dataclass(frozen=True)
class Curve:
    """The whole curve: smooth sections separated by stops, and what each corner kept."""

    sections: tuple[PathCurve, ...]
    corners: tuple[CornerReport, ...]
    goal: np.ndarray  # the exact last waypoint, shape (dof,)


def _dedupe(waypoints: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    keep = [0]
    for i in range(1, len(waypoints)):
        if np.max(np.abs(waypoints[i] - waypoints[keep[-1]])) > tol:
            keep.append(i)
    if len(keep) == 1 and len(waypoints) > 1:
        keep.append(len(waypoints) - 1)
    return waypoints[keep]


def _blend_free(checker: _Checker | _Certifier, blend: PathCurve, step: float
                ) -> tuple[bool, Certificate | None]:
    # (free, the certificate when a certifier decided)
    if hasattr(checker, "pieces"):
        cert = checker.pieces(blend.starts, blend.u1, blend.u2, blend.lengths)
        return bool(cert.free), cert
    return checker.first_invalid(blend.dense(step)) < 0, None


def build_curve(waypoints: np.ndarray, checker: _Checker | _Certifier | None, *,
                max_radius: float = 0.25, edge_fraction: float = 0.45,
                step: float = CHECK_STEP, max_shrinks: int = 4) -> Curve:
    """Blend the corners of a collision-checked polyline, re-checking each blend.

    Args:
        waypoints: the checked path, shape (k, dof), k >= 2.
        checker: a :class:`arduinobot.planner.collision.proof.certify.Certifier` (each blend is certified free over
            its whole length), or anything with ``first_invalid(qs) -> int`` (a
            CollisionWorld: blends sampled at ``step``); None skips the blend checks (only
            for paths known to lie in free space, e.g. tests).
        max_radius: the largest blend radius [rad] (distance from the waypoint along each edge).
        edge_fraction: a blend uses at most this fraction of each adjacent edge's length.
        step: max joint step [rad] between re-checked blend states.
        max_shrinks: halvings of a colliding blend before the corner becomes a stop.

    Returns:
        The :class:`Curve`; a path of one distinct point gives one zero-length section.
    """
    wp = np.asarray(waypoints, float)
    if wp.ndim != 2 or len(wp) < 2:
        raise InvalidRequest(f"a path needs shape (k >= 2, dof), got {wp.shape}", field="path")
    wp = _dedupe(wp)
    d = np.diff(wp, axis=0)
    lens = np.linalg.norm(d, axis=1)
    if lens.max() == 0.0:
        z = np.zeros((1, wp.shape[1]))
        sec = PathCurve(wp[:1], z, z, np.zeros(1), ["line"])
        return Curve((sec,), (), wp[-1].copy())
    u = d / lens[:, None]
    # np.allclose(u[i - 1], u[i], atol=1e-12) for every corner i at once (its elementwise
    # test, rtol 1e-5; the tangents are finite): ~20 us a corner as separate calls
    collinear = np.concatenate(([False], np.all(
        np.abs(u[:-1] - u[1:]) <= 1e-12 + 1e-5 * np.abs(u[1:]), axis=1)))
    radii = np.zeros(len(wp))
    corners: list[CornerReport] = []
    for i in range(1, len(wp) - 1):
        if collinear[i]:  # no corner at all
            corners.append(CornerReport(i, "straight", 0.0, 0))
            continue
        r = min(max_radius, edge_fraction * lens[i - 1], edge_fraction * lens[i])
        shrinks = 0
        if r <= 0.0:
            corners.append(CornerReport(i, "stop", 0.0, 0))
            continue
        while True:
            blend = PathCurve((wp[i] - r * u[i - 1])[None], u[i - 1][None], u[i][None],
                              np.array([2 * r]), ["blend"])
            free, cert = (True, None) if checker is None else _blend_free(checker, blend, step)
            if free:
                break
            shrinks += 1
            if shrinks > max_shrinks:
                r, cert = 0.0, None
                break
            r *= 0.5
        radii[i] = r
        corners.append(CornerReport(i, "blend" if r > 0 else "stop", float(r), shrinks,
                                    cert))
        if r == 0.0:
            log.info("corner %d: every blend collides, the motion stops there", i)
    sections: list[PathCurve] = []
    pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, str]] = []  # of a section

    def flush() -> None:
        if pieces:
            starts, u1s, u2s, lengths, kinds = zip(*pieces)
            sections.append(PathCurve(np.array(starts), np.array(u1s), np.array(u2s),
                                      np.array(lengths), kinds))
        pieces.clear()

    for e in range(len(d)):
        collinear_in = bool(collinear[e])
        r0 = radii[e] if e > 0 else 0.0
        r1 = radii[e + 1] if e + 1 < len(wp) - 1 else 0.0
        if e > 0 and r0 == 0.0 and not collinear_in:
            flush()  # a hard corner: rest at wp[e]
        line_len = lens[e] - r0 - r1
        if line_len > 1e-12:
            pieces.append((wp[e] + r0 * u[e], u[e], u[e], float(line_len), "line"))
        if r1 > 0.0:
            pieces.append((wp[e + 1] - r1 * u[e], u[e], u[e + 1], float(2 * r1), "blend"))
    flush()
    return Curve(tuple(sections), tuple(corners), wp[-1].copy())
