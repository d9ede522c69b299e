"""Reproducible CSG generator for the arduinobot's seven STL meshes.

Every part is modelled in its *link* frame, in centimetres, because that is
where the joint axes live (shoulder and elbow about x, base yaw and gripper
fingers about z) and where the clearance rules are easiest to reason about.
Each part is then mapped into its *file* frame, the frame the URDF's
``<origin>`` and ``scale="0.01 0.01 0.01"`` expect, and written as binary STL.

The envelopes (axis-aligned bounds of every file) follow the "Mesh envelopes"
table of the robot model. The shapes are laid out so that, with the URDF's
kinematics:

* no two links touch at the zero pose (every pair keeps >= 5 mm at robot
  scale);
* every parent/child pair stays apart over its joint's whole range.  The
  upper arm is a pair of side plates whose inner faces stay 6 mm outside the
  forearm's width, so the forearm can fold through it; the shoulder tower
  cheeks stand 6 mm outside the upper arm's width; the basement's top stops
  5 mm below the turntable's underside; the gripper bracket stops 5 mm above
  the fingers, and its servo sits behind the fingers' swept discs;
* the two fingers' jaw pads sit at different heights (right low, left high),
  so the pads may cross at the closed pose without touching.

Run ``python -m arduinobot.description.meshgen`` to rewrite the committed meshes. Only this needs
the mesh-boolean library manifold3d, an optional extra (``pip install -e '.[meshgen]'``):
nothing at run time imports this module.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import trimesh

try:
    from manifold3d import CrossSection, Manifold
except ImportError as e:  # an optional extra: say which, not just the module's name
    raise ImportError("arduinobot.description.meshgen needs manifold3d, the 'meshgen' extra: "
                      "pip install -e '.[meshgen]'") from e

from arduinobot.description.csg import (
    SEG,
    SEG_FINE,
    SEG_SMALL,
    UNION,
    Vec2,
    Vec3,
    circle,
    extrude,
    rect,
    rounded_box,
    rounded_rect,
    rounded_slab,
    stadium,
    turned,
)

MESH_DIR: Path = Path(__file__).resolve().parent / "arduinobot_description" / "meshes"


# (xyz [m], rpy [quarter turns]) of each mesh's visual/collision origin in the
# URDF.  The URDF writes pi as 3.14159, so its rotations differ from these
# exact axis permutations by ~3e-6 rad: a few micrometres at most.
ORIGINS: dict[str, tuple[Vec3, Vec3]] = {
    "basement.STL": ((-0.5, -0.5, 0.0), (0.0, 0.0, 0.0)),
    "base_plate.STL": ((-0.39, -0.39, -0.56), (0.0, 0.0, 0.0)),
    "forward_drive_arm.STL": ((0.19, 0.06, -0.08), (0.0, -1.0, 1.0)),
    "horizontal_arm.STL": ((-0.03, -0.4, -0.06), (1.0, 0.0, 1.0)),
    "claw_support.STL": ((0.0, -0.05, -0.15), (0.0, 0.0, 1.0)),
    "right_finger.STL": ((-0.1, 0.5, -0.1), (0.0, 0.0, -1.0)),
    "left_finger.STL": ((-0.04, 0.5, -0.1), (0.0, 0.0, -1.0)),
}


# ------------------------------------------------------------------- parts
# All parts below are in their link frame, centimetres.


def basement() -> Manifold:
    """Base housing: hollow rounded box, bearing ring for the turntable, cable slot."""
    outline = rounded_rect((-49.5, -49.5), (45.1, 38.0), 6.0, SEG)
    shell = rounded_slab(outline, "z", 0.0, 27.0, 2.0, fillet_lo=False)
    cavity = extrude(rounded_rect((-47.0, -47.0), (42.6, 35.5), 3.5, SEG), "z", -1.0, 24.5)
    housing = shell - cavity
    # Cable slot at the back wall, vents on the right-hand wall.
    housing -= extrude(stadium((2.0, -7.0), (2.0, 7.0), 3.0), "y", -51.0, -45.0)
    vents = [
        extrude(stadium((y, 11.0), (y, 19.0), 1.2, SEG_SMALL), "x", 40.0, 47.0)
        for y in np.arange(-30.0, 25.0, 6.0)
    ]
    housing -= Manifold.batch_boolean(vents, UNION)
    # Bearing ring and shaft boss on the joint_1 axis.  The ring top is at
    # 30.9 cm, 1 mm under the table's 31.0, and the turntable's underside 1 mm
    # over its table value, for a 5 mm gap instead of a 3 mm one.
    ring = turned("z", (0.0, 0.0), 25.0, 30.0, 26.5, 30.9, fillet=0.6, segments=SEG_FINE * 2)
    boss = turned("z", (0.0, 0.0), 3.0, 7.0, 26.5, 29.0, fillet=0.5, segments=SEG_FINE)
    screw_heads = [
        turned("z", (x, y), 0.0, 1.6, 26.0, 28.0, fillet=0.3, segments=SEG_SMALL)
        for x in (-42.0, 38.0)
        for y in (-42.0, 31.0)
    ]
    return Manifold.batch_boolean([housing, ring, boss, *screw_heads], UNION)


def base_plate() -> Manifold:
    """Turntable disc carrying the shoulder tower: two cheeks and the shoulder servo."""
    disc = turned("z", (0.0, 0.0), 0.0, 33.0, 0.7, 5.7, fillet=1.5, segments=SEG_FINE * 2)
    bolt_holes = [
        extrude(circle((24.0 * math.cos(a), 24.0 * math.sin(a)), 2.2, SEG_SMALL), "z", -1.0, 8.0)
        for a in np.radians([45.0, 135.0, 225.0, 315.0])
    ]
    disc -= Manifold.batch_boolean(bolt_holes, UNION)
    # Cable-clamp lugs at the rim fix the y extents of the envelope.
    lug_back = rounded_slab(rounded_rect((-6.0, -39.0), (6.0, -28.0), 3.0), "z", 0.9, 4.5, 0.8)
    lug_back -= extrude(stadium((-2.5, -34.5), (2.5, -34.5), 1.5, SEG_SMALL), "z", -1.0, 8.0)
    lug_front = rounded_slab(rounded_rect((-6.0, 28.0), (6.0, 37.6), 3.0), "z", 0.9, 4.5, 0.8)
    lug_front -= extrude(stadium((-2.5, 33.0), (2.5, 33.0), 1.5, SEG_SMALL), "z", -1.0, 8.0)

    # Cheeks sit 6 mm outside the upper arm's width ([-12.2, 16.8] cm here),
    # so the arm can swing between them over the whole shoulder range.
    shoulder: Vec2 = (0.0, 35.0)  # (y, z) of joint_2
    cheek_outline = CrossSection.batch_hull(
        [rounded_rect((-24.0, 5.0), (24.0, 11.0), 2.0), circle(shoulder, 22.7, SEG_FINE)]
    )
    cheek_holes = Manifold.batch_boolean(
        [
            extrude(circle(shoulder, 3.0, SEG), "x", -45.0, 45.0),
            extrude(stadium((-12.0, 17.0), (12.0, 17.0), 4.0), "x", -45.0, 45.0),
            extrude(circle((0.0, 50.0), 3.5, SEG), "x", -45.0, 45.0),
        ],
        UNION,
    )
    left_cheek = rounded_slab(cheek_outline, "x", -16.4, -12.8, 1.0) - cheek_holes
    right_cheek = rounded_slab(cheek_outline, "x", 17.4, 21.0, 1.0) - cheek_holes
    bearing = turned("x", shoulder, 3.0, 7.0, 20.5, 24.0, fillet=0.8, segments=SEG_FINE)

    # Shoulder servo on the outside of the left cheek, output on the axis.
    servo = rounded_box((-37.0, -10.0, 25.0), (-16.0, 10.0, 45.0), 1.2)
    ears = rounded_box((-21.0, -14.0, 27.0), (-18.0, 14.0, 43.0), 0.8)
    plug = turned("x", (0.0, 29.0), 0.0, 2.5, -39.0, -36.5, fillet=0.5, segments=SEG_SMALL)
    return Manifold.batch_boolean(
        [disc, lug_back, lug_front, left_cheek, right_cheek, bearing, servo, ears, plug], UNION
    )


def forward_drive_arm() -> Manifold:
    """Upper arm: twin side plates from shoulder hub to elbow, braced at the back.

    The plates' inner faces stay 6 mm outside the forearm's width
    (x in [-3, 5] cm), because the forearm folds through the upper arm's
    whole length over the elbow range; the only cross brace lies behind
    (y < -6.6 cm) and farther than 47 cm from the elbow, outside the
    forearm's swept volume.
    """
    # (y, z) outline: shoulder end off-centre towards -y (the envelope is
    # 9.1 cm behind the axis but 5.9 in front), a straight back edge down the
    # lower half for the brace, a round end about the elbow.
    outline = CrossSection.batch_hull(
        [
            circle((-1.6, -0.4), 7.5, SEG_FINE),
            circle((0.0, 80.0), 4.5, SEG_FINE),
            circle((-7.1, 35.0), 2.0),
        ]
    )
    holes = Manifold.batch_boolean(
        [
            extrude(circle((-1.6, 14.0), 3.2), "x", -20.0, 20.0),
            extrude(stadium((-1.6, 24.0), (-1.6, 38.0), 2.8), "x", -20.0, 20.0),
            extrude(stadium((-1.0, 47.0), (-0.4, 64.0), 2.2), "x", -20.0, 20.0),
            extrude(circle((0.0, 0.0), 1.5, SEG_SMALL), "x", -20.0, 20.0),
            extrude(circle((0.0, 80.0), 1.2, SEG_SMALL), "x", -20.0, 20.0),
        ],
        UNION,
    )
    left_plate = rounded_slab(outline, "x", -6.8, -3.6, 0.8)
    right_plate = rounded_slab(outline, "x", 5.6, 8.8, 0.8)
    web = rounded_box((-6.0, -9.1, 4.0), (8.0, -6.6, 33.0), 0.6)
    shoulder_left = turned("x", (0.0, 0.0), 0.0, 4.0, -10.2, -6.4, fillet=0.6, segments=SEG_FINE)
    shoulder_right = turned("x", (0.0, 0.0), 0.0, 4.0, 8.4, 12.0, fillet=0.6, segments=SEG_FINE)
    elbow_left = turned("x", (0.0, 80.0), 0.0, 3.5, -9.0, -6.4, fillet=0.5, segments=SEG_FINE)
    # Elbow servo on the outer face of the right plate.
    servo = rounded_box((8.4, -5.0, 66.0), (18.8, 5.0, 84.0), 1.0)
    ears = rounded_box((8.4, -5.6, 64.0), (12.0, 5.6, 68.5), 0.6)
    parts = [left_plate, right_plate, web, shoulder_left, shoulder_right, elbow_left, servo, ears]
    return Manifold.batch_boolean(parts, UNION) - holes


def horizontal_arm() -> Manifold:
    """Forearm: elbow hub, long slender beam to the wrist, rear counterweight.

    The beam keeps x >= 0.5 cm so the gripper bracket (x <= -0.1 cm) can
    hang beside its tip with clearance.
    """
    hub = turned("x", (0.0, 0.0), 0.0, 5.9, -3.0, 5.0, fillet=0.8, segments=SEG_FINE)
    outline = CrossSection.batch_hull(
        [circle((-33.0, 0.0), 3.0), circle((0.0, 0.0), 4.5, SEG_FINE), circle((84.6, 0.0), 3.0)]
    )
    beam = rounded_slab(outline, "x", 0.5, 4.5, 0.7)
    slots = Manifold.batch_boolean(
        [
            extrude(stadium((10.0, 0.0), (34.0, 0.0), 1.6), "x", -10.0, 10.0),
            extrude(stadium((42.0, 0.0), (66.0, 0.0), 1.4), "x", -10.0, 10.0),
            extrude(stadium((-26.0, 0.0), (-11.0, 0.0), 1.4), "x", -10.0, 10.0),
            extrude(circle((0.0, 0.0), 1.5, SEG_SMALL), "x", -10.0, 10.0),
            extrude(circle((80.0, 0.0), 0.7, SEG_SMALL), "x", -10.0, 10.0),
            extrude(circle((85.0, 0.0), 0.7, SEG_SMALL), "x", -10.0, 10.0),
        ],
        UNION,
    )
    counterweight = rounded_box((-2.0, -39.9, -4.5), (4.0, -29.0, 9.1), 1.0)
    return Manifold.batch_boolean([hub, beam, counterweight], UNION) - slots


def claw_support() -> Manifold:
    """Gripper bracket: mounting plate beside the wrist, palm with finger pivots, servo.

    Everything except the servo stays 5 mm above the fingers (z > -10.5 cm);
    the servo hangs behind the fingers' swept discs (y < 3.5 cm, the
    fingers' tails reach down to y = 4.6 cm).
    """
    right_pivot: Vec2 = (-4.0, 13.0)
    left_pivot: Vec2 = (-22.0, 13.0)
    palm_outline = CrossSection.batch_hull(
        [
            circle(left_pivot, 3.1, SEG_FINE),
            circle(right_pivot, 3.1, SEG_FINE),
            rounded_rect((-23.0, -4.6), (-0.5, 3.0), 1.0),
        ]
    )
    palm = rounded_slab(palm_outline, "z", -10.5, -8.0, 0.6)
    tongue = rounded_slab(stadium((-13.0, 13.0), (-13.0, 47.1), 2.0), "z", -10.3, -8.4, 0.5)
    pivots = (left_pivot, right_pivot)
    bosses = [turned("z", p, 0.0, 2.4, -8.3, -6.0, fillet=0.4, segments=SEG) for p in pivots]
    pins = Manifold.batch_boolean(
        [extrude(circle(p, 0.8, SEG_SMALL), "z", -12.0, -5.0) for p in pivots], UNION
    )
    mount_outline = CrossSection.batch_hull(
        [rect((-4.9, -10.2), (7.0, 17.45)), circle((1.05, 17.45), 5.95, SEG_FINE)]
    )
    mount = rounded_slab(mount_outline, "x", -3.0, -0.1, 0.5)
    mount_holes = Manifold.batch_boolean(
        [
            extrude(circle((1.05, 16.0), 3.0), "x", -10.0, 10.0),
            extrude(circle((-1.5, 0.0), 0.6, SEG_SMALL), "x", -10.0, 10.0),
            extrude(circle((4.5, 0.0), 0.6, SEG_SMALL), "x", -10.0, 10.0),
        ],
        UNION,
    )
    gusset = rounded_box((-6.0, -4.4, -8.5), (-2.5, 2.5, 2.0), 0.5)
    servo = rounded_box((-19.0, -4.7, -14.9), (-7.0, 3.5, 4.0), 0.8)
    ears = rounded_box((-21.5, -4.0, -8.3), (-4.5, 2.6, -6.8), 0.4)
    spline = turned("z", (-10.0, -0.7), 0.0, 1.2, 3.7, 5.5, fillet=0.3, segments=SEG_SMALL)
    parts = [palm, tongue, *bosses, mount, gusset, servo, ears, spline]
    body = Manifold.batch_boolean(parts, UNION)
    return body - pins - mount_holes


def finger(side: float) -> Manifold:
    """A gripper finger about its pivot at the link origin.

    ``side`` is -1 for the right finger (jaw points to -x, jaw low) and +1
    for the left (jaw to +x, jaw high).  The low and high layers are 6 mm
    apart, so the crossing jaws of the closed gripper never touch.  Each
    tail lies in its jaw's layer too: the tails swing towards each other as
    the gripper opens and pass one above the other.
    """
    hub_r = 4.0 if side < 0 else 3.9
    reach = 10.0 if side < 0 else 10.6
    # Layer (bottom, top) in link z; the hub spans the full -10..-1.  The
    # sub-parts are staggered by a few mm so no two faces are coplanar,
    # which would leave sliver triangles after the booleans.
    pad_z = (-9.7, -5.8) if side < 0 else (-5.2, -1.3)
    bend_z = (pad_z[0] + 0.2, pad_z[1] - 0.2)
    tail_z = (pad_z[0] + 0.1, pad_z[1] - 0.1)

    def sx(x: float) -> float:
        return side * x

    hub = turned("z", (0.0, 0.0), 0.0, hub_r, -10.0, -1.0, fillet=0.6, segments=SEG_FINE)
    tail = rounded_slab(stadium((0.0, 0.0), (0.0, -6.4), 2.0), "z", *tail_z, 0.5)
    prong = rounded_slab(stadium((0.0, 2.0), (sx(0.4), 40.0), 1.6), "z", -9.8, -1.2, 0.5)
    bend = rounded_slab(stadium((sx(0.4), 40.0), (sx(reach - 3.5), 46.0), 1.6), "z", *bend_z, 0.5)
    pad_lo, pad_hi = sorted((sx(reach - 4.5), sx(reach)))
    pad = rounded_slab(rounded_rect((pad_lo, 43.5), (pad_hi, 50.0), 1.0), "z", *pad_z, 0.4)
    # Grip ridges: shallow grooves across the jaw face.
    grooves = Manifold.batch_boolean(
        [
            extrude(circle((sx(reach + 0.35), y), 0.6, SEG_SMALL), "z", -12.0, 1.0)
            for y in (45.0, 46.6, 48.2)
        ],
        UNION,
    )
    pin_hole = extrude(circle((0.0, 0.0), 1.0, SEG_SMALL), "z", -12.0, 1.0)
    return Manifold.batch_boolean([hub, tail, prong, bend, pad], UNION) - grooves - pin_hole


PARTS: dict[str, Callable[[], Manifold]] = {
    "basement.STL": basement,
    "base_plate.STL": base_plate,
    "forward_drive_arm.STL": forward_drive_arm,
    "horizontal_arm.STL": horizontal_arm,
    "claw_support.STL": claw_support,
    "right_finger.STL": lambda: finger(-1.0),
    "left_finger.STL": lambda: finger(1.0),
}


# -------------------------------------------------------------- file frame


def origin_rotation(rpy_quarters: Sequence[float]) -> np.ndarray:
    """Exact rotation for an rpy given in quarter turns (URDF fixed-axis xyz)."""
    r, p, y = (q * 0.5 * math.pi for q in rpy_quarters)
    rot = trimesh.transformations.euler_matrix(r, p, y, "sxyz")[:3, :3]
    return np.round(rot)


def link_to_file(vertices_cm: np.ndarray, name: str) -> np.ndarray:
    # link = R * (0.01 * file) + t  =>  file = R^T (link_cm - 100 t)
    xyz, rpy = ORIGINS[name]
    rot = origin_rotation(rpy)
    return (vertices_cm - 100.0 * np.asarray(xyz)) @ rot


def to_trimesh(solid: Manifold, name: str) -> trimesh.Trimesh:
    mesh = solid.to_mesh64()
    vertices = link_to_file(np.asarray(mesh.vert_properties)[:, :3], name)
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    # Round-trip through float32 now so the returned mesh equals the file.
    vertices = vertices.astype(np.float32).astype(np.float64)
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=True)


def build(name: str) -> trimesh.Trimesh:
    return to_trimesh(PARTS[name](), name)


def generate(out_dir: Path = MESH_DIR) -> dict[str, trimesh.Trimesh]:
    """Build all seven meshes, write them as binary STL into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    meshes: dict[str, trimesh.Trimesh] = {}
    for name in PARTS:
        mesh = build(name)
        (out_dir / name).write_bytes(trimesh.exchange.stl.export_stl(mesh))
        meshes[name] = mesh
    return meshes


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    out_dir = Path(args[0]) if args else MESH_DIR
    for name, mesh in generate(out_dir).items():
        lo, hi = mesh.bounds
        low = " ".join(f"{v:.2f}" for v in lo)
        high = " ".join(f"{v:.2f}" for v in hi)
        print(
            f"{name:24s} {len(mesh.faces):6d} tris  [{low}] -> [{high}] cm  "
            f"watertight={mesh.is_watertight}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
