"""rmw_zenoh's graph: data key expressions, liveliness tokens and entity GIDs.

From src/arduinobot/ros2/rmw_zenoh docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5 ("Topic and
Service name mapping", "Graph Cache") and rmw_zenoh_cpp/src/detail/liveliness_utils.cpp @
3411fdec149fe0c932f24d4d79ef908eb81d7482 (``TopicInfo::TopicInfo``, ``Entity::Entity``):

- data key: ``<domain_id>/<fully qualified name without its leading '/'>/<dds type>/<hash>``
- node token: ``@ros2_lv/<domain_id>/<zid>/<node_id>/<node_id>/NN/<enclave>/<ns>/<name>``
- endpoint token: ``@ros2_lv/<domain_id>/<zid>/<node_id>/<entity_id>/<MP|MS|SS|SC>/
  <enclave>/<ns>/<node name>/<name>/<dds type>/<hash>/<qos>``, every chunk mangled
  (``/`` -> ``%``), the QoS as :meth:`arduinobot.ros2.wire.qos.QoS.encode`.
- GID: XXH3-128 (seed 0) of the token's key expression, its low 64 bits then its high 64
  bits, little-endian (``simplified_XXH3_128bits``, a copy of stock XXH3). rmw_zenoh's
  graph cache derives an entity's GID from its token the same way, so the GID we put in
  attachments is the one ``ros2 topic info -v`` shows for us.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeGuard

import xxhash

from arduinobot.ros2.errors import MalformedToken
from arduinobot.ros2.wire.names import demangle, mangle
from arduinobot.ros2.wire.qos import QoS

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger(__name__)

ADMIN_SPACE = "@ros2_lv"
EntityKind = Literal["NN", "MP", "MS", "SS", "SC"]
ENTITY_KINDS: tuple[str, ...] = ("NN", "MP", "MS", "SS", "SC")


def _is_entity_kind(kind: str) -> TypeGuard[EntityKind]:
    return kind in ENTITY_KINDS


@dataclass(frozen=True)
class NodeInfo:
    """A node as the graph knows it. ``zid`` is the Zenoh session id (``str(zid)``)."""

    domain_id: int
    zid: str
    node_id: int
    namespace: str
    name: str
    enclave: str = "/"


@dataclass(frozen=True)
class EndpointInfo:
    """A publisher (MP), subscription (MS), service (SS) or client (SC) of ``node`` on
    the fully qualified ``name``."""

    node: NodeInfo
    entity_id: int
    kind: EntityKind
    name: str
    dds_type: str
    type_hash: str
    qos: QoS


def topic_key(domain_id: int, name: str, dds_type: str, type_hash: str) -> str:
    """The key expression data of fully qualified ``name`` travels on."""
    return f"{domain_id}/{name.strip('/')}/{dds_type}/{type_hash}"


def _node_chunks(node: NodeInfo, entity_id: int, kind: str) -> list[str]:
    return [ADMIN_SPACE, str(node.domain_id), node.zid, str(node.node_id), str(entity_id),
            kind, mangle(node.enclave), mangle(node.namespace), mangle(node.name)]


def node_token(node: NodeInfo) -> str:
    """The node's liveliness token."""
    return "/".join(_node_chunks(node, node.node_id, "NN"))


def endpoint_token(ep: EndpointInfo) -> str:
    """The endpoint's liveliness token."""
    return "/".join(_node_chunks(ep.node, ep.entity_id, ep.kind)
                    + [mangle(ep.name), mangle(ep.dds_type), mangle(ep.type_hash),
                       ep.qos.encode()])


def gid_of(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity with liveliness token ``token``."""
    return xxhash.xxh3_128(token.encode()).intdigest().to_bytes(16, "little")


@dataclass(frozen=True)
class Token:
    """A parsed graph token (what ``Entity::make(keyexpr)`` reads): ``endpoint`` is None
    for a node."""

    node: NodeInfo
    kind: EntityKind
    entity_id: int
    endpoint: EndpointInfo | None

    @classmethod
    def parse(cls, key: str) -> Token:
        parts = key.split("/")
        if len(parts) not in (9, 13) or parts[0] != ADMIN_SPACE:
            raise MalformedToken(key, "a graph token is @ros2_lv/ and 8 (node) or 12 "
                                 "(endpoint) chunks")
        if any(not p for p in parts):
            raise MalformedToken(key, "has an empty chunk")
        kind = parts[5]
        if not _is_entity_kind(kind) or (kind == "NN") != (len(parts) == 9):
            raise MalformedToken(key, f"entity kind {kind!r} with {len(parts) - 1} chunks")
        if not (parts[1].isdigit() and parts[3].isdigit() and parts[4].isdigit()):
            raise MalformedToken(key, "domain, node and entity ids must be integers")
        node = NodeInfo(int(parts[1]), parts[2], int(parts[3]), demangle(parts[7]),
                        demangle(parts[8]), demangle(parts[6]))
        endpoint = None
        if kind != "NN":
            endpoint = EndpointInfo(node, int(parts[4]), kind,
                                    demangle(parts[9]), demangle(parts[10]),
                                    demangle(parts[11]), QoS.decode(parts[12]))
        return cls(node, kind, int(parts[4]), endpoint)


def endpoint_selector(domain_id: int, kind: EntityKind, name: str, dds_type: str,
                      type_hash: str) -> str:
    """A liveliness selector matching every ``kind`` endpoint on fully qualified ``name``
    with that type, whatever its session, node or QoS."""
    return "/".join([ADMIN_SPACE, str(domain_id), "*", "*", "*", kind, "*", "*", "*",
                     mangle(name), mangle(dds_type), mangle(type_hash), "*"])


def query_graph(session: zenoh.Session, selector: str, *, timeout: float = 2.0) -> list[Token]:
    """The graph tokens alive now under ``selector`` (``@ros2_lv/<domain>/**`` for a whole
    domain). A token that does not parse is logged with its code and skipped."""
    found: list[Token] = []
    replies: Any = session.liveliness().get(selector, timeout=timeout)
    for reply in replies:
        if reply.ok is None:
            continue
        key = str(reply.ok.key_expr)
        try:
            found.append(Token.parse(key))
        except MalformedToken as e:
            log.warning("%s: skipped a graph token: %s", e.code, e)
    return found
