"""What the kept scene needs of the robot to attach and detach
(:class:`arduinobot.scene.frames.Frames`), in the service: the serving process holds a
:class:`PooledFrames`, which asks the pool (a ``frames`` job), so it never imports the
planner nor holds the GIL for a collision check next to Zenoh's callbacks; a worker
answers with its :class:`arduinobot.planner.frames.RobotFrames` (:func:`answer_frames`).

It parses the scene's inline meshes there too (:meth:`PooledFrames.store_mesh`, op
``mesh``): a mesh's parse takes ~110 MB for a moment (a 1.6 MB OBJ of 199,000
triangles), and in the serving process, among Zenoh's threads and their malloc arenas,
mesh churn left it at 421 MiB with the scene cleared (69 at start: ``./dev bench
mesh_churn``); a worker has its memory cap, gives its heap back after the job, and is
replaced if the parse runs out of memory.
"""

from __future__ import annotations

import base64
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import orjson

from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import Description
from arduinobot.planner.checks import joint_values
from arduinobot.scene.cloud import Cells, CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from arduinobot.service.messages import Failure, Submit, outcome_of

if TYPE_CHECKING:  # a worker's; the serving process never imports it
    from arduinobot.planner.frames import RobotFrames

_log = logging.getLogger(__name__)


class PooledFrames:
    """Frames whose link poses and contacts a worker of the pool computes (``frames``
    jobs, :func:`answer_frames`); a state is checked here (no kinematics needed). A state
    is the checked ``{joint: value}`` map: the worker orders it."""

    def __init__(self, description: Description, *, submit: Submit) -> None:
        self.description = description
        self._submit = submit

    def state(self, values: Any, *, field: str) -> Any:
        return joint_values(self.description, values, field=field)

    def link_pose(self, q: Any, link: str) -> np.ndarray:
        return np.array(self._ask({"op": "link_pose", "joints": q, "link": link})["pose"],
                        float)

    def link_contacts(self, a: AttachedObject, q: Any) -> list[tuple[str, str]]:
        pairs = self._ask({"op": "contacts", "joints": q, "attached": a})["pairs"]
        return [(x, y) for x, y in pairs]

    def grasp_distance(self, a: AttachedObject, q: Any) -> tuple[float, str]:
        out = self._ask({"op": "grasp", "joints": q, "attached": a})
        return float(out["distance"]), str(out["nearest"])

    def keep_cloud(self, data: dict[str, Any], q: Any, *, where: str,
                   objects: Sequence[Obstacle], attached: Sequence[AttachedObject]
                   ) -> tuple[tuple[CloudObstacle, ...], dict[str, Any]]:
        out = self._ask({"op": "cloud", "joints": q, "data": data, "where": where,
                         "objects": tuple(objects), "attached": tuple(attached)})
        bodies = tuple(CloudObstacle(b["id"], Cells(np.frombuffer(
            base64.b64decode(b["index"]), "<i8").reshape(-1, 3).copy(), b["resolution"]),
            b["unknown"]) for b in out["bodies"])
        return bodies, out["counts"]

    def store_mesh(self, data: Mapping[str, Any], *, where: str, folder: Path
                   ) -> dict[str, Any]:
        """:meth:`arduinobot.scene.shapes.Mesh.stored` in a worker: the object's data
        with ``mesh_path`` (the file written in ``folder``) for its inline mesh.

        Raises:
            InvalidRequest: the mesh's refusals, naming the field under ``where``.
            PlanningError: RESOURCE_LIMIT (the parse ran out of a worker's memory).
        """
        out = outcome_of(self._submit, "frames", {"op": "mesh", "data": dict(data),
                                                  "where": where, "folder": str(folder)})
        if isinstance(out, Failure):
            if out.code == Code.INVALID_REQUEST:  # as raised there: field and all
                err: PlanningError = InvalidRequest.__new__(InvalidRequest)
                PlanningError.__init__(err, out.message, details=dict(out.details))
                err.field = out.details.get("field")  # type: ignore[attr-defined]
            else:
                err = PlanningError(f"{where}.mesh: {out.message}",
                                    details={**out.details, "field": f"{where}.mesh"})
                err.code = out.code
            raise err
        return dict(orjson.loads(out.body)["stored"])

    def _ask(self, data: Mapping[str, Any]) -> dict[str, Any]:
        out = outcome_of(self._submit, "frames", data)
        if isinstance(out, Failure):
            err = PlanningError(f"the robot's frames could not be computed: {out.message}",
                                details=dict(out.details))
            err.code = out.code
            raise err
        return orjson.loads(out.body)


def answer_mesh(data: Mapping[str, Any]) -> dict[str, Any]:
    """A ``frames`` job of op ``mesh`` in a worker: ``{"stored": the object's data with
    mesh_path}`` (see :meth:`PooledFrames.store_mesh`)."""
    from arduinobot.scene.shapes.mesh import Mesh
    return {"stored": Mesh.stored(data["data"], where=data["where"],
                                  folder=Path(data["folder"]))}


def answer_frames(frames: RobotFrames, data: Mapping[str, Any]) -> dict[str, Any]:
    """A ``frames`` job in a worker: ``link_pose`` -> ``{"pose": 4x4}``, ``contacts``
    -> ``{"pairs": [[object, link], ...]}``, at the state ``data["joints"]`` (checked by
    :meth:`PooledFrames.state`)."""
    names = frames.kinematics().joint_names
    joints = data["joints"]
    q = np.array([joints[n] for n in names], float)
    if data["op"] == "link_pose":
        return {"pose": frames.link_pose(q, data["link"]).tolist()}
    if data["op"] == "grasp":
        distance, nearest = frames.grasp_distance(data["attached"], q)
        return {"distance": distance, "nearest": nearest}
    if data["op"] == "cloud":  # the cells' indices as int64 bytes: 3 numbers a cell
        bodies, counts = frames.keep_cloud(data["data"], q, where=data["where"],
                                           objects=data["objects"],
                                           attached=data["attached"])
        return {"counts": counts, "bodies": [
            {"id": b.id, "unknown": b.unknown, "resolution": b.cells.resolution,
             "index": base64.b64encode(np.ascontiguousarray(b.cells.index, "<i8")
                                       .tobytes()).decode("ascii")} for b in bodies]}
    return {"pairs": [list(p) for p in frames.link_contacts(data["attached"], q)]}
