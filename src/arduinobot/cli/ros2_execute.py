"""`arduinobot execute --ros2`: a plan sent to the user's joint_trajectory_controllers
(control_msgs/action/FollowJointTrajectory, or JointTrajectory on a topic), one per
group, named by the MoveIt config's moveit_controllers.yaml (see docs/ros2.md)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
from typing import TYPE_CHECKING, Any

from arduinobot.cli.argtypes import UsageError
from arduinobot.cli.common import EXIT_CANCELLED, EXIT_FAIL, EXIT_OK, client, connect, sigint_sets
from arduinobot.cli.ros2_options import Ros2Settings

if TYPE_CHECKING:
    from arduinobot.description import Description
    from arduinobot.execution.robots.base import RobotError
    from arduinobot.ros2.controllers import Controller

log = logging.getLogger(__name__)

def controllers_of(desc: Description, names: list[str] | None) -> tuple[Controller, ...]:
    """The controllers to send to: the MoveIt config's ``moveit_controllers.yaml``
    (the package's ``config/``, beside the SRDF), else ``<group>_controller`` per SRDF
    group (its actuated, non-mimic joints; a group whose joints an earlier one has is
    skipped); ``names`` (--controller) keeps those, and a name neither knows is a
    controller of every joint the others leave.

    Raises:
        UsageError: a --controller name unknown while every joint already has one.
    """
    from arduinobot.ros2.controllers import Controller, read_moveit_controllers
    cfg = desc.config
    dirs = [d for d in ((cfg.moveit_package / "config") if cfg.moveit_package else None,
                        cfg.srdf.parent if cfg.srdf else None) if d is not None]
    found = next((d / "moveit_controllers.yaml" for d in dirs
                  if (d / "moveit_controllers.yaml").is_file()), None)
    if found is not None:
        known = read_moveit_controllers(found)
        log.info("controllers from %s: %s", found, ", ".join(c.name for c in known))
    else:
        taken: set[str] = set()
        out = []
        actuated = set(desc.robot.actuated_joints)
        for g in (desc.srdf.groups.values() if desc.srdf else ()):
            joints = tuple(j for j in g.joints if j in actuated and j not in taken)
            if joints:
                out.append(Controller(f"{g.name}_controller", joints))
                taken.update(joints)
        known = tuple(out)
        log.info("no moveit_controllers.yaml: controllers after the SRDF groups: %s",
                 ", ".join(c.name for c in known) or "none")
    if not names:
        return known
    by_name = {c.name: c for c in known}
    chosen = [by_name[n] for n in names if n in by_name]
    unknown = [n for n in names if n not in by_name]
    if len(unknown) > 1:
        raise UsageError(f"controllers {', '.join(unknown)} are not in the MoveIt config "
                         f"(it has {', '.join(by_name) or 'none'}); at most one unknown "
                         "--controller takes the remaining joints")
    if unknown:
        rest = tuple(j for j in desc.robot.actuated_joints
                     if not any(j in c.joints for c in chosen))
        if not rest:
            raise UsageError(f"controller {unknown[0]} is not in the MoveIt config and "
                             "the others already move every joint")
        chosen.append(Controller(unknown[0], rest))
    return tuple(chosen)


def execute_on_controllers(ns: argparse.Namespace, req: dict[str, Any] | None,
                           settings: Ros2Settings, desc: Description) -> int:
    """Send the trajectory (TRAJ.json, or planned from the controllers' /joint_states)
    to the joint_trajectory_controllers; Ctrl-C cancels (they stop and hold)."""
    from arduinobot.execution.executor import NotAtStart
    from arduinobot.execution.segments import (
        SampledTrajectory,
        check_fits,
        parse_trajectory,
        read_json,
    )
    from arduinobot.ros2 import Ros2Error
    from arduinobot.ros2.controllers import split_trajectory
    from arduinobot.ros2.trajectory_target import TargetOptions, TrajectoryTarget

    controllers = controllers_of(desc, ns.controller)
    try:
        with client(ns) as c:  # the router's session: the service plans on it too
            target = TrajectoryTarget(c.session, domain_id=settings.domain_id,
                                      namespace=settings.namespace,
                                      attachment=settings.attachment,
                                      options=TargetOptions(control_msgs=ns.control_msgs))
            try:
                now = target.joint_positions(timeout=3.0)
                if req is not None:
                    if "start" not in req:
                        req["start"] = _start_from(now, desc)
                    with connect(ns, model_drives_robot=True) as service:
                        body: Any = service.request("plan", req)
                else:
                    body = read_json(ns.trajectory)
                names, times, cols = parse_trajectory(body)
                traj = SampledTrajectory.from_json(body)
                check_fits(traj, desc)
                _check_ros2_start(traj, now, ns.start_tolerance, NotAtStart)
                parts = split_trajectory(names, times, cols, controllers)
                where = ", ".join(f"{p.controller.name} ({', '.join(p.joint_names)})"
                                  for p in parts)
                print(f"executing {traj.duration:.3f} s on {where} (ROS 2 domain "
                      f"{settings.domain_id}; Ctrl-C stops)", file=sys.stderr)
                cancel = threading.Event()
                with sigint_sets(cancel):
                    if ns.ros2_topic:
                        done = target.publish(parts, cancel=cancel)
                        print("published on " + ", ".join(
                            "/" + p.controller.topic for p in parts)
                            + ("" if done else "; cancelled: an empty trajectory sent "
                               "(the controllers hold)"))
                        return EXIT_OK if done else EXIT_CANCELLED
                    outcomes = target.follow(parts, cancel=cancel)
            finally:
                target.close()
    except Ros2Error as e:
        print(f"arduinobot: {e.code}: {e.message}", file=sys.stderr)
        if e.details:
            print(f"  details: {json.dumps(e.details, default=str)[:2000]}", file=sys.stderr)
        return EXIT_FAIL
    for o in outcomes:
        print(f"{o.controller}: {o.outcome}" + (f" ({o.error_string})" if o.error_string
                                                 else ""))
    return EXIT_OK if all(o.outcome == "succeeded" for o in outcomes) else EXIT_CANCELLED


def _start_from(now: dict[str, float] | None, desc: Description) -> dict[str, float]:
    """A plan's start from the controllers' /joint_states (clipped to the limits, as
    :func:`arduinobot.execution.executor.plan_start`).

    Raises:
        UsageError: no /joint_states arrived, or it lacks a joint of the robot.
    """
    names = desc.robot.actuated_joints
    if now is None:
        raise UsageError("no /joint_states from the ROS 2 side (is joint_state_broadcaster "
                         "active?): cannot plan from the robot's state; give TRAJ.json or "
                         "a request with a start")
    missing = [n for n in names if n not in now]
    if missing:
        raise UsageError(f"/joint_states lacks {', '.join(missing)}: cannot plan from it")
    lim = desc.robot.position_limits(tuple(names))
    return {n: min(max(now[n], float(lo)), float(hi)) for n, (lo, hi) in zip(names, lim)}


def _check_ros2_start(traj: Any, now: dict[str, float] | None, tolerance: float,
                      not_at_start: type[RobotError]) -> None:
    """Refuse a trajectory that does not start where /joint_states says the arm is (a
    controller would jump there); without /joint_states the check is skipped, said."""
    if now is None:
        log.warning("no /joint_states from the ROS 2 side: the trajectory's start is not "
                    "checked against the arm")
        return
    for j, name in enumerate(traj.joint_names):
        if name in now and abs(now[name] - traj.positions[0][j]) > tolerance:
            raise not_at_start(
                f"the robot is not at the trajectory's start: {name} is at {now[name]:.4f} "
                f"rad (/joint_states), the trajectory starts at {traj.positions[0][j]:.4f} "
                f"rad (tolerance {tolerance:g} rad); plan from the robot's state",
                details={"joint": name, "robot": now[name],
                         "start": float(traj.positions[0][j]), "tolerance": tolerance})
