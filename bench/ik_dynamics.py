"""Speed of position IK (closed form and numeric fallback) and batched inverse dynamics.

Prints figures, then one line of JSON.  Usage: ./dev bench ik_dynamics
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from arduinobot.description import load_description
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.dynamics import InverseDynamics
from arduinobot.planner.kinematics.ik import position_ik
from bench._lib.report import emit


def per_call(fn, n: int) -> float:
    fn()  # warm-up (numba compile, caches)
    t = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t) / n


def main() -> None:
    d = load_description()
    kin, tcp = Kinematics(d.robot), d.tcp
    rng = np.random.default_rng(0)
    qs = np.c_[rng.uniform(-1.5, 1.5, (50, 3)), np.zeros(50)]
    targets = [kin.point_position(q, tcp.parent_link, tcp.xyz) for q in qs]
    it = iter(range(10**9))
    closed = per_call(lambda: position_ik(kin, tcp, targets[next(it) % 50]), 500)
    numeric = per_call(lambda: position_ik(kin, tcp, targets[next(it) % 50],
                                           joints=("joint_3", "joint_1", "joint_2")), 20)

    dyn = InverseDynamics(d.robot)
    m = 10_000
    q, qd, qdd = (rng.uniform(-1.5, 1.5, (m, 4)), rng.uniform(-3, 3, (m, 4)),
                  rng.uniform(-10, 10, (m, 4)))
    batch = per_call(lambda: dyn.torques_batch(q, qd, qdd), 20) / m
    single = per_call(lambda: dyn.torques(q[0], qd[0], qdd[0]), 2000)
    mass = per_call(lambda: dyn.mass_matrix(q[0]), 2000)

    figures = {"ik_closed_form_us": closed * 1e6, "ik_numeric_ms": numeric * 1e3,
               "rnea_batched_us_per_sample": batch * 1e6, "rnea_single_call_us": single * 1e6,
               "mass_matrix_us": mass * 1e6}
    print(f"position IK, closed form:      {closed * 1e6:8.1f} us/call")
    print(f"position IK, numeric fallback: {numeric * 1e3:8.1f} ms/call")
    print(f"RNEA batched:                  {batch * 1e6:8.3f} us/sample ({m} samples)")
    print(f"RNEA single call:              {single * 1e6:8.1f} us")
    print(f"mass matrix single call:       {mass * 1e6:8.1f} us")
    emit("ik_dynamics", figures)


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__).parse_args()  # --help, and no arguments
    main()
