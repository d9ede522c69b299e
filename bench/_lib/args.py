"""The command line of the benchmarks that take only a problem count."""

from __future__ import annotations

import argparse


def problems_per_scene(doc: str, default: int, argv: list[str] | None = None) -> int:
    """``[N]`` from the command line (``--help`` prints ``doc``): problems per scene."""
    ap = argparse.ArgumentParser(description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("n", type=int, nargs="?", default=default,
                    help=f"problems per scene (default {default})")
    n = ap.parse_args(argv).n
    if n < 1:
        ap.error(f"N must be >= 1, not {n}")
    return n
