"""Zenoh session configuration: the embedded default, a config file, overrides."""

from __future__ import annotations

import json

from arduinobot.contract.zconfig import DEFAULT_ENDPOINT, zenoh_config
from arduinobot.service.server import ServeOptions


def _get(cfg, key):
    return json.loads(cfg.get_json(key))


def test_embedded_default_is_a_loopback_peer_without_multicast():
    o = ServeOptions()
    cfg = zenoh_config(mode=o.mode, listen=o.listen, connect=o.connect)
    assert o.prefix == "arduinobot" and DEFAULT_ENDPOINT == "tcp/127.0.0.1:7447"
    assert _get(cfg, "mode") == "peer"
    assert _get(cfg, "listen/endpoints") == ["tcp/127.0.0.1:7447"]
    assert _get(cfg, "scouting/multicast/enabled") is False
    # shared memory off for every session (service, router, client): see zenoh_config
    assert _get(cfg, "transport/shared_memory/enabled") is False
    assert _get(zenoh_config(shared_memory=True), "transport/shared_memory/enabled") is True


def test_a_config_file_is_passed_through_and_options_override_it(tmp_path):
    f = tmp_path / "zenoh.json5"
    f.write_text("""{
      // JSON5: comments and trailing commas
      mode: "client",
      connect: { endpoints: ["tcp/10.0.0.1:7447"], },
      transport: { auth: { usrpwd: { user: "robot", password: "secret" } } },
    }""")
    cfg = zenoh_config(config_file=f)
    assert _get(cfg, "mode") == "client"
    assert _get(cfg, "connect/endpoints") == ["tcp/10.0.0.1:7447"]
    assert _get(cfg, "transport/auth/usrpwd/user") == "robot"
    assert _get(cfg, "scouting/multicast/enabled") is False  # never on unless asked
    cfg = zenoh_config(config_file=f, mode="peer", connect=["tcp/127.0.0.1:9000"],
                       multicast_scouting=True)
    assert _get(cfg, "mode") == "peer"
    assert _get(cfg, "connect/endpoints") == ["tcp/127.0.0.1:9000"]
    assert _get(cfg, "scouting/multicast/enabled") is True
