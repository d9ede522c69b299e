"""The viewer: a viser server showing the robot, sliders per joint and collisions.

Threading: viser runs GUI callbacks on its own threads; every change of the shown pose
goes through :meth:`RobotViewer.set_q`, which holds one lock while it moves the links (and
the objects they carry) and recolours them; a new kept scene goes through
:meth:`RobotViewer.set_scene`, under the same lock.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.collision.world import CollisionWorld, StateCheck
from arduinobot.scene.obstacles import Obstacle
from arduinobot.viewer import require
from arduinobot.viewer.geometry import (
    CARRIED_RGB,
    COLLISION_RGB,
    OBSTACLE_RGB,
    SCENE_RGB,
    frame_box,
    link_meshes,
    matrix_to_wxyz,
    obstacle_mesh,
    world_bounds,
)
from arduinobot.viewer.scene_view import CloudItem, SceneItem, ViewerScene, world_points

if TYPE_CHECKING:
    import viser  # optional (the view extra): imported at run time through require()

_log = logging.getLogger(__name__)


class RobotViewer:
    """Serve a page showing ``description`` at the slider values, with collisions in red.

    Args:
        description: the robot.
        obstacles: a request's own obstacles to show (and check against).
        scene: a kept scene to show (and check against): free objects in the world,
            carried ones on their link; :meth:`set_scene` replaces it.
        host: the address to listen on (127.0.0.1: this machine only).
        port: the HTTP/websocket port.

    The first pose is all zeros clamped into the limits.

    Raises:
        arduinobot.contract.errors.InvalidRequest: an obstacle with the id of a scene object.
    """

    def __init__(self, description: Description, *, obstacles: Sequence[Obstacle] = (),
                 scene: ViewerScene | None = None, host: str = "127.0.0.1",
                 port: int = 8080) -> None:
        viser = require("viser")
        self.description = description
        self.obstacles = tuple(obstacles)
        self.scene = scene if scene is not None else ViewerScene()
        self.world = self._world(self.scene)
        self.kin = self.world.kin
        self.joint_names = self.kin.joint_names
        lim = description.robot.position_limits(self.joint_names)
        self.lower = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -math.pi)
        self.upper = np.where(np.isfinite(lim[:, 1]), lim[:, 1], math.pi)
        self._q = np.clip(np.zeros(self.kin.dof), self.lower, self.upper)
        self._lock = threading.RLock()
        self._local = threading.local()  # marks set_q's own slider writes
        self.meshes = link_meshes(description, self.kin)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.gui.configure_theme(control_layout="floating", control_width="medium",
                                        show_share_button=False)
        self._build_scene()
        self.sliders = self._build_joint_panel()
        self.check = self.world.check(self._q)
        self._poses = self.kin.link_poses(self._q)
        self.set_q(self._q, force=True)
        _log.info("viewer serving %s on http://%s:%d", description.robot.name, host,
                  self.server.get_port())

    # -- building ----------------------------------------------------------------------
    def _build_scene(self) -> None:
        scene = self.server.scene
        scene.set_up_direction("+z")
        poses = self.kin.link_poses(self._q)
        bounds = world_bounds(self.meshes, poses, self.obstacles,
                              extra=world_points(self.scene.items, self._by_link(poses)))
        size = float(np.max(bounds[1] - bounds[0]))
        cell = 10 ** math.floor(math.log10(max(size, 1e-3) / 2))
        extent = 2 * cell * math.ceil(1.5 * size / (2 * cell))
        scene.add_grid("/ground", width=extent, height=extent, plane="xy", cell_size=cell,
                       section_size=cell * 5, position=(float(bounds.mean(axis=0)[0]),
                                                        float(bounds.mean(axis=0)[1]), 0.0))
        view = frame_box(bounds)
        cam = self.server.initial_camera
        cam.fov = view.fov
        cam.look_at = view.look_at
        cam.position = view.position
        cam.up = (0.0, 0.0, 1.0)
        axes = 0.12 * size
        self._frames = {}
        self._mesh_handles = {}
        for m in self.meshes:
            self._frames[m.link] = scene.add_frame(
                f"/robot/{m.link}", show_axes=False, axes_length=axes, axes_radius=axes * 0.04)
            self._mesh_handles[m.link] = scene.add_mesh_simple(
                f"/robot/{m.link}/visual", m.vertices, m.faces, color=m.color)
        self._obstacle_handles = {}
        for o in self.obstacles:
            mesh = obstacle_mesh(o)
            pose = o.pose()
            self._obstacle_handles[o.id] = scene.add_mesh_simple(
                f"/obstacles/{o.id}", np.asarray(mesh.vertices, np.float32),
                np.asarray(mesh.faces, np.uint32), color=OBSTACLE_RGB, opacity=0.85,
                wxyz=matrix_to_wxyz(pose[:3, :3]), position=tuple(pose[:3, 3]))
        self._colors = {m.link: m.color for m in self.meshes}
        self._colors.update({o: OBSTACLE_RGB for o in self._obstacle_handles})
        self._scene_handles: dict[str, Any] = {}
        self._scene_items: dict[str, SceneItem] = {}
        for item in self.scene.items:
            self._draw_item(item, poses)
        for cloud in self.scene.clouds:
            self._draw_cloud(cloud)

    def _draw_cloud(self, cloud: CloudItem) -> None:
        """Add a kept cloud's cells to the page: a point per cell, a cell wide,
        coloured by height."""
        self._scene_handles[cloud.id] = self.server.scene.add_point_cloud(
            f"/scene/{cloud.id}", cloud.points, cloud.colors, point_size=cloud.size,
            point_shape="square", precision="float32")

    def _draw_item(self, item: SceneItem, poses: np.ndarray) -> None:
        """Add one kept-scene object to the page at its pose for link ``poses``."""
        pose = self._item_pose(item, poses)
        self._scene_handles[item.id] = self.server.scene.add_mesh_simple(
            f"/scene/{item.id}", item.vertices, item.faces,
            color=CARRIED_RGB if item.carried else SCENE_RGB, opacity=0.85,
            wxyz=matrix_to_wxyz(pose[:3, :3]), position=tuple(float(v) for v in pose[:3, 3]))
        self._scene_items[item.id] = item

    def _item_pose(self, item: SceneItem, poses: np.ndarray) -> np.ndarray:
        return item.pose(poses[self.kin.link_index[item.link]] if item.link is not None
                         else None)

    def _by_link(self, poses: np.ndarray) -> dict[str, np.ndarray]:
        return {name: poses[i] for name, i in self.kin.link_index.items()}

    def _world(self, scene: ViewerScene) -> CollisionWorld:
        """The collision check of the robot with the obstacles and ``scene`` (the robot's
        own geometry built once, reused for every scene)."""
        both = sorted({o.id for o in self.obstacles} & {i.id for i in scene.items})
        if both:
            raise InvalidRequest(
                f"id(s) {', '.join(both)} name both an obstacle of this page and an object "
                f"of the kept scene ({scene.summary()}): rename the obstacle",
                field="obstacles")
        current: CollisionWorld | None = getattr(self, "world", None)  # None: the first
        bodies = current.bodies if current is not None else None
        return CollisionWorld(self.description, obstacles=self.obstacles + scene.obstacles,
                              attached=scene.attached, bodies=bodies,
                              clouds=scene.cloud_bodies)

    def _build_joint_panel(self) -> dict[str, viser.GuiSliderHandle[float]]:
        gui = self.server.gui
        robot = self.description.robot
        sliders: dict[str, viser.GuiSliderHandle[float]] = {}
        with gui.add_folder("Joints"):
            for i, name in enumerate(self.joint_names):
                mimics = robot.mimics_of(name)
                hint = f"{name} [rad]" + (f"; {', '.join(mimics)} follow(s) it" if mimics else "")
                label = name + (f" (+{', '.join(mimics)})" if mimics else "")
                s = gui.add_slider(label, min=float(self.lower[i]), max=float(self.upper[i]),
                                   step=0.01, initial_value=float(self._q[i]), hint=hint,
                                   marks=tuple((float(v), f"{v:.2f}") for v in
                                               (self.lower[i], self.upper[i])))
                s.on_update(self._slider_moved)
                sliders[name] = s
            srdf = self.description.srdf
            states = {label: dict(st.values) for label, st in
                      srdf.labelled_states().items()} if srdf is not None else {}
            if states:
                pick = gui.add_dropdown("Named state", ("(choose)",) + tuple(states),
                                        hint="move the sliders to an SRDF named state")

                @pick.on_update
                def _(_event: object) -> None:
                    if pick.value in states:
                        self.set_joints(states[pick.value])
            frames = gui.add_checkbox("Show link frames", False)

            @frames.on_update
            def _(_event: object) -> None:
                for f in self._frames.values():
                    f.show_axes = frames.value
        with gui.add_folder("Collisions"):
            self._collision_md = gui.add_markdown("")
        with gui.add_folder("Scene"):
            self._scene_md = gui.add_markdown(self.scene.summary())
        return sliders

    # -- state -------------------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        """The shown pose, shape (dof,) [rad], in ``joint_names`` order (a copy)."""
        with self._lock:
            return self._q.copy()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}/"

    def _slider_moved(self, _event: object) -> None:
        if getattr(self._local, "setting", False):
            return
        self.set_q([float(self.sliders[n].value) for n in self.joint_names])

    def set_q(self, q: ArrayLike, *, force: bool = False) -> StateCheck:
        """Show pose ``q`` (shape (dof,) [rad], clamped into the limits): move the links,
        the sliders, and colour colliding bodies red. Returns the collision check."""
        qc = np.clip(np.asarray(q, dtype=float).reshape(-1), self.lower, self.upper)
        with self._lock:
            if not force and np.array_equal(qc, self._q):
                return self.check
            self._q = qc
            poses = self.kin.link_poses(qc)
            check = self.world.check(qc)
            red = {name for pair in check.pairs for name in pair}
            with self.server.atomic():
                for m in self.meshes:
                    t = poses[m.index]
                    f = self._frames[m.link]
                    f.wxyz = matrix_to_wxyz(t[:3, :3])
                    f.position = tuple(float(v) for v in t[:3, 3])
                for item in self._scene_items.values():
                    if item.carried:  # it moves with its link
                        t = self._item_pose(item, poses)
                        h = self._scene_handles[item.id]
                        h.wxyz = matrix_to_wxyz(t[:3, :3])
                        h.position = tuple(float(v) for v in t[:3, 3])
                for name, h in (self._mesh_handles | self._obstacle_handles).items():
                    want = COLLISION_RGB if name in red else self._colors[name]
                    if force or tuple(h.color) != want:
                        h.color = want
                for name, item in self._scene_items.items():  # a cloud keeps its heights
                    h = self._scene_handles[name]
                    want = COLLISION_RGB if name in red else \
                        CARRIED_RGB if item.carried else SCENE_RGB
                    if force or tuple(h.color) != want:
                        h.color = want
                self._local.setting = True
                try:
                    for i, n in enumerate(self.joint_names):
                        if abs(float(self.sliders[n].value) - qc[i]) > 1e-9:
                            # viser defines value's setter apart from its getter, which
                            # mypy reads as a read-only property
                            self.sliders[n].value = float(qc[i])  # type: ignore[misc]
                finally:
                    self._local.setting = False
                self._collision_md.content = _collision_text(check)
            self.check, self._poses = check, poses
        return check

    def set_joints(self, values: Mapping[str, float]) -> StateCheck:
        """Show the current pose with the named joints at ``values`` [rad] (names that are
        not actuated joints are ignored); see :meth:`set_q`."""
        q = self.q
        for name, v in values.items():
            if name in self.joint_names:
                q[self.joint_names.index(name)] = float(v)
        return self.set_q(q)

    def link_poses(self) -> np.ndarray:
        """The shown links' poses, shape (n_links, 4, 4), in ``kin.link_names`` order."""
        with self._lock:
            return self._poses.copy()

    def set_scene(self, scene: ViewerScene) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """Show ``scene`` instead of the current kept scene: what was removed or changed
        goes, what was added or changed is drawn, carried objects on their link, and the
        collision check takes the new scene. Returns (ids drawn anew, ids taken away).

        Raises:
            arduinobot.contract.errors.InvalidRequest: a scene object with the id of one of the
                obstacles (the page keeps the scene it shows).
        """
        # refused here, before anything on the page changes; built outside the lock (a
        # mesh's trees take a moment) so the robot keeps moving meanwhile
        world = self._world(scene)
        with self._lock:
            fresh, gone = scene.changes(self.scene)
            with self.server.atomic():
                for oid in gone:
                    self._scene_handles.pop(oid).remove()
                    self._scene_items.pop(oid, None)  # a cloud is no item
                items = {i.id: i for i in scene.items}
                clouds = {c.id: c for c in scene.clouds}
                for oid in fresh:
                    if oid in clouds:
                        self._draw_cloud(clouds[oid])
                    else:
                        self._draw_item(items[oid], self._poses)
            self.scene, self.world = scene, world
            self.set_q(self._q, force=True)
            self._scene_md.content = scene.summary()
        _log.info("viewer: scene %s (%d drawn anew, %d taken away)", scene.summary(),
                  len(fresh), len(gone))
        return fresh, gone

    def object_poses(self) -> dict[str, np.ndarray]:
        """Where the kept scene's objects are shown, id -> pose in the world, shape (4, 4)
        (carried ones where their link is now)."""
        with self._lock:
            return {i: self._item_pose(item, self._poses)
                    for i, item in self._scene_items.items()}

    def close(self) -> None:
        self.server.stop()


def _collision_text(check: StateCheck) -> str:
    if check.valid:
        return "**No collision**"
    lines = "\n".join(f"- {a} ↔ {b}" for a, b in check.pairs)
    return f"**In collision** ({len(check.pairs)} pairs):\n\n{lines}"
