"""Every joint limit the planner and the time parameterisation use, with its source.

Position, velocity and effort come from the URDF; acceleration and jerk from the
package's ``config/joint_limits.yaml`` (MoveIt's keys), whose ``max_velocity`` and
``min_position``/``max_position`` may narrow the URDF's (the loader applies the
position keys to the robot itself). Nothing is defaulted silently:
a missing acceleration or jerk limit is derived by a documented rule and ``sources``
says so; where no rule applies, :class:`~arduinobot.contract.errors.LimitsError` is raised.

Rules for missing figures:

- acceleration [rad/s^2]: ``ACCELERATION_MARGIN * (effort - max|g_i(q)|) / max M_ii(q)``,
  the worst case over ``DERIVATION_SAMPLES`` seeded samples uniform within the
  position limits (continuous joints over [-pi, pi]): the torque left after holding the
  arm against gravity, accelerating the joint's largest effective inertia, with half
  kept in reserve for the coupling and velocity terms the diagonal ignores. It fails
  (LimitsError) when the effort cannot hold the worst-case gravity torque or the
  joint moves no mass.
  A figure beyond ``SERVO_ACCELERATION_CAP`` (40 rad/s^2) is capped there, with a
  warning: the rule reads a URDF's nominal effort over CAD inertias, which for a small
  arm of hobby or bus servos (an SG90, a Feetech STS3215) gives 1e3-3e5 rad/s^2, and no
  such servo accelerates beyond about 40 rad/s^2 (the STS3215's acceleration register
  tops out at 254 x 100 steps/s^2 = 39 rad/s^2). A ``max_acceleration`` in
  joint_limits.yaml is taken as given.
- jerk [rad/s^3]: ``acceleration / JERK_RAMP_TIME``: the full acceleration is reached
  in 0.1 s.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import SupportsFloat, SupportsIndex

import numpy as np

from arduinobot.contract.errors import InvalidRequest, LimitsError
from arduinobot.description.loader import Description

_log = logging.getLogger(__name__)

ACCELERATION_MARGIN = 0.5
DERIVATION_SAMPLES = 2000
DERIVATION_SEED = 20240607
JERK_RAMP_TIME = 0.1  # [s]
#: the most a derived acceleration may be [rad/s^2]: what hobby and bus servos can do
SERVO_ACCELERATION_CAP = 40.0

_KINDS = ("lower", "upper", "velocity", "acceleration", "jerk", "effort")


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Limits of the actuated joints, each array shape (dof,) in ``joint_names`` order.

    Attributes:
        joint_names: the joints.
        lower, upper: position limits [rad or m]; -inf/inf for continuous joints.
        velocity: [rad/s or m/s], scaled by ``velocity_scaling``.
        acceleration: [rad/s^2 or m/s^2], scaled by ``acceleration_scaling``.
        jerk: [rad/s^3 or m/s^3], also scaled by ``acceleration_scaling``.
        effort: [N m or N].
        sources: ``"<joint>.<kind>"`` -> where the figure came from ("urdf",
            "config/joint_limits.yaml", or "derived: <rule>"), plus ``"scaling"``.
    """

    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    effort: np.ndarray
    sources: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        for kind in _KINDS:
            a = np.array(getattr(self, kind), dtype=float)
            if a.shape != (n,):
                raise InvalidRequest(f"{kind} must have shape ({n},), got {a.shape}",
                                     field=kind)
            a.setflags(write=False)
            object.__setattr__(self, kind, a)
        object.__setattr__(self, "sources", MappingProxyType(dict(self.sources)))

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def subset(self, joint_names: Sequence[str]) -> JointLimits:
        """The limits of some of the joints, in the given order."""
        try:
            idx = [self.joint_names.index(n) for n in joint_names]
        except ValueError:
            raise InvalidRequest(f"unknown joint in {list(joint_names)}; have "
                                 f"{', '.join(self.joint_names)}", field="joint_names") from None
        names = tuple(joint_names)
        src = {k: v for k, v in self.sources.items()
               if k.split(".", 1)[0] in names or "." not in k}
        return JointLimits(names, self.lower[idx], self.upper[idx], self.velocity[idx],
                           self.acceleration[idx], self.jerk[idx], self.effort[idx], sources=src)

    @classmethod
    def from_description(
        cls,
        description: Description,
        *,
        velocity_scaling: float = 1.0,
        acceleration_scaling: float = 1.0,
        joint_names: Sequence[str] | None = None,
    ) -> JointLimits:
        """Gather the limits of ``joint_names`` (default: the actuated joints).

        Args:
            description: the robot; its ``joint_limits`` is MoveIt's joint_limits.yaml
                (``has_velocity_limits``/``max_velocity``, which may only tighten the
                URDF's velocity; ``has_acceleration_limits``/``max_acceleration``;
                ``has_jerk_limits``/``max_jerk``).
            velocity_scaling: in (0, 1]; multiplies the velocity limits.
            acceleration_scaling: in (0, 1]; multiplies the acceleration limits and, so
                that the time to reach full acceleration stays the same, the jerk limits.

        Raises:
            InvalidRequest: a scaling factor outside (0, 1] or an unknown joint.
            LimitsError: a movable joint without an effort or velocity limit, a malformed
                joint_limits.yaml entry, or an acceleration no rule can derive.
        """
        _check_scaling(velocity_scaling, "velocity_scaling")
        _check_scaling(acceleration_scaling, "acceleration_scaling")
        robot = description.robot
        names = tuple(joint_names) if joint_names is not None else robot.actuated_joints
        for n in names:
            if n not in robot.actuated_joints:
                raise InvalidRequest(f"'{n}' is not an actuated joint "
                                     f"({', '.join(robot.actuated_joints)})",
                                     field="joint_names")
        yaml_src = "config/joint_limits.yaml"
        sources: dict[str, str] = {}
        vals: dict[str, list[float]] = {k: [] for k in _KINDS}
        for name in names:
            lim = robot.joints[name].limit
            cfg = description.joint_limits.get(name, {})
            lo, hi = robot.position_limits((name,))[0]
            if lo > hi:
                raise LimitsError(f"lower {lo} exceeds upper {hi}", joint=name,
                                  limit="position")
            vals["lower"].append(lo)
            vals["upper"].append(hi)
            # the loader has narrowed the URDF's range by min/max_position where given
            for kind, key, v in (("lower", "min_position", lo), ("upper", "max_position", hi)):
                sources[f"{name}.{kind}"] = yaml_src if cfg.get(key) == v else "urdf"
            effort = lim.effort if lim is not None else 0.0
            if not (math.isfinite(effort) and effort > 0):
                raise LimitsError("the URDF gives no positive <limit effort=...>", joint=name,
                                  limit="effort")
            vals["effort"].append(effort)
            sources[f"{name}.effort"] = "urdf"
            vel, vsrc = _velocity(name, lim.velocity if lim is not None else 0.0, cfg, yaml_src)
            vals["velocity"].append(vel * velocity_scaling)
            sources[f"{name}.velocity"] = vsrc
            for kind in ("acceleration", "jerk"):  # nan: derived below
                value = _yaml_limit(name, cfg, kind)
                vals[kind].append(math.nan if value is None else value)
                if value is not None:
                    sources[f"{name}.{kind}"] = yaml_src
        _derive_missing(description, names, vals, sources)
        vals["acceleration"] = [a * acceleration_scaling for a in vals["acceleration"]]
        vals["jerk"] = [j * acceleration_scaling for j in vals["jerk"]]
        sources["scaling"] = (f"velocity x {velocity_scaling}, acceleration and jerk x "
                              f"{acceleration_scaling}")
        arr = {k: np.array(vals[k], dtype=float) for k in _KINDS}
        return cls(names, arr["lower"], arr["upper"], arr["velocity"], arr["acceleration"],
                   arr["jerk"], arr["effort"], sources=sources)


