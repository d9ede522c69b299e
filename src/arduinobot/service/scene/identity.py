"""A kept scene's identity: its revision and a digest of its content.

Revision numbers alone cannot tell two scenes apart that two instances made while they
could not see each other (a partition, a pause past Zenoh's lease: each applied its own
change 3 on top of 2). The digest can: a SHA-256 of the revision and of each member's
SHA-256 (the wire form of every object, cloud and carried object as applied: the same
bytes on every instance that took the same changes), sent in every ``<prefix>/scene`` reply (``digest``) and with every change the leader
sends (``base_digest``: the scene the change applies to). A member whose scene is at the
change's base revision but not its digest fetches the leader's whole scene instead of
applying the change to another scene; a catch-up takes the leader's scene when it is at
the same revision with another digest (:mod:`arduinobot.service.scene.sync`).

Each member is hashed once, when it first appears: an apply that moves one box in a scene
with a 300,000-point cloud hashes the box, not the cloud's 4.8 MB of base64 (8 ms an
apply), and the whole reply is encoded only when someone asks for it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping
from typing import Any

import orjson

from arduinobot.scene.state import SceneState

__all__ = ["EncodedScenes", "encode_scene", "scene_digest"]


def _member(data: Mapping[str, Any]) -> bytes:
    return hashlib.sha256(orjson.dumps(data)).digest()


def _combine(revision: int, sections: Iterable[Iterable[bytes]]) -> str:
    h = hashlib.sha256(b"%d" % revision)
    for members in sections:
        h.update(b"|")
        for m in members:
            h.update(m)
    return h.hexdigest()[:16]


def scene_digest(state: SceneState) -> str:
    """``state``'s digest: 16 hex digits of the SHA-256 of its revision and of each
    object's, cloud's and carried object's SHA-256, in the scene's order."""
    return _combine(state.revision, ([_member(o.data) for o in state.objects],
                                     [_member(c.data) for c in state.clouds],
                                     [_member(a.data) for a in state.attached]))


def encode_scene(state: SceneState, digest: str | None = None) -> bytes:
    """The ``<prefix>/scene`` reply of ``state``: its JSON with ``digest``."""
    return orjson.dumps({**state.to_json(),
                         "digest": scene_digest(state) if digest is None else digest})


class EncodedScenes:
    """The digests of the last two scenes asked (the one now and the one it replaces,
    whose digest a change names), each member hashed once while it stays in the scene,
    and the reply of the newest, encoded once when first asked: meshes and clouds make a
    scene's JSON large."""

    def __init__(self) -> None:
        self._digests: list[tuple[SceneState, str]] = []
        self._reply: tuple[SceneState, bytes] | None = None
        # id(member's data) -> (the data, kept alive so the id stays its own; its hash)
        self._members: dict[int, tuple[Mapping[str, Any], bytes]] = {}

    def _hash(self, data: Mapping[str, Any], seen: dict[int, tuple[Mapping[str, Any], bytes]]
              ) -> bytes:
        hit = self._members.get(id(data))
        h = hit[1] if hit is not None and hit[0] is data else _member(data)
        seen[id(data)] = (data, h)
        return h

    def digest(self, state: SceneState) -> str:
        """``state``'s digest (:func:`scene_digest`)."""
        for s, d in self._digests:
            if s is state:
                return d
        seen: dict[int, tuple[Mapping[str, Any], bytes]] = {}
        d = _combine(state.revision, ([self._hash(o.data, seen) for o in state.objects],
                                      [self._hash(c.data, seen) for c in state.clouds],
                                      [self._hash(a.data, seen) for a in state.attached]))
        # the members of the scenes kept (the last one's too: a change names its base)
        for s, _ in self._digests[-1:]:
            for data in (*(o.data for o in s.objects), *(c.data for c in s.clouds),
                         *(a.data for a in s.attached)):
                if id(data) in self._members:
                    seen.setdefault(id(data), self._members[id(data)])
        self._members = seen
        self._digests = [*self._digests[-1:], (state, d)]
        return d

    def of(self, state: SceneState) -> tuple[bytes, str]:
        """``state``'s reply and digest."""
        d = self.digest(state)
        if self._reply is None or self._reply[0] is not state:
            self._reply = (state, encode_scene(state, d))
        return self._reply[1], d
