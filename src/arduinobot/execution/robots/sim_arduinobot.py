"""The simulated twin: the loaded description running in MuJoCo.

Position servos (force capped at the URDF effort) follow the setpoints, with velocity
and, when the setpoint carries an acceleration, computed-torque feed-forward (MuJoCo's
inverse dynamics of the reference motion), so feedback only corrects; the physics
steps at :data:`~arduinobot.execution.robots.mjcf.TIMESTEP` with contacts on. Servo gains come from a
ros2_control controllers yaml (``gains: {joint: {p, d}}`` of an effort-commanding
joint_trajectory_controller) when the packages have one, else each joint is a critically damped servo of
``bandwidth`` Hz at its inertia in the initial pose: ``kp = M_ii w^2``, ``kv = 2 M_ii w``.

:meth:`SimArduinobot.advance` steps the physics as fast as it can; the executor's clock
decides whether that is paced in real time.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.description import Description
from arduinobot.execution.robots.base import (
    JointState,
    MimicMap,
    Robot,
    RobotError,
    check_setpoint,
    initial_positions,
)
from arduinobot.execution.robots.controller_gains import controller_gains, find_controllers_yaml
from arduinobot.execution.robots.loose_state import LooseState
from arduinobot.execution.robots.mjcf import (
    GRASP_PREFIX,
    LOOSE_PREFIX,
    TIMESTEP,
    Gains,
    Progress,
    servo_ctrl,
    to_mjcf,
)
from arduinobot.planner.cache import ArtifactCache

log = logging.getLogger(__name__)

DEFAULT_BANDWIDTH = 10.0  # [Hz]


class SimulationError(RobotError):
    """MuJoCo could not build or step the model."""

    code: str = Code.SIMULATION_ERROR


@dataclass(frozen=True)
class SimStats:
    """What the physics did since the last reset.

    Attributes:
        peak_force: per actuated joint, the largest |actuator force| [N m or N].
        peak_feedforward: the largest |torque| the reference motion itself needs (MuJoCo's
            inverse dynamics of the setpoints: what the trajectory asks of the motors,
            before feedback).
        effort: the actuators' force limits (URDF effort), same order.
        saturated_steps: physics steps with some actuator at its force limit.
        contacts: the body pairs (link/link or link/obstacle) that touched.
        contact_steps: physics steps with any live contact.
        steps: physics steps taken; time [s] the simulated time they cover.
    """

    peak_force: tuple[float, ...]
    peak_feedforward: tuple[float, ...]
    effort: tuple[float, ...]
    saturated_steps: int
    contacts: tuple[tuple[str, str], ...]
    contact_steps: int
    steps: int
    time: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _resolved(description: Description, attached: Sequence[Any]) -> tuple[Any, ...]:
    """Carried objects with their default touch links (what the planner excludes)."""
    if not attached:
        return ()
    from arduinobot.scene.obstacles import resolve_attached
    return resolve_attached(description, tuple(attached))


class SimArduinobot(Robot):
    """The description in MuJoCo.

    Args:
        description: the robot.
        obstacles: world obstacles (the plan request's form, or the kept scene's
            :class:`arduinobot.scene.obstacles.Obstacle`, meshes included).
        attached: carried objects (:class:`arduinobot.scene.obstacles.AttachedObject`), each welded to
            its link with its mass (:meth:`set_scene` changes both later).
        loose: objects a task picks up (AttachedObject posed in the world): free bodies
            with their mass, gripped and let go by :meth:`grasp` (:func:`task_objects`).
        controllers: a controllers yaml (default:
            :func:`~arduinobot.execution.robots.controller_gains.find_controllers_yaml`).
        initial: actuated positions [rad] to start at (default: initial_positions.yaml, else 0).
        bandwidth: [Hz] of the default servos.
        cache: keeps the meshes' convex pieces between runs (V-HACD takes seconds per
            mesh); progress: told of each mesh decomposed afresh.

    Raises:
        SimulationError: MuJoCo refused the model.
    """

    # the simulation figures since the last reset (kept across a scene rebuild)
    _peak: np.ndarray
    _peak_ff: np.ndarray
    _saturated: int
    _contacts: set[tuple[str, str]]
    _contact_steps: int
    _steps: int

    realtime_only = False
    feedback = True  # the simulation's joint positions
    # the setpoint of the current tick [rad, rad/s, rad/s^2] and its jerk [rad/s^3]
    _q_ref: np.ndarray
    _qd_ref: np.ndarray | None
    _qdd_ref: np.ndarray | None
    _jerk: np.ndarray | None

    def __init__(self, description: Description, *, obstacles: Sequence[Any] = (),
                 attached: Sequence[Any] = (), loose: Sequence[Any] = (),
                 controllers: Path | None = None, initial: Sequence[float] | None = None,
                 bandwidth: float = DEFAULT_BANDWIDTH, cache: ArtifactCache | None = None,
                 progress: Progress | None = None, ground: bool = True) -> None:
        import mujoco  # optional dependency (the `sim` extra)

        self._mj = mujoco
        self._description = description
        self._cache, self._progress = cache, progress
        self._ground = ground  # a floor at z = 0 (arduinobot.scene.ground), kept on rebuilds
        robot = description.robot
        attached = _resolved(description, attached)
        loose = _resolved(description, loose)
        self.mimic = MimicMap.from_description(description)
        self.joint_names = self.mimic.actuated
        self.state_names = self.mimic.names
        ctl = controllers or find_controllers_yaml(description)
        chosen = controller_gains(ctl, self.joint_names) if ctl else {}
        self.gain_source = {n: f"{ctl}" for n in chosen}
        placeholder = {n: chosen.get(n, Gains(1.0, 0.0)) for n in self.joint_names}
        excluded = [(d.link1, d.link2) for d in description.srdf.disabled_collisions] \
            if description.srdf is not None else []
        q0 = initial_positions(description, self.joint_names) if initial is None \
            else check_setpoint(initial, self.joint_names, "initial positions")
        for _ in range(2):
            self.xml = to_mjcf(robot, gains=placeholder, excluded=excluded, obstacles=obstacles,
                               attached=attached, loose=loose, cache=cache, progress=progress,
                               ground=ground)
            self._build(robot.name)
            self._set_positions(q0)
            # MuJoCo collides meshes as convex hulls: hulls of concave links (fingers, an
            # L-shaped arm) can overlap in a pose the planner proved free. Such pairs are
            # excluded, with a warning naming them.
            touching = [p for p in self.contacts_now() if not any(
                n.startswith("obstacle:") for n in p)]
            if not touching:
                break
            log.info("MuJoCo (convex hulls) sees %s touching in the initial pose; their "
                     "contacts are ignored", ", ".join(f"{a}/{b}" for a, b in touching))
            excluded = [*excluded, *touching]
        self._excluded = excluded
        m = self.model
        self.effort = np.array([m.actuator_forcerange[a, 1] for a in self._act])
        # default gains: a critically damped servo of `bandwidth` Hz at each joint's inertia
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, self.data, full)
        w = 2 * math.pi * bandwidth
        self.gains: list[Gains] = []
        for i, n in enumerate(self.joint_names):
            if n in chosen:
                g = chosen[n]
            else:
                inertia = float(full[self._dadr[i], self._dadr[i]])
                g = Gains(inertia * w * w, 2.0 * inertia * w)
                self.gain_source[n] = f"default: critically damped {bandwidth:g} Hz servo"
            self.gains.append(g)
        self._apply_gains()
        self._tick = 0.0
        self._scratch = mujoco.MjData(m)
        self.reset(q0)
        log.info("MuJoCo twin of '%s': %d bodies, %d geoms, timestep %g s; gains %s",
                 robot.name, m.nbody, m.ngeom, TIMESTEP,
                 {n: (round(g.kp, 1), round(g.kv, 1)) for n, g in zip(self.joint_names,
                                                                       self.gains)})

    def _apply_gains(self) -> None:
        m = self.model
        for a, g in zip(self._act, self.gains):
            m.actuator_gainprm[a, 0] = g.kp
            m.actuator_biasprm[a, :3] = (0.0, -g.kp, -g.kv)

    def set_scene(self, obstacles: Sequence[Any] = (), attached: Sequence[Any] = (),
                  loose: Sequence[Any] = (), *, moving: bool = False,
                  ground: bool | None = None, keep_loose: bool = False) -> None:
        """Put ``obstacles`` in the world and weld ``attached`` to their links instead of
        what was there (the kept scene at a new revision, or a plan's own obstacles), the
        arm at rest where it is now; the servo gains and figures stay. ``moving``: the
        arm keeps its motion instead (positions, velocities, setpoint and clock: a blend
        changes the world between two ticks); ``loose`` objects start afresh either way,
        unless ``keep_loose``: those the twin had already keep their simulated pose,
        velocity and grip (:mod:`.loose_state`: a task planned again mid-way).
        ``ground``: a floor at z = 0 from now on, as the plan had its ground (None: as
        before).

        Raises:
            SimulationError: MuJoCo refused the model.
        """
        if ground is not None:
            self._ground = ground
        q = np.asarray(self.state().positions[:len(self.joint_names)], float)
        d = self.data
        motion = (d.qpos[self._qadr].copy(), d.qvel[self._dadr].copy(), float(d.time),
                  self._q_ref, self._qd_ref, self._qdd_ref, self._jerk) if moving else None
        kept = LooseState.of(self._mj, self.model, d) if keep_loose else None
        robot = self._description.robot
        gains = {n: g for n, g in zip(self.joint_names, self.gains)}
        self.xml = to_mjcf(robot, gains=gains, excluded=self._excluded, obstacles=obstacles,
                           attached=_resolved(self._description, attached),
                           loose=_resolved(self._description, loose), cache=self._cache,
                           progress=self._progress, ground=self._ground)
        stats = (self._peak, self._peak_ff, self._saturated, self._contacts,
                 self._contact_steps, self._steps)
        self._build(robot.name)
        self._apply_gains()
        self._scratch = self._mj.MjData(self.model)
        self.reset(q)
        (self._peak, self._peak_ff, self._saturated, self._contacts, self._contact_steps,
         self._steps) = stats
        if motion is not None:  # the joints are the same in the new model, by name
            qpos, qvel, t, self._q_ref, self._qd_ref, self._qdd_ref, self._jerk = motion
            self.data.qpos[self._qadr], self.data.qvel[self._dadr] = qpos, qvel
            self.data.time = t
            self._mj.mj_forward(self.model, self.data)
        if kept is not None:
            kept.put(self._mj, self.model, self.data)

    def _build(self, name: str) -> None:
        mujoco = self._mj
        try:
            self.model = m = mujoco.MjModel.from_xml_string(self.xml)
        except ValueError as e:
            raise SimulationError(f"MuJoCo refused the model of '{name}': {e}") from e
        self.data = mujoco.MjData(m)
        jid = {n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in self.state_names}
        self._qadr = np.array([m.jnt_qposadr[jid[n]] for n in self.state_names])
        self._dadr = np.array([m.jnt_dofadr[jid[n]] for n in self.state_names])
        self._act = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n)
                              for n in self.joint_names])
        self._body_of_geom = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or "world"
                              for b in m.geom_bodyid]
        self._geom_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
                            for g in range(m.ngeom)]

    def grasp(self, object_id: str, hold: bool) -> None:
        """Weld the loose object ``object_id`` to its link where it is now (``hold``), or
        let it go: a free body under gravity again.

        Raises:
            SimulationError: no loose object of that id.
        """
        mj, m, d = self._mj, self.model, self.data
        eq = mj.mj_name2id(m, mj.mjtObj.mjOBJ_EQUALITY, GRASP_PREFIX + object_id)
        if eq < 0:
            raise SimulationError(f"the twin has no loose object '{object_id}'")
        if hold:
            # the weld keeps the pose the object has in its link now (the gripper closed
            # on it), not the one it had when the model was built
            b1, b2 = int(m.eq_obj1id[eq]), int(m.eq_obj2id[eq])
            r1 = d.xmat[b1].reshape(3, 3)
            rel = np.empty(4)
            inv = np.empty(4)
            mj.mju_negQuat(inv, d.xquat[b1])
            mj.mju_mulQuat(rel, inv, d.xquat[b2])
            m.eq_data[eq, 0:3] = 0.0
            m.eq_data[eq, 3:6] = r1.T @ (d.xpos[b2] - d.xpos[b1])
            m.eq_data[eq, 6:10] = rel
            m.eq_data[eq, 10] = 1.0
        d.eq_active[eq] = int(hold)

    def object_pose(self, object_id: str) -> np.ndarray:
        """The loose object's simulated pose in the world (4x4, MuJoCo's xpos/xmat).

        Raises:
            SimulationError: no loose object of that id.
        """
        mj = self._mj
        b = mj.mj_name2id(self.model, mj.mjtObj.mjOBJ_BODY, LOOSE_PREFIX + object_id)
        if b < 0:
            raise SimulationError(f"the twin has no loose object '{object_id}'")
        out = np.eye(4)
        out[:3, :3] = self.data.xmat[b].reshape(3, 3)
        out[:3, 3] = self.data.xpos[b]
        return out

    def _set_positions(self, q: np.ndarray) -> None:
        self.data.qpos[self._qadr] = self.mimic.expand(q)
        self.data.qvel[:] = 0.0
        self._mj.mj_forward(self.model, self.data)

    # -- Robot -------------------------------------------------------------------------
    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None:
        """The setpoint; with velocities and accelerations the servos also get the
        rigid-body torque of the reference motion as feed-forward (computed torque)."""
        q = check_setpoint(positions, self.joint_names)
        qd = None if velocities is None else check_setpoint(velocities, self.joint_names,
                                                            "velocities")
        qdd = None if accelerations is None else check_setpoint(
            accelerations, self.joint_names, "accelerations")
        # within the tick the reference moves on with the tick's jerk: given, else the
        # one the last two accelerations imply (a jerk-limited trajectory's jerk is
        # piecewise constant; at a switch that guess overshoots for one tick)
        prev = self._qdd_ref
        if jerks is not None:
            self._jerk = check_setpoint(jerks, self.joint_names, "jerks")
        else:
            self._jerk = None if qdd is None or prev is None or self._tick <= 0 else \
                (qdd - prev) / self._tick
        self._q_ref, self._qd_ref, self._qdd_ref = q, qd, qdd

    def _inverse(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """The actuator torques [N m] of the rigid-body motion (q, qd, qdd) by MuJoCo's
        inverse dynamics without constraints, mimic torques folded into their leaders."""
        mj, m, d = self._mj, self.model, self._scratch
        d.qpos[self._qadr] = self.mimic.expand(q)
        d.qvel[self._dadr] = self.mimic.expand(qd, rate=True)
        d.qacc[self._dadr] = self.mimic.expand(qdd, rate=True)
        flags = m.opt.disableflags
        m.opt.disableflags = flags | int(mj.mjtDisableBit.mjDSBL_CONSTRAINT)
        try:
            mj.mj_inverse(m, d)
        finally:
            m.opt.disableflags = flags
        f = d.qfrc_inverse[self._dadr]
        tau = f[:len(self.joint_names)].copy()
        for k, (lead, mult) in enumerate(zip(self.mimic.leader, self.mimic.multiplier)):
            tau[lead] += mult * f[len(self.joint_names) + k]
        return tau

    def advance(self, dt: float) -> None:
        """Step the physics for ``dt`` [s]. Within the tick the servos' setpoint moves on
        with the commanded velocity and acceleration (as an interpolating servo does),
        with the reference motion's torque as feed-forward; a bare position is held."""
        mj, m, d = self._mj, self.model, self.data
        h = m.opt.timestep
        n = max(1, int(round(dt / h)))
        self._tick = dt
        kp = np.array([g.kp for g in self.gains])
        q0, qd0, qdd0 = self._q_ref, self._qd_ref, self._qdd_ref
        for i in range(n):
            tau = i * h
            if qd0 is None:
                ctrl = servo_ctrl(q0, None, self.gains)
            elif qdd0 is None:
                ctrl = servo_ctrl(q0 + qd0 * tau, qd0, self.gains)
            else:
                j = self._jerk if self._jerk is not None else 0.0
                q = q0 + tau * (qd0 + tau * (0.5 * qdd0 + tau * j / 6))
                qd = qd0 + tau * (qdd0 + 0.5 * tau * j)
                qdd = qdd0 + tau * j
                ff = self._inverse(q, qd, qdd)
                np.maximum(self._peak_ff, np.abs(ff), out=self._peak_ff)
                ctrl = servo_ctrl(q, qd, self.gains) + ff / kp
            d.ctrl[self._act] = ctrl
            mj.mj_step(m, d)
            f = np.abs(d.actuator_force[self._act])
            np.maximum(self._peak, f, out=self._peak)
            if np.any(f >= self.effort * (1 - 1e-9)):
                self._saturated += 1
            if d.ncon:
                touching = self.contacts_now()
                self._contacts.update(touching)
                self._contact_steps += bool(touching)
            self._steps += 1
        if not np.all(np.isfinite(d.qpos)):
            raise SimulationError("the simulation diverged (non-finite positions)",
                                  details={"time": float(d.time)})

    def _pair(self, g1: int, g2: int) -> tuple[str, str]:
        def name(g: int) -> str:
            n = self._geom_names[g]
            return n if n.startswith("obstacle:") else self._body_of_geom[g]
        return tuple(sorted((name(g1), name(g2))))  # type: ignore[return-value]

    def state(self) -> JointState:
        d = self.data
        eff = np.concatenate([d.actuator_force[self._act],
                              d.qfrc_constraint[self._dadr[len(self.joint_names):]]])
        return JointState(self.state_names, tuple(map(float, d.qpos[self._qadr])),
                          tuple(map(float, d.qvel[self._dadr])), tuple(map(float, eff)),
                          float(d.time))

    def reset(self, positions: Sequence[float] | np.ndarray) -> None:
        """Back to rest at ``positions`` [rad] (time 0, setpoint there, figures cleared)."""
        q = check_setpoint(positions, self.joint_names, "positions")
        self._mj.mj_resetData(self.model, self.data)
        self._set_positions(q)
        self._q_ref = q
        self._qd_ref = None
        self._qdd_ref = None
        self._jerk = None
        self.data.ctrl[self._act] = servo_ctrl(q, None, self.gains)
        self._peak = np.zeros(len(self.joint_names))
        self._peak_ff = np.zeros(len(self.joint_names))
        self._saturated = 0
        self._contacts = set()
        self._contact_steps = 0
        self._steps = 0

    # -- simulation figures ------------------------------------------------------------
    def stats(self) -> SimStats:
        return SimStats(tuple(map(float, self._peak)), tuple(map(float, self._peak_ff)),
                        tuple(map(float, self.effort)),
                        self._saturated, tuple(sorted(self._contacts)), self._contact_steps,
                        self._steps, float(self.data.time))  # 0 at reset

    def contacts_now(self) -> list[tuple[str, str]]:
        """Body pairs in contact in the current state."""
        d = self.data
        return sorted({self._pair(int(c.geom1), int(c.geom2))
                       for c in d.contact[:d.ncon] if c.dist <= 0})