def _derive_missing(description: Description, names: Sequence[str],
                    vals: dict[str, list[float]], sources: dict[str, str]) -> None:
    """Fill in place the (unscaled) accelerations and jerks joint_limits.yaml leaves out
    (nan in ``vals``): accelerations from the dynamics, then jerks from the acceleration
    over ``JERK_RAMP_TIME``; ``sources`` says how each was derived."""
    missing_acc = [i for i, a in enumerate(vals["acceleration"]) if math.isnan(a)]
    if missing_acc:
        derived = derive_accelerations(description, [names[i] for i in missing_acc])
        for i, a in zip(missing_acc, derived):
            rule = (f"derived: {ACCELERATION_MARGIN} x (effort - max |gravity torque|) / "
                    f"max M_ii(q) over {DERIVATION_SAMPLES} seeded samples")
            if a > SERVO_ACCELERATION_CAP:
                _log.warning("%s: the acceleration derived from effort and inertia, %.4g "
                             "rad/s^2, is beyond what a servo can do; using %g rad/s^2 (set "
                             "max_acceleration in joint_limits.yaml)", names[i], a,
                             SERVO_ACCELERATION_CAP)
                rule += (f", {a:.4g} rad/s^2, capped at {SERVO_ACCELERATION_CAP:g} "
                         "(beyond what a servo can do)")
                a = SERVO_ACCELERATION_CAP
            vals["acceleration"][i] = a
            sources[f"{names[i]}.acceleration"] = rule
    for i, name in enumerate(names):
        if math.isnan(vals["jerk"][i]):
            vals["jerk"][i] = vals["acceleration"][i] / JERK_RAMP_TIME
            sources[f"{name}.jerk"] = (f"derived: acceleration / {JERK_RAMP_TIME} s ramp "
                                       f"(acceleration from "
                                       f"{sources[f'{name}.acceleration'].split(':')[0]})")


