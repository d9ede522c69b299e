"""A client with nothing but `zenoh` and `json`: what any language with a Zenoh binding
does to talk to `arduinobot serve`.

Requests and replies are JSON; an error comes back as a reply error
`{"error": {"code", "message", "details"}}`. The keys and fields: docs/service.md.

    .venv/bin/python examples/05_raw_zenoh.py [ENDPOINT]   # with `arduinobot serve` running
"""

import json
import sys

import zenoh

endpoint = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"

cfg = zenoh.Config()
cfg.insert_json5("mode", '"client"')
cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
cfg.insert_json5("scouting/multicast/enabled", "false")  # only the endpoint above
# with shared memory on, a request over 3 KB would leave a 16 MiB pool in the service
cfg.insert_json5("transport/shared_memory/enabled", "false")


def ask(session: zenoh.Session, key: str, request: dict | None = None) -> dict:
    """The one reply to a query on ``key``; raises RuntimeError on an error reply."""
    payload = json.dumps(request) if request is not None else None
    for reply in session.get(key, payload=payload, timeout=30):
        if reply.ok is not None:
            return json.loads(reply.ok.payload.to_bytes())
        raise RuntimeError(json.loads(reply.err.payload.to_bytes())["error"])
    raise RuntimeError(f"no reply on {key}: is `arduinobot serve` running at {endpoint}?")


with zenoh.open(cfg) as s:
    robot = ask(s, "arduinobot/description")
    print(f"robot {robot['robot']}: joints {robot['actuated_joints']}, "
          f"default group {robot['default_group']}")

    plan = ask(s, "arduinobot/plan", {"goal": {"named": "reach_left"}, "seed": 1})
    points = plan["trajectory"]["points"]
    print(f"plan: {plan['duration']:.3f} s, {len(points)} samples, "
          f"certified {plan['verification']['certified']}")

    try:
        ask(s, "arduinobot/plan", {"goal": {"named": "no_such_state"}})
    except RuntimeError as e:
        err = e.args[0]
        print(f"{err['code']}: {err['message']}")
