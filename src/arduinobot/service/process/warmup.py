"""``python -m arduinobot.service.process.warmup``: compile and cache every numerical kernel once, and the
shipped robot's collision geometry.

numba compiles the planner's kernels the first time they run and keeps them on disk;
``./dev setup`` runs this after installing, so a fresh machine's first ``arduinobot
serve`` loads them instead of spending ~30 s compiling. The shipped robot's trees, hulls
and part hulls go to the artifact cache ``serve`` reads by default (``DiskCache()``), so
its first start reads them too (~6 s to build).
"""

from __future__ import annotations

import sys
import time


def main() -> int:
    t0 = time.perf_counter()
    from arduinobot.description import load_description
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    from arduinobot.service.plan.handlers import Handlers
    from arduinobot.service.process.disk_cache import DiskCache
    set_ompl_log_level("none")
    Handlers(load_description(), cache=DiskCache()).warm_up()
    print(f"arduinobot: numerical kernels compiled and cached, and the shipped robot's "
          f"geometry, in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
