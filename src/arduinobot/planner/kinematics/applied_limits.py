"""The limits a plan was held to, and where each came from: for ``info``, the plan
summary and the plots.

The planner scales the velocity limits by the request's ``velocity_scaling`` and the
acceleration and jerk limits by its ``acceleration_scaling``; a request that sets none
gets joint_limits.yaml's ``default_*_scaling_factor`` (MoveIt's 0.1 in a Setup
Assistant package). Showing the full limits next to such a plan made it look ten times
too slow; this module gives the applied figures and says why they are what they are.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:  # the plan command's client path must not import the planner (numba)
    from arduinobot.description import Description
    from arduinobot.planner.kinematics.limits import JointLimits

Kind = Literal["lower", "upper", "velocity", "acceleration", "jerk", "effort"]
KINDS: tuple[Kind, ...] = ("lower", "upper", "velocity", "acceleration", "jerk", "effort")
UNITS: Mapping[str, str] = {"position": "rad", "velocity": "rad/s",
                            "acceleration": "rad/s^2", "jerk": "rad/s^3", "effort": "N m"}


@dataclass(frozen=True, eq=False)
class AppliedLimits:
    """Limits of ``joints`` at full scale and as applied, with their origins.

    Attributes:
        joints: the joints, in the order of every array.
        full: kind -> shape (j,) figures at full scale (nan: none).
        velocity_scaling, acceleration_scaling: the factors applied, in (0, 1].
        scaling_from: where the factors came from, for humans.
        sources: kind -> one phrase naming where the full figures came from
            (``URDF``, ``joint_limits.yaml``, ``default (<rule>)``), per joint where
            they differ.
    """

    joints: tuple[str, ...]
    full: Mapping[str, np.ndarray]
    velocity_scaling: float = 1.0
    acceleration_scaling: float = 1.0
    scaling_from: str = "none"
    sources: Mapping[str, str] = field(default_factory=dict)

    def factor(self, kind: str) -> float:
        """The scaling applied to ``kind`` (1 for position and effort)."""
        if kind == "velocity":
            return self.velocity_scaling
        if kind in ("acceleration", "jerk"):
            return self.acceleration_scaling
        return 1.0

    def applied(self, kind: str) -> np.ndarray:
        """``kind``'s figures as the planner enforced them, shape (j,)."""
        return self.full[kind] * self.factor(kind)

    def origin(self, kind: str) -> str:
        """Where ``kind`` came from and how it was scaled, e.g. ``joint_limits.yaml
        x0.1``; position is named by its ``lower``/``upper`` sources."""
        if kind == "position":
            lo, hi = self.sources.get("lower", "?"), self.sources.get("upper", "?")
            return lo if lo == hi else f"lower {lo}, upper {hi}"
        src = self.sources.get(kind, "?")
        f = self.factor(kind)
        return src if f == 1.0 else f"{src} x{f:g}"

    def lines(self) -> list[str]:
        """Where each limit came from and the scaling, one line each."""
        out = [f"  {k}: {self.origin(k)}"
               for k in ("position", "velocity", "acceleration", "jerk", "effort")]
        out.append(f"  scaling: velocity x{self.velocity_scaling:g}, acceleration and jerk "
                   f"x{self.acceleration_scaling:g} ({self.scaling_from})")
        return out

    @classmethod
    def from_joint_limits(cls, lim: JointLimits, *, joints: Sequence[str] | None = None,
                          velocity_scaling: float = 1.0, acceleration_scaling: float = 1.0,
                          scaling_from: str = "none") -> AppliedLimits:
        """From the planner's full-scale :class:`JointLimits` (``from_description`` at
        scaling 1)."""
        names = tuple(joints) if joints is not None else lim.joint_names
        sub = lim.subset(names)
        return cls(names, {k: np.asarray(getattr(sub, k), float) for k in KINDS},
                   velocity_scaling, acceleration_scaling, scaling_from,
                   {k: summarise_sources(lim.sources, names, k) for k in KINDS})

    @classmethod
    def from_description_reply(cls, robot: Mapping[str, Any], joints: Sequence[str], *,
                               request: Mapping[str, Any] | None = None) -> AppliedLimits:
        """From a ``<prefix>/description`` reply (``limits``, ``limit_sources``,
        ``default_scaling``) and the plan request that set the scaling, if any. A
        service that does not send ``limit_sources`` gives ``?`` sources."""
        limits = robot.get("limits", {})
        full: dict[str, np.ndarray] = {
            k: np.array([_num(limits.get(j, {}).get(k)) for j in joints], float) for k in KINDS}
        raw = robot.get("limit_sources") or {}
        flat = {f"{j}.{k}": src for j, kinds in raw.items() for k, src in kinds.items()}
        sources: dict[str, str] = {k: summarise_sources(flat, joints, k) if flat else "?"
                                   for k in KINDS}
        req = request or {}
        default = robot.get("default_scaling") or {}
        vs, as_ = req.get("velocity_scaling"), req.get("acceleration_scaling")
        parts = []
        if vs is None or as_ is None:
            cfg = (robot.get("config") or {}).get("joint_limits")
            parts.append("joint_limits.yaml default_*_scaling_factor" if cfg
                         else "default: no joint_limits.yaml")
        if vs is not None or as_ is not None:
            parts.insert(0, "the request")
        return cls(tuple(joints), full,
                   float(vs if vs is not None else default.get("velocity", 1.0)),
                   float(as_ if as_ is not None else default.get("acceleration", 1.0)),
                   ", ".join(parts), sources)


