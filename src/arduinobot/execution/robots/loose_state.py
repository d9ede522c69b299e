"""A twin's loose objects kept across a rebuild of its model.

The twin rebuilds its MuJoCo model for every change of its world (the kept scene at a
new revision). A task's loose objects (what it picks up) would start afresh where the
task first had them: a box already in the gripper would jump back onto the table when a
sphere is added on its way and the task is planned again from where the arm stopped.
:class:`LooseState` keeps each one's simulated pose and velocity (its free joint) and
whether the gripper holds it (its grasp weld, with the relative pose taken when it
closed), by name, and puts them into the new model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.execution.robots.mjcf import GRASP_PREFIX, LOOSE_PREFIX

__all__ = ["LooseState"]


@dataclass(frozen=True)
class LooseState:
    """The loose objects' state in one model, by name.

    Attributes:
        joints: free joint name -> (qpos shape (7,) [m, quaternion], qvel shape (6,)
            [m/s, rad/s]).
        welds: grasp weld name -> (active, eq_data shape (11,): the relative pose kept).
    """

    joints: dict[str, tuple[np.ndarray, np.ndarray]]
    welds: dict[str, tuple[bool, np.ndarray]]

    @classmethod
    def of(cls, mj: Any, model: Any, data: Any) -> LooseState:
        """What ``data`` (of ``model``; ``mj`` the mujoco module) holds of the loose
        objects now."""
        joints = {}
        for j in range(model.njnt):
            name = mj.mj_id2name(model, mj.mjtObj.mjOBJ_JOINT, j) or ""
            if name.startswith(LOOSE_PREFIX) and model.jnt_type[j] == mj.mjtJoint.mjJNT_FREE:
                a, v = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
                joints[name] = (data.qpos[a:a + 7].copy(), data.qvel[v:v + 6].copy())
        welds = {}
        for e in range(model.neq):
            name = mj.mj_id2name(model, mj.mjtObj.mjOBJ_EQUALITY, e) or ""
            if name.startswith(GRASP_PREFIX):
                welds[name] = (bool(data.eq_active[e]), model.eq_data[e].copy())
        return cls(joints, welds)

    def put(self, mj: Any, model: Any, data: Any) -> None:
        """Put the kept state into ``data`` (of a new ``model``) for every loose object
        both have, then recompute the positions (the others, new to the model, start
        where it has them)."""
        for name, (q, v) in self.joints.items():
            j = mj.mj_name2id(model, mj.mjtObj.mjOBJ_JOINT, name)
            if j < 0 or model.jnt_type[j] != mj.mjtJoint.mjJNT_FREE:
                continue
            a, d = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            data.qpos[a:a + 7], data.qvel[d:d + 6] = q, v
        for name, (active, eq) in self.welds.items():
            e = mj.mj_name2id(model, mj.mjtObj.mjOBJ_EQUALITY, name)
            if e < 0:
                continue
            model.eq_data[e] = eq
            data.eq_active[e] = int(active)
        mj.mj_forward(model, data)
