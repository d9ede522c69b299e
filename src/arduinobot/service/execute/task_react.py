"""A running task's rest, cut by its steps, for the reactor's recheck.

A task's joined motion changes its world along the way (an attach, a detach, an object
resting on its support until the lift), so its rest is not checked in one scene: the
task service sends, with the joined trajectory, each lasting step's piece (its time
span [s], its carried objects, allowed pairs and the task's own obstacles there:
:mod:`arduinobot.service.task.pieces`). :class:`TaskPieces` samples the rest of each
piece at every control tick from now (the piece's first and last states exactly: each
step starts and ends at rest, so the pieces meet), for one ``recheck`` job
(:mod:`arduinobot.service.plan.task_recheck`), and says where a refusal fell: the
trajectory time of the refused state and of the last certified one, and the step (its
index, kind and label, and the task's own step it belongs to: a pick, a place).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.execution.segments import Segment

EPS = 1e-9  # [s] a piece that starts this close to its end has no rest


@dataclass(frozen=True)
class TaskPieces:
    """The execute request's ``task`` section (see the module doc)."""

    pieces: tuple[Mapping[str, Any], ...]
    moved: tuple[str, ...] = ()
    ground: bool = True
    name: str | None = None
    #: what planning its rest again needs (the task's JSON form, where it is from)
    replan: Mapping[str, Any] | None = None
    #: why its rest is not re-checked (None: it is)
    unchecked: str | None = None

    @classmethod
    def of(cls, section: Mapping[str, Any]) -> TaskPieces:
        return cls(tuple(section.get("pieces") or ()),
                   tuple(str(m) for m in section.get("moved") or ()),
                   bool(section.get("ground", True)), section.get("name"),
                   section.get("replan"), section.get("unchecked"))

    def step(self, piece: int) -> dict[str, Any]:
        """Piece ``piece``'s step as events name it."""
        p = self.pieces[piece]
        return {"index": p["step"], "kind": p["kind"], "label": p.get("label"),
                "task_step": p["task_step"], "task_kind": p["task_kind"]}

    def piece_at(self, t: float) -> int | None:
        """The piece playing at trajectory time ``t`` [s] (one that ends there: the
        next; None: none lasts from there on)."""
        for i, p in enumerate(self.pieces):
            if p["start"] - EPS <= t < p["end"] - EPS:
                return i
        return None

    def at(self, t: float) -> dict[str, Any] | None:
        """The step playing at trajectory time ``t`` [s] (None: none lasts there)."""
        i = self.piece_at(t)
        return None if i is None else self.step(i)

    def rest(self, seg: Segment, t: float, rate: float
             ) -> tuple[dict[str, Any], list[tuple[int, np.ndarray]]]:
        """The recheck job's data for ``seg`` from trajectory time ``t`` [s] on, sampled
        at ``rate`` [Hz]; and for each piece sent, its index and its states' times [s]."""
        dt = 1.0 / rate
        sent: list[dict[str, Any]] = []
        spans: list[tuple[int, np.ndarray]] = []
        for i, p in enumerate(self.pieces):
            lo, hi = max(t, float(p["start"])), min(float(p["end"]), seg.duration)
            if hi - lo <= EPS:
                continue
            ts = np.append(np.arange(lo, hi, dt), hi)
            qs = np.array([seg.evaluate(float(x))[0] for x in ts])
            sent.append({"positions": qs.tolist(),
                         **{k: list(p.get(k) or ()) for k in ("obstacles", "attached",
                                                               "allowed")}})
            spans.append((i, ts))
        return ({"joint_names": list(seg.joint_names), "pieces": sent,
                 "moved": list(self.moved), "ground": self.ground}, spans)

    def where(self, body: Mapping[str, Any], spans: Sequence[tuple[int, np.ndarray]]
              ) -> tuple[float | None, dict[str, Any], dict[str, Any]]:
        """A refusal's place (``body``: the job's answer, not certified): the time [s]
        of the last certified state (None: not even the first), the refusal (its time
        [s] and pair), and the step it fell in."""
        k = int(body["piece"])
        i, ts = spans[k]
        safe = int(body["safe"])
        if safe >= 0:
            until: float | None = float(ts[safe])
        else:  # the pieces before it were certified through their ends, where it starts
            until = float(spans[k - 1][1][-1]) if k > 0 else None
        ref = body["refused"]
        refused = {"time": float(ts[min(int(ref["state"]), len(ts) - 1)]),
                   "pair": ref["pair"]}
        return until, refused, self.step(i)