def _check_scaling(value: float, name: str) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and 0.0 < value <= 1.0):
        raise InvalidRequest(f"must lie in (0, 1], got {value!r}", field=name)


def _yaml_number(name: str, cfg: Mapping[str, object], key: str) -> float:
    raw = cfg.get(key)
    try:  # what float() does not take is not a number either
        v = float(raw) if isinstance(raw, (str, SupportsFloat, SupportsIndex)) else math.nan
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(raw, bool) or not (math.isfinite(v) and v > 0):
        raise LimitsError(f"joint_limits.yaml {key} must be a positive number, got {raw!r}",
                          joint=name, limit=key.removeprefix("max_"))
    return v


def _yaml_limit(name: str, cfg: Mapping[str, object], kind: str) -> float | None:
    """The yaml figure for ``kind`` if ``has_<kind>_limits`` is true, else None."""
    flag = cfg.get(f"has_{kind}_limits", False)
    if not isinstance(flag, bool):
        raise LimitsError(f"joint_limits.yaml has_{kind}_limits must be true or false, "
                          f"got {flag!r}", joint=name, limit=kind)
    return _yaml_number(name, cfg, f"max_{kind}") if flag else None


def _velocity(name: str, urdf: float, cfg: Mapping[str, object], yaml_src: str
              ) -> tuple[float, str]:
    have_urdf = math.isfinite(urdf) and urdf > 0
    from_yaml = _yaml_limit(name, cfg, "velocity")
    if from_yaml is None:
        if not have_urdf:
            raise LimitsError("the URDF gives no positive <limit velocity=...> and "
                              "joint_limits.yaml none either", joint=name, limit="velocity")
        return urdf, "urdf"
    if not have_urdf or from_yaml <= urdf:
        return from_yaml, yaml_src
    _log.warning("%s: joint_limits.yaml max_velocity %g exceeds the URDF's %g; using the "
                 "URDF's", name, from_yaml, urdf)
    return urdf, f"urdf ({yaml_src} max_velocity {from_yaml:g} is looser; may only tighten)"


def derive_accelerations(description: Description, joints: Sequence[str]) -> np.ndarray:
    """The acceleration limit [rad/s^2] the module's rule gives each of ``joints``.

    Raises:
        LimitsError: the effort cannot hold the worst-case gravity torque, or the joint
            moves no mass.
    """
    robot = description.robot
    # imported here: numba's kernels load with the first limits derived from the dynamics,
    # not with every importer of JointLimits (the service's serving process reads limits)
    from arduinobot.planner.kinematics.dynamics import InverseDynamics

    dyn = InverseDynamics(robot)  # all actuated joints: each one's pose changes M and g
    lim = robot.position_limits(dyn.joint_names)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    rng = np.random.default_rng(DERIVATION_SEED)
    qs = rng.uniform(lo, hi, size=(DERIVATION_SAMPLES, dyn.dof))
    zero = np.zeros_like(qs)
    grav = np.max(np.abs(dyn.torques_batch(qs, zero, zero)), axis=0)
    inertia = np.max(np.diagonal(dyn.mass_matrix_batch(qs), axis1=1, axis2=2), axis=0)
    out = []
    for name in joints:
        i = dyn.joint_names.index(name)
        urdf_limit = robot.joints[name].limit
        if urdf_limit is None:  # a continuous joint may come without <limit>
            raise LimitsError("no acceleration limit in joint_limits.yaml, and none can be "
                              "derived: the URDF gives the joint no <limit effort=>",
                              joint=name, limit="acceleration")
        effort = urdf_limit.effort
        if inertia[i] <= 0:
            raise LimitsError("no acceleration limit in joint_limits.yaml, and none can be "
                              "derived: the joint moves no mass (no <inertial>)",
                              joint=name, limit="acceleration")
        if grav[i] >= effort:
            raise LimitsError(f"no acceleration limit in joint_limits.yaml, and none can be "
                              f"derived: the worst-case gravity torque {grav[i]:.4g} N m "
                              f"reaches the effort limit {effort:.4g} N m",
                              joint=name, limit="acceleration",
                              details={"gravity_torque": float(grav[i]),
                                       "effort": float(effort)})
        out.append(ACCELERATION_MARGIN * (effort - grav[i]) / inertia[i])
    return np.array(out)
