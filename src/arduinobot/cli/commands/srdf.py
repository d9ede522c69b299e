"""`arduinobot srdf`: recompute the SRDF's disabled collision pairs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from arduinobot.cli.common import EXIT_FAIL, EXIT_OK, add_model_args, load_from_args, wrote


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "srdf", help="recompute the SRDF's disabled collision pairs",
        description="Recompute <disable_collisions> as MoveIt's setup assistant does, "
        "with reasons: Adjacent (joined by a joint, or rigidly by fixed joints), Always "
        "(in every one of N seeded samples), Never-proven (a bound over the joint limits "
        "proves the pair cannot touch). Pairs that merely never touched in the samples "
        "stay checked; --sampled also writes them as Never-sampled for MoveIt (this "
        "service still checks them). Prints the pairs; --write updates the SRDF in "
        "place, --output writes elsewhere (for a model without an SRDF, a new one).",
        epilog="example:\n  arduinobot srdf ~/ws/src/arduinobot_description/urdf/"
        "arduinobot.urdf.xacro --package-dir ~/ws/src --output arduinobot.srdf")
    add_model_args(p)
    p.add_argument("--samples", type=int, default=2000, metavar="N",
                   help="random states to sample (default 2000)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="sampler seed")
    p.add_argument("--sampled", action="store_true",
                   help="also write pairs that never touched in the samples (Never-sampled)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help="rewrite the package's SRDF")
    g.add_argument("--output", metavar="PATH", help="write the updated SRDF to PATH")
    p.set_defaults(func=cmd_srdf)


def cmd_srdf(ns: argparse.Namespace) -> int:
    from arduinobot.description.srdf import replace_disabled_collisions, starter_srdf
    from arduinobot.planner.collision.acm_gen import (
        compute_acm,  # FCL, numba: only for this command
    )

    d = load_from_args(ns)
    src = d.srdf.source if d.srdf is not None else None
    if src is None and ns.write:
        print("arduinobot: srdf: the model has no SRDF to rewrite; use --output PATH to "
              "write a new one", file=sys.stderr)
        return EXIT_FAIL
    r = compute_acm(d, samples=ns.samples, seed=ns.seed, include_sampled=ns.sampled)
    for p in r.disabled:
        print(f"disable {p.link1} / {p.link2}: {p.reason}")
    for a, b in r.unproven:
        print(f"check   {a} / {b}: never collided in {r.samples} samples, but not proven "
              f"apart{' (written as Never-sampled)' if ns.sampled else ''}")
    for (a, b), n in r.collision_counts.items():
        if n:
            print(f"check   {a} / {b}: collided in {n} of {r.samples} samples")
    print(f"{len(r.disabled)} disabled pairs, {r.samples} samples (seed {ns.seed}), "
          f"{r.seconds:.2f} s")
    if ns.write or ns.output:
        # a new one has the groups, end effector and home state the service derives
        tool = d.tcp.parent_link if d.tcp is not None else d.robot.root
        base = Path(src).read_text(encoding="utf-8") if src is not None else \
            starter_srdf(d.robot, d.derived, tool)
        text = replace_disabled_collisions(base, r.disabled)
        dest = Path(src) if ns.write and src is not None else Path(ns.output)
        dest.write_text(text, encoding="utf-8")
        wrote(dest, f"{len(r.disabled)} disabled pairs")
    return EXIT_OK
