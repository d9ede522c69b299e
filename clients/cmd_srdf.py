"""`arduinobot srdf`: recompute the SRDF's disabled collision pairs."""

from __future__ import annotations

import argparse
from pathlib import Path

from description.srdf import replace_disabled_collisions
from planner.acm_gen import compute_acm

from .common import EXIT_FAIL, EXIT_OK, add_model_args, load_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "srdf", help="recompute the SRDF's disabled collision pairs",
        description="Recompute <disable_collisions> as MoveIt's setup assistant does "
        "(Adjacent, Always in N seeded samples, Never), except that a pair is only "
        "'Never' when a bound over the joint limits proves it cannot touch; pairs that "
        "merely never touched in the samples stay checked. Prints the pairs with reasons; "
        "--write updates the package's SRDF in place, --output writes elsewhere.")
    add_model_args(p)
    p.add_argument("--samples", type=int, default=2000, metavar="N",
                   help="random states to sample (default 2000)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="sampler seed")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help="rewrite the package's SRDF")
    g.add_argument("--output", metavar="PATH", help="write the updated SRDF to PATH")
    p.set_defaults(func=cmd_srdf)


def cmd_srdf(ns: argparse.Namespace) -> int:
    d = load_from_args(ns)
    if d.srdf is None or d.srdf.source is None:
        print("arduinobot: the model has no SRDF to update")
        return EXIT_FAIL
    r = compute_acm(d, samples=ns.samples, seed=ns.seed)
    for p in r.disabled:
        print(f"disable {p.link1} / {p.link2}: {p.reason}")
    for a, b in r.unproven:
        print(f"check   {a} / {b}: never collided in {r.samples} samples, but not proven apart")
    for (a, b), n in r.collision_counts.items():
        if n:
            print(f"check   {a} / {b}: collided in {n} of {r.samples} samples")
    print(f"{len(r.disabled)} disabled pairs, {r.samples} samples (seed {ns.seed}), "
          f"{r.seconds:.2f} s")
    if ns.write or ns.output:
        src = Path(d.srdf.source)
        text = replace_disabled_collisions(src.read_text(encoding="utf-8"), r.disabled)
        dest = src if ns.write else Path(ns.output)
        dest.write_text(text, encoding="utf-8")
        print(f"wrote {dest}")
    return EXIT_OK
