"""Model checks: what ``check_urdf`` checks, simulation readiness, and plausibility.

Each check yields :class:`Finding` objects at level PASS, WARN or FAIL; a model with
any FAIL is not ready for planning or simulation.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from arduinobot.description.config_yaml import apply_position_limits, read_joint_limits
from arduinobot.description.errors import DescriptionError
from arduinobot.description.geometry import MeshFile
from arduinobot.description.loader import model_path, read_model
from arduinobot.description.meshes import load_mesh
from arduinobot.description.model import Inertial, Link, Robot
from arduinobot.description.moveit_config import resolve_config
from arduinobot.description.packages import (
    SHIPPED_PACKAGE_DIR,
    PackageIndex,
    build_package_index,
    find_package_root,
)
from arduinobot.description.srdf import parse_srdf
from arduinobot.description.urdf import parse_urdf

_log = logging.getLogger(__name__)

Level = Literal["PASS", "WARN", "FAIL"]

# An inertia more than this many times the one the mesh implies at the link's mass
# is not a modelling choice but a placeholder (the seed's unit tensor on a 10 g finger).
PLAUSIBLE_INERTIA_RATIO = 10.0


@dataclass(frozen=True)
class Finding:
    """One check's verdict on one subject (or on all of them, for a PASS)."""

    level: Level
    check: str
    subject: str
    message: str
    details: Mapping[str, object] = field(default_factory=dict)

    def line(self) -> str:
        return f"{self.level}  {self.check:<18} {self.subject}: {self.message}"

    def to_json(self) -> dict[str, object]:
        return {"level": self.level, "check": self.check, "subject": self.subject,
                "message": self.message, "details": dict(self.details)}


@dataclass(frozen=True)
class CheckReport:
    source: str
    findings: tuple[Finding, ...]

    @property
    def failed(self) -> bool:
        return any(f.level == "FAIL" for f in self.findings)

    def count(self, level: Level) -> int:
        return sum(f.level == level for f in self.findings)

    def to_json(self) -> dict[str, object]:
        return {"source": self.source, "ok": not self.failed,
                "counts": {lvl: self.count(lvl) for lvl in ("PASS", "WARN", "FAIL")},
                "findings": [f.to_json() for f in self.findings]}


def _fail_from(e: DescriptionError, check: str) -> Finding:
    return Finding("FAIL", check, e.element or (Path(e.file).name if e.file else "model"),
                   e.message + (f" (fix: {e.hint})" if e.hint else ""),
                   {"file": e.file} if e.file else {})


def check_model(
    path: str | Path | None = None,
    *,
    package_dirs: Sequence[str | Path] = (),
    args: Mapping[str, str] | None = None,
    moveit_config: str | Path | None = None,
    srdf: str | Path | None = None,
    joint_limits: str | Path | None = None,
    env: Mapping[str, str] | None = None,
) -> CheckReport:
    """Check a URDF or xacro file (default: the shipped arduinobot) and the planning
    configuration found for it (see :func:`description.load_description`); never raises
    for a problem in the model, it reports it.

    Only what breaks loading, planning or simulation FAILs; what CAD exports and the
    MoveIt Setup Assistant normally leave (open meshes, a stale SRDF) WARNs."""
    packages = build_package_index(package_dirs, env=env, model=model_path(path))
    try:
        text, p, expansion_warnings = read_model(path, args=args, packages=packages)
        report = parse_urdf(text, packages=packages, source=p, strict=False)
    except DescriptionError as e:
        return CheckReport(str(path or "shipped model"), (_fail_from(e, "load"),))
    findings = [Finding("WARN", "packages", p.name, w) for w in packages.warnings]
    findings.extend(Finding("WARN", "xacro.args" if w.startswith("--arg") else "xacro", p.name,
                            w) for w in expansion_warnings)
    findings.extend(_fail_from(e, "parse") for e in report.problems)
    findings.extend(Finding("WARN", "parse", e.element or "model",
                            e.message + (f" (fix: {e.hint})" if e.hint else ""))
                    for e in report.warnings)
    robot = report.robot
    if robot is None:
        return CheckReport(str(p), tuple(findings))
    findings.append(Finding("PASS", "structure", robot.name,
                            f"one root '{robot.root}', a tree of {len(robot.links)} links and "
                            f"{len(robot.joints)} joints, every name resolves"))
    findings.extend(_check_links(robot))
    shipped = find_package_root(p.parent) == SHIPPED_PACKAGE_DIR
    findings.extend(_check_inertials(robot, shipped=shipped))
    findings.extend(_check_meshes(robot))
    findings.extend(_check_joints(robot))
    findings.extend(_check_config(robot, p, packages, moveit_config=moveit_config, srdf=srdf,
                                  joint_limits=joint_limits))
    return CheckReport(str(p), tuple(findings))


