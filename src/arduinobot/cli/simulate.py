"""``arduinobot plan --simulate``: replay the plan on the twin of the robot it was planned
for: the model options' with --local, the service's own (its ``<prefix>/description``)
otherwise. The replay itself is :func:`arduinobot.execution.simulate.simulate`."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import Any

from arduinobot.cli.common import load_from_args
from arduinobot.cli.remote_model import disk_cache, model_of_service, progress_printer
from arduinobot.client.replies import PlanReply
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.execution.simulate import plot, simulate, summary


def simulate_command(ns: argparse.Namespace, res: PlanReply, req: Mapping[str, Any],
                     robot: Mapping[str, Any]) -> int:
    """``plan --simulate`` of the plan ``res`` (of request ``req``): on the model options'
    twin with --local, else on the robot the service serves (``robot``, its
    ``<prefix>/description`` reply).

    Raises:
        TrajectoryMismatch: the plan does not fit the model it is replayed on.
    """
    desc = load_from_args(ns) if ns.local else model_of_service(robot)
    r = simulate(desc, SampledTrajectory.of(res), obstacles=req.get("obstacles", ()),
                 cache=disk_cache(), progress=progress_printer(),
                 ground=bool(req.get("ground", True)))
    print(summary(r))
    if ns.plot:
        plot(r, ns.plot)
    return 0