def short_source(source: str) -> str:
    """Where a figure came from, in a word or three, from a
    :attr:`~arduinobot.planner.kinematics.limits.JointLimits.sources` entry: ``URDF``,
    ``joint_limits.yaml``, or ``default (<rule>)`` for one the planner derived."""
    if source.startswith("derived: acceleration /"):  # "derived: acceleration / 0.1 s ramp"
        return f"default ({source.removeprefix('derived: ').split(' ramp')[0]})"
    if source.startswith("derived") and "capped at" in source:
        return f"default (from effort, gravity and inertia, capped at {source.split('capped at ')[1].split(' ')[0]})"
    if source.startswith("derived"):
        return "default (from effort, gravity and inertia)"
    if source.startswith("config/joint_limits.yaml"):
        return "joint_limits.yaml"
    if source.startswith("urdf"):
        return "URDF"
    return source


def summarise_sources(sources: Mapping[str, str], joints: Sequence[str], kind: str) -> str:
    """One phrase for where ``kind`` of every joint came from (``sources``:
    ``"<joint>.<kind>"`` -> source): the source alone when all agree, else each with its
    joints (``URDF (joint_1), joint_limits.yaml (joint_2, joint_3)``)."""
    by: dict[str, list[str]] = {}
    for j in joints:
        by.setdefault(short_source(sources.get(f"{j}.{kind}", "unknown")), []).append(j)
    if len(by) == 1:
        return next(iter(by))
    return ", ".join(f"{src} ({', '.join(js)})" for src, js in by.items())


def _num(v: object) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else np.nan


def default_scaling_from(description: Any) -> str:
    """Where a :class:`~arduinobot.description.Description`'s default scaling came from."""
    if description.config.joint_limits is None:
        return "default: no joint_limits.yaml"
    return f"default_*_scaling_factor of {description.config.joint_limits}"


def applied_limits(description: Description, joints: tuple[str, ...]) -> AppliedLimits:
    """The limits of ``joints`` at the description's default scaling (what a request
    that sets none is held to), with where each came from (``info``, the viewer's plots)."""
    from arduinobot.planner.kinematics.limits import JointLimits  # the planner: imported when asked

    return AppliedLimits.from_joint_limits(
        JointLimits.from_description(description), joints=joints,
        velocity_scaling=description.default_velocity_scaling,
        acceleration_scaling=description.default_acceleration_scaling,
        scaling_from=default_scaling_from(description))