def _summarise(check: str, subjects: list[str], bad: list[Finding], what: str) -> Iterator[Finding]:
    yield from bad
    ok = len(subjects) - len({f.subject for f in bad if f.level == "FAIL"})
    if ok:
        yield Finding("PASS", check, f"{ok} of {len(subjects)}", what)


def _check_links(robot: Robot) -> Iterator[Finding]:
    bad: list[Finding] = []
    frames = robot.frame_links
    links = [link for name, link in robot.links.items()
             if name != robot.root and name not in frames]
    if frames:
        # a frame on a fixed joint is merged into its parent by simulators and planners
        yield Finding("PASS", "link.frames", ", ".join(frames),
                      "massless frame(s) on a fixed joint: merged into the parent link, "
                      "no visual, collision or inertia needed", {"frames": list(frames)})
    for link in links:
        missing = [tag for tag, have in (("visual", link.visuals), ("collision", link.collisions),
                                         ("inertial", link.inertial)) if not have]
        if missing:
            bad.append(Finding("FAIL", "link.elements", link.name,
                               f"has no <{'>, <'.join(missing)}>; a simulator needs all three",
                               {"missing": missing}))
    yield from _summarise("link.elements", [x.name for x in links], bad,
                          "every link but the root has visual, collision and inertial")


def _principal(inertial: Inertial) -> np.ndarray:
    return np.linalg.eigvalsh(inertial.tensor())


def _check_inertials(robot: Robot, *, shipped: bool = False) -> Iterator[Finding]:
    bad: list[Finding] = []
    frames = robot.frame_links
    with_inertial = [x for x in robot.links.values()
                     if x.inertial is not None and x.name not in frames]
    for link in with_inertial:
        ine = link.inertial
        if ine is None:
            continue
        if not ine.mass > 0:
            bad.append(Finding("FAIL", "inertial.mass", link.name, f"mass {ine.mass} must be > 0"))
        ev = _principal(ine)
        if not ev.min() > 0:
            bad.append(Finding("FAIL", "inertial.inertia", link.name,
                               f"inertia is not positive definite (principal moments "
                               f"{np.round(ev, 9).tolist()})"))
        else:
            a, b, c = np.sort(ev)
            if a + b < c * (1 - 1e-9):
                bad.append(Finding("FAIL", "inertial.inertia", link.name,
                                   f"principal moments {np.round(ev, 9).tolist()} break the "
                                   "triangle inequality (no real body has them)"))
        bad.extend(_plausibility(link, shipped=shipped))
    yield from _summarise("inertial", [x.name for x in with_inertial], bad,
                          "mass > 0, inertia positive definite and physically realisable")


