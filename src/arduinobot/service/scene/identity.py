"""A kept scene's identity: its revision and a digest of its content.

Revision numbers alone cannot tell two scenes apart that two instances made while they
could not see each other (a partition, a pause past Zenoh's lease: each applied its own
change 3 on top of 2). The digest can: a SHA-256 of the scene's JSON (the wire form of
every object as applied, the same bytes on every instance that took the same changes),
sent in every ``<prefix>/scene`` reply (``digest``) and with every change the leader
sends (``base_digest``: the scene the change applies to). A member whose scene is at the
change's base revision but not its digest fetches the leader's whole scene instead of
applying the change to another scene; a catch-up takes the leader's scene when it is at
the same revision with another digest (:mod:`arduinobot.service.scene.sync`).
"""

from __future__ import annotations

import hashlib

import orjson

from arduinobot.scene.state import SceneState

__all__ = ["EncodedScenes", "encode_scene"]


def encode_scene(state: SceneState) -> tuple[bytes, str]:
    """The ``<prefix>/scene`` reply of ``state`` (its JSON with ``digest``) and its
    digest (16 hex digits of the SHA-256 of its JSON without the digest)."""
    body = state.to_json()
    digest = hashlib.sha256(orjson.dumps(body)).hexdigest()[:16]
    return orjson.dumps({**body, "digest": digest}), digest


class EncodedScenes:
    """:func:`encode_scene` of the last two scenes asked (the one now and the one it
    replaces, whose digest a change names), each encoded once: meshes and clouds make a
    scene's JSON large."""

    def __init__(self) -> None:
        self._kept: list[tuple[SceneState, bytes, str]] = []

    def of(self, state: SceneState) -> tuple[bytes, str]:
        """``state``'s reply and digest."""
        for s, body, digest in self._kept:
            if s is state:
                return body, digest
        body, digest = encode_scene(state)
        self._kept = [*self._kept[-1:], (state, body, digest)]
        return body, digest

    def digest(self, state: SceneState) -> str:
        return self.of(state)[1]
