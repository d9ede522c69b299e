"""The peer benchmark's printed report (bench/peer.py): per model and scene, ours
through the service against MPlib."""

from __future__ import annotations

from typing import Any

# [m] a certified clearance under this: the motion came within microns of some contact
NEAR = 1e-4
STAGES = ("validate", "plan", "simplify", "recheck", "parameterise", "verify", "total")


def fmt(x: float | None, spec: str = ".1f") -> str:
    return "-" if x is None else format(x, spec)


def report(name: str, res: dict[str, Any]) -> None:
    sc = res["scale_check"]
    print(f"\n== {name}, group {res['group']}: {res['source']}; scaling {res['scaling']} "
          f"on both sides (model "
          f"default {res['default_scaling']}); MPlib vs our checker on {sc['states']} states: "
          f"{sc['agree']} agree ({sc['ours_colliding']} colliding by ours, "
          f"{sc['mplib_colliding']} by MPlib)")
    first = next(iter(res["scenes"].values()), None)
    if first is not None:
        print(f"  MPlib's column: {first['mplib']['problem']}")
    for scene, r in res["scenes"].items():
        o, m = r["ours"], r["mplib"]
        st = o["stage_median_ms"]
        print(f"  {scene:8s} n={r['problems']}  success ours {o['success']:.2f} "
              f"{o['failures'] or ''} mplib {fmt(m['success'], '.2f')} {m['failures'] or ''}")
        print(f"    wall ms median/p95: ours {fmt(o['median_ms'])}/{fmt(o['p95_ms'])}  "
              f"mplib (plan+TOPP) {fmt(m['median_ms'])}/{fmt(m['p95_ms'])}  ours/mplib "
              f"{fmt(r['ours_over_mplib_median'], '.2f')}x  (ours over the wire: "
              f"{fmt(o['wire_overhead_ms_median'])} ms beyond the reply's total)")
        print("    ours stages median ms: " + " ".join(f"{k} {fmt(st[k])}" for k in STAGES)
              + f"; verify share {fmt(o['verify_share_median'], '.0%')}")
        pr = o["proof_ms_median"]
        print(f"    near contact (certified clearance < {1e3 * NEAR:g} mm): "
              f"{fmt(o['near_contact_share'], '.0%')} of motions, wall median "
              f"{fmt(o['wall_ms_median_near'])} ms; proof (recheck) median ms: all "
              f"{fmt(pr['all'])} near {fmt(pr['near'])} others {fmt(pr['others'])}")
        c = o["min_clearance_m"]
        print(f"    certified min clearance m: min {fmt(c['min'], '.4f')} median "
              f"{fmt(c['median'], '.4f')} (all certified: {o['certified_all']})")
        print(f"    duration s median: ours {fmt(o['duration_s_median'], '.3f')} toppra same "
              f"path {fmt(o['toppra_duration_s_median'], '.3f')} -> ratio median "
              f"{fmt(o['jerk_limited_over_toppra_median'], '.3f')} max "
              f"{fmt(o['jerk_limited_over_toppra_max'], '.3f')} (target <= 1.2); mplib "
              f"{fmt(m['duration_s_median'], '.3f')}")
        print(f"      jerk floor (slowest joint's own time-optimal jerk-limited move over its "
              f"travel) / toppra median {fmt(o['jerk_floor_over_toppra_median'], '.3f')}; "
              f"ours / floor median {fmt(o['jerk_limited_over_floor_median'], '.3f')}")
        ro, rm = o["recheck"], m["recheck"]
        print(f"    re-check at {res['recheck_step']} rad, trajectories with a collision: ours "
              f"{ro['with_collision']}/{ro['checked']}  mplib {rm['with_collision']}/"
              f"{rm['checked']}" + (
                  "" if "recheck_own_problem" not in m else
                  f" on our robot (left finger following), "
                  f"{m['recheck_own_problem']['with_collision']}/"
                  f"{m['recheck_own_problem']['checked']} on its own problem (held)"))

        def worst(rc: dict[str, Any]) -> str:
            return " ".join(f"{k} {v:.3f}" for k, v in rc["worst_ratio"].items())
        print(f"      other findings (limits by finite differences; ours on the interpolated "
              f"samples, indicative): ours {ro['kinds']} worst/limit {worst(ro)}; mplib "
              f"{rm['kinds']} worst/limit {worst(rm)}")


def _w(d: dict[str, Any] | None) -> str:
    if not d:
        return "-"
    return f"{fmt(d['median_ms'])}/{fmt(d['p95_ms'])}/{fmt(d['max_ms'])}"


def _rungs(rungs: dict[str, int] | None) -> str:
    # the proofs' ladder use summed over the scene's replies (verification.rungs)
    if not rungs:
        return ""
    return "  rungs " + " ".join(f"{k} {v}" for k, v in rungs.items() if v)


def report_mbm(name: str, res: dict[str, Any]) -> None:
    """The MBM-class block (bench/_lib/peer_mbm.py): solved, wall median/p95/max [ms]."""
    o = res["ours"]
    print(f"\n== {name}: {res['source']}\n  {len(res['problems'])} problems x "
          f"{res['repeat']} repeats, {res['planning_time']} s budget; paths re-checked at "
          f"{res['recheck_step']} rad on the meshes; wall ms median/p95/max")
    print(f"  ours   solved {o['solved']}/{o['runs']}  all {_w(o['wall_all'])}  warm (repeats "
          f"after the first) {_w(o['wall_warm'])}  collisions {o['recheck']['with_collision']}"
          f" (deeper than 1 mm: {o['recheck']['with_deep_collision']})"
          f"/{o['recheck']['checked']}  certified {o['certified']}")
    print("         cold start (first plan per worker) s: "
          + " ".join(f"{w:.2f}" for w in o["cold_start_s"])
          + f"; first plan in a new world {_w(o['cold_new_world'])}")
    st = o["stage_median_ms"]
    print("         stages median ms: " + " ".join(f"{k} {fmt(st[k])}" for k in STAGES)
          + f"; proof (recheck) {_w(o['proof'])}; clearance mm min/median "
          f"{fmt(o['clearance_mm']['min'], '.2f')}/{fmt(o['clearance_mm']['median'], '.2f')}")
    for side in ("mplib", "hpp"):
        m = res.get(side)
        if m:
            print(f"  {side:6s} solved {m['solved']}/{m['runs']}  all {_w(m['wall_all'])}  "
                  f"solved only {_w(m['wall_solved'])}  collisions "
                  f"{m['recheck']['with_collision']}/{m['recheck']['checked']} (deeper than "
                  f"{m['recheck']['deeper_than_mm']:g} mm: {m['recheck']['with_deep_collision']})"
                  f"  ({m['settings']})")
    print("  per scene: solved ours/mplib/hpp, wall median ours/mplib/hpp ms, our max proof ms")
    for scene, s in o["scenes"].items():
        m = res["mplib"]["scenes"].get(scene, {})
        h = (res.get("hpp") or {}).get("scenes", {}).get(scene, {})
        print(f"    {scene:18s} {s['solved']}/{m.get('solved', '-')}/{h.get('solved', '-')} "
              f"of {s['runs']}  {fmt(s['median_ms'])}/{fmt(m.get('median_ms'))}/"
              f"{fmt(h.get('median_ms'))}  proof max {fmt(s['proof_max_ms'])}"
              + _rungs(s.get("rungs")))
    if o["failures"]:
        print(f"  our failures: {o['failures']}")