def mesh_inertia(link: Link, mass: float) -> tuple[np.ndarray, bool] | None:
    """The inertia tensor [kg m^2] about the centre of mass that the link's collision
    meshes imply at ``mass`` and uniform density, in the link frame, and whether it is
    reliable: an open (not watertight) CAD mesh has no volume, so its convex hull stands
    in and the figure is only indicative. None if the meshes cannot say."""
    from arduinobot.description.meshes import concatenate, shape_mesh
    try:
        parts = [shape_mesh(s) for s in link.collisions]
    except DescriptionError:
        return None
    if not parts:
        return None
    mesh = concatenate(parts)
    reliable = bool(mesh.is_volume and mesh.volume > 0)
    if not reliable:
        try:
            mesh = mesh.convex_hull
        except Exception:  # noqa: BLE001 -- qhull refuses degenerate input: no figure
            _log.debug("no convex hull for %s", link.name, exc_info=True)
            return None
        if not mesh.volume > 0:
            return None
    mesh.density = mass / mesh.volume
    return np.asarray(mesh.moment_inertia), reliable


# Why the shipped model keeps inertias the plausibility check flags: said where the WARN
# appears, so a user does not take it for a fault of their install.
SHIPPED_INERTIA_NOTE = (
    "expected: the shipped model keeps the course's unit-tensor default_inertial so its "
    "figures follow the course; use figures like these for simulation")


def _plausibility(link: Link, *, shipped: bool = False) -> Iterator[Finding]:
    ine = link.inertial
    if ine is None or not ine.mass > 0:
        return
    got = mesh_inertia(link, ine.mass)
    if got is None:
        return
    implied, reliable = got
    given, expected = _principal(ine).max(), np.linalg.eigvalsh(implied).max()
    if expected > 0 and given > PLAUSIBLE_INERTIA_RATIO * expected:
        t = np.round(implied, 8)
        src = "the mesh implies" if reliable else \
            "the convex hull of the open mesh implies (unreliable: the mesh has no volume)"
        yield Finding(
            "WARN", "inertial.plausible", link.name,
            f"inertia {given:g} kg m^2 is {given / expected:,.0f}x what {src} for "
            f"{ine.mass:g} kg: ixx={t[0, 0]:.3g} ixy={t[0, 1]:.3g} "
            f"ixz={t[0, 2]:.3g} iyy={t[1, 1]:.3g} iyz={t[1, 2]:.3g} izz={t[2, 2]:.3g}"
            + (f" ({SHIPPED_INERTIA_NOTE})" if shipped else ""),
            {"given_max": float(given), "implied": t.tolist(), "ratio": float(given / expected),
             "reliable": reliable, "shipped_placeholder": shipped})


def _check_meshes(robot: Robot) -> Iterator[Finding]:
    bad: list[Finding] = []
    subjects = []
    # the robot's size from its kinematics, to spot meshes in the wrong unit
    span = float(sum(np.linalg.norm(j.origin.xyz) for j in robot.joints.values()))
    for link in robot.links.values():
        for tag, shapes in (("visual", link.visuals), ("collision", link.collisions)):
            for i, s in enumerate(shapes):
                g = s.geometry
                if not isinstance(g, MeshFile):  # the check of mesh files
                    continue
                subj = f"{link.name} {tag}#{i + 1}"
                subjects.append(subj)
                if g.path is None:
                    bad.append(Finding("FAIL", "mesh", subj, f"'{g.uri}' did not resolve"))
                    continue
                try:
                    mesh = load_mesh(g.path, g.scale)
                except DescriptionError as e:
                    bad.append(Finding("FAIL", "mesh", subj, e.message))
                    continue
                if not mesh.is_watertight:
                    # CAD exports often are; FCL, MuJoCo and Gazebo use them as they are
                    bad.append(Finding("WARN", "mesh", subj,
                                       f"{g.path.name} is not watertight (open edges): fine "
                                       "for collision checking, but an inertia derived from "
                                       "it is unreliable", {"watertight": False}))
                size = float(np.max(mesh.extents))
                factor = _scale_factor(size, span)
                if factor is not None:
                    bad.append(Finding(
                        "WARN", "mesh.scale", subj,
                        f"{g.path.name} is {size:.4g} m across at scale {_fmt(g.scale)} on a "
                        f"robot whose joints span {span:.3g} m: likely in the wrong unit; try "
                        f"scale=\"{_fmt(tuple(x * factor for x in g.scale))}\" "
                        f"(x{factor:g})", {"extent": size, "factor": factor}))
    folders = sorted({str(src.parent) for link in robot.links.values()
                      for s in (*link.visuals, *link.collisions)
                      if (src := s.geometry.source) is not None})
    yield from _summarise("mesh", subjects, bad, "every mesh resolves and loads"
                          + (f", from {', '.join(folders)}" if folders else ""))


