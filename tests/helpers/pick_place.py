"""A pick and place on the course-like workspace (tests/helpers/course_workspace.py): a
table with a box on it, a bin with walls beside it, and the task that moves the box into
the bin (above, LIN down 5 cm, close, attach, LIN up, across, down, open, detach, up),
in the task's JSON form (``<prefix>/task``'s ``task``). Shared by
tests/planner/tasks/test_task.py, tests/service/test_task_pool.py and bench/task.py; and
docs/tasks.md's pick as the page gives it (:func:`docs_pick`)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

TABLE_TOP = 0.35  # [m] the table's top, under the course arm's reach (10x scale model)
BOX = 0.08  # [m] the box's edge
ABOVE = 0.61  # [m] the tcp (claw_support's origin) above the box's top before the
#: descent: the course gripper's fingers reach ~0.55 m below it (the 10x model)
DROP = 0.05  # [m] each straight-line descent and ascent
#: [m] the box's bottom above the table: none, it rests on it (an attached object may
#: touch what it rests on until a motion takes it clear: planner/tasks/progress.py)
GAP = 0.0
#: [m] see and pick's box above its table (tests/cli/test_see_and_pick.py): planned
#: where the camera saw it, a few mm off, it must not be seen inside the table
HOVER = 0.002
BIN_INNER = 0.2  # [m] the bin's inside, square
BIN_FLOOR = 0.06  # [m] the bin's floor below the box's bottom at its lowest
BIN_RIM = 0.02  # [m] the bin's walls above it
WALL = 0.01  # [m]
BOX_XY = (0.52, 0.80)  # [m] the box's nominal place on the table
BIN_XY = (-0.55, 0.78)  # [m] the bin's nominal place
#: [m] the two-step task lets the box go with its bottom this far above the table's height
RELEASE = 0.01


def bin_walls(cx: float, cy: float) -> list[dict[str, Any]]:
    """A bin (a floor and four walls) centred at (cx, cy): the box is lowered into it
    until its bottom is at the table's height and let go (it drops onto the floor)."""
    floor = TABLE_TOP - BIN_FLOOR
    top = TABLE_TOP + BIN_RIM
    h = top - floor
    out = [{"id": "bin_floor", "shape": "box", "size": [BIN_INNER + 2 * WALL] * 2 + [WALL],
            "xyz": [cx, cy, floor - WALL / 2]}]
    off = BIN_INNER / 2 + WALL / 2
    for name, dx, dy, sx, sy in (("bin_n", 0, off, BIN_INNER + 2 * WALL, WALL),
                                 ("bin_s", 0, -off, BIN_INNER + 2 * WALL, WALL),
                                 ("bin_e", off, 0, WALL, BIN_INNER),
                                 ("bin_w", -off, 0, WALL, BIN_INNER)):
        out.append({"id": name, "shape": "box", "size": [sx, sy, h],
                    "xyz": [cx + dx, cy + dy, floor + h / 2]})
    return out


def pick_and_place(box_xy: tuple[float, float] = BOX_XY,
                   bin_xy: tuple[float, float] = BIN_XY, *, attach: bool = True,
                   mass: float = 0.05, seed: int = 1) -> dict[str, Any]:
    """The pick and place task's JSON form (``<prefix>/task``'s ``task``): a table under
    the box, a low bin beside it; ``attach`` False leaves out the attach and detach
    steps (the gripper closes and opens on nothing the planner carries)."""
    bx, by = box_xy
    cx, cy = bin_xy
    box_z = TABLE_TOP + GAP + BOX / 2
    above_box = [bx, by, TABLE_TOP + BOX + ABOVE]
    above_bin = [cx, cy, TABLE_TOP + BOX + ABOVE]
    obstacles = [
        {"id": "table", "shape": "box", "size": [0.5, 0.5, 0.05],
         "xyz": [bx, by, TABLE_TOP - 0.025]},
        {"id": "box", "shape": "box", "size": [BOX, BOX, BOX], "xyz": [bx, by, box_z]},
        *bin_walls(cx, cy),
    ]
    down = {"line": {"offset": [0.0, 0.0, -DROP]}}
    up = {"line": {"offset": [0.0, 0.0, DROP]}}
    steps: list[dict[str, Any]] = [
        {"gripper": "open", "label": "open"},
        {"move": {"position": above_box}, "label": "above the box"},
        {**down, "label": "down"},
        {"gripper": "close", "label": "grip"},
        # the course workspace has no tool point between the fingers (its tcp is
        # claw_support's origin), so a position goal over the box leaves the fingers
        # 0.25 m from it: the twin welds the box all the same; reach says it is known
        *([{"attach": "box", "mass": mass, "reach": 0.3, "label": "pick"}] if attach
          else []),
        {**up, "label": "up"},
        {"move": {"position": above_bin}, "label": "above the bin"},
        {**down, "label": "down"},
        {"gripper": "open", "label": "release"},
        *([{"detach": "box", "label": "place"}] if attach else []),
        {**up, "label": "up"},
    ]
    return {"obstacles": obstacles, "steps": steps, "seed": seed}


def pick_and_place_by_name(box_xy: tuple[float, float] = BOX_XY,
                           bin_xy: tuple[float, float] = BIN_XY, *, mass: float = 0.05,
                           seed: int = 1) -> dict[str, Any]:
    """The same pick and place as two steps (``pick box``, ``place box`` at ``bin``, a
    place the task names), the box resting on the table (no gap): the service generates
    the grasp and the rest. ``bin`` is a position over the bin, the box's bottom
    :data:`RELEASE` above the table's height (inside the walls, as the eleven steps let
    it go): the course claw, 0.36 m across its fingers, does not fit between the bin's
    walls (0.2 m apart), so the box is let go there and drops onto the floor."""
    bx, by = box_xy
    cx, cy = bin_xy
    obstacles = [
        {"id": "table", "shape": "box", "size": [0.5, 0.5, 0.05],
         "xyz": [bx, by, TABLE_TOP - 0.025]},
        {"id": "box", "shape": "box", "size": [BOX, BOX, BOX],
         "xyz": [bx, by, TABLE_TOP + BOX / 2]},
        *bin_walls(*bin_xy),
    ]
    return {"obstacles": obstacles,
            "places": {"bin": {"position": [cx, cy, TABLE_TOP + RELEASE + BOX / 2]}},
            "steps": [{"pick": "box", "mass": mass}, {"place": "box", "at": "bin"}],
            "seed": seed}


def variants(n: int, *, seed: int = 7, attach: bool = True, by_name: bool = False
             ) -> list[dict[str, Any]]:
    """``n`` pick and place tasks, the box and the bin moved up to 4 cm (seeded);
    ``by_name``: the two-step form (:func:`pick_and_place_by_name`) of the same ones."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        db, dc = rng.uniform(-0.04, 0.04, 2), rng.uniform(-0.04, 0.04, 2)
        box, bin_ = (BOX_XY[0] + db[0], BOX_XY[1] + db[1]), (BIN_XY[0] + dc[0],
                                                             BIN_XY[1] + dc[1])
        out.append(pick_and_place_by_name(box, bin_, seed=i + 1) if by_name else
                   pick_and_place(box, bin_, attach=attach, seed=i + 1))
    return out


def docs_pick() -> dict[str, Any]:
    """The first JSON block of docs/tasks.md: the pick it tells the user to save."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "tasks.md").read_text()
    block = re.search(r"```json\n(.*?)```", text, re.S)
    assert block is not None, "docs/tasks.md has no JSON block"
    out: dict[str, Any] = json.loads(block.group(1))
    return out