def _fmt(scale: tuple[float, ...]) -> str:
    return " ".join(f"{x:g}" for x in scale)


def _scale_factor(size: float, span: float) -> float | None:
    """The power of ten that brings a mesh ``size`` [m] across to the scale of a robot
    whose joints span ``span`` [m], if it is off by 100x or more (the missing
    ``scale="0.001 0.001 0.001"`` of a millimetre CAD export is 1000x)."""
    if span <= 0 or size <= 0:
        return None
    ratio = size / span
    if 0.01 < ratio < 100:
        return None
    return float(10.0 ** -round(np.log10(ratio)))


def _check_joints(robot: Robot) -> Iterator[Finding]:
    bad: list[Finding] = []
    movable = [j for j in robot.joints.values() if j.movable]
    for j in movable:
        lim = j.limit
        if lim is None:
            continue
        if j.type in ("revolute", "prismatic") and not (
                lim.lower is not None and lim.upper is not None and lim.lower < lim.upper):
            bad.append(Finding("FAIL", "joint.limits", j.name,
                               f"lower {lim.lower} must be < upper {lim.upper}"))
        if not lim.effort > 0:
            bad.append(Finding("FAIL", "joint.limits", j.name, f"effort {lim.effort} must be > 0"))
        if not lim.velocity > 0:
            bad.append(Finding("FAIL", "joint.limits", j.name,
                               f"velocity {lim.velocity} must be > 0"))
    yield from _summarise("joint.limits", [j.name for j in movable], bad,
                          "lower < upper, effort > 0, velocity > 0, axes non-zero")
    mimics = [j for j in robot.joints.values() if j.mimic is not None]
    if mimics:
        yield Finding("PASS", "joint.mimic", ", ".join(j.name for j in mimics),
                      "; ".join(f"{j.name} = {j.mimic.multiplier:g} * {j.mimic.joint}"
                                f" + {j.mimic.offset:g}" for j in mimics if j.mimic))


def _check_config(robot: Robot, path: Path, packages: PackageIndex, *,
                  moveit_config: str | Path | None, srdf: str | Path | None,
                  joint_limits: str | Path | None) -> Iterator[Finding]:
    try:
        files = resolve_config(robot.name, description_root=find_package_root(path.parent),
                               packages=packages, model_folder=path.parent,
                               moveit_config=moveit_config, srdf=srdf,
                               joint_limits=joint_limits)
    except DescriptionError as e:
        yield _fail_from(e, "config")
        return
    yield Finding("PASS" if files.srdf else "WARN", "config", "files",
                  "; ".join(x.strip() for x in files.lines()), files.to_json())
    if files.joint_limits is not None:
        try:
            limits, _ = read_joint_limits(files.joint_limits, robot)
            _, ignored = apply_position_limits(robot, limits, files.joint_limits)
        except DescriptionError as e:
            yield _fail_from(e, "joint_limits")
        else:
            for w in ignored:
                yield Finding("WARN", "joint_limits", files.joint_limits.name, w)
    if files.srdf is None:
        return
    try:
        parsed = parse_srdf(files.srdf.read_text(encoding="utf-8"), robot, source=files.srdf)
    except DescriptionError as e:
        yield _fail_from(e, "srdf")
        return
    for w in parsed.warnings:
        yield Finding("WARN", "srdf", files.srdf.name, w)
    yield Finding("PASS", "srdf", files.srdf.name,
                  f"groups {', '.join(parsed.groups)}; named states "
                  f"{', '.join(f'{s.group}/{s.name}' for s in parsed.states)}; "
                  f"{len(parsed.disabled_collisions)} disabled collision pairs")
