"""A ROS 2 node over a Zenoh session: its graph token and the endpoints it declares.

One :class:`Node` is what one ``rclcpp::Node`` is under rmw_zenoh: a liveliness token
(``NN``), then a token per publisher, subscription, service and client. Node and entity
ids come from one counter per process (rmw_zenoh counts per context, i.e. per session;
they only have to be unique within one).
"""

from __future__ import annotations

import itertools
import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from arduinobot.ros2.attachment import LAYOUTS, AttachmentLayout
from arduinobot.ros2.errors import EntityClosed, InvalidOption
from arduinobot.ros2.wire.graph import (
    EndpointInfo,
    EntityKind,
    NodeInfo,
    Token,
    node_token,
    query_graph,
)
from arduinobot.ros2.wire.names import fully_qualified, validate_namespace, validate_node_name
from arduinobot.ros2.wire.qos import DEFAULT, SERVICES_DEFAULT, QoS
from arduinobot.ros2.wire.services import ServiceClient, ServiceServer
from arduinobot.ros2.wire.topics import MessageInfo, Publisher, Subscription
from arduinobot.ros2.wire.types import TypeStore

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger(__name__)

_ids = itertools.count()
_ids_lock = threading.Lock()


def _next_id() -> int:
    with _ids_lock:
        return next(_ids)


class Node:
    """A node named ``name`` in ``namespace`` on ROS domain ``domain_id``.

    ``attachment`` picks the attachment layout of the ROS 2 nodes we talk to:
    ``"current"`` for Jazzy rmw_zenoh 0.2.4+, Kilted and Rolling; ``"jazzy-0.2.3"`` for
    Jazzy 0.2.0-0.2.3 (:mod:`arduinobot.ros2.attachment`). ``types`` is shared by every endpoint;
    register extra types in it before declaring endpoints that use them.
    """

    def __init__(self, session: zenoh.Session, name: str, *, namespace: str = "/",
                 domain_id: int = 0, types: TypeStore | None = None,
                 attachment: AttachmentLayout = "current", enclave: str = "/") -> None:
        if not 0 <= domain_id <= 232:
            raise InvalidOption("ROS_DOMAIN_ID", domain_id, "ROS 2 domains are 0..232")
        if attachment not in LAYOUTS:
            raise InvalidOption("attachment", attachment, f"one of {LAYOUTS}")
        self.session = session
        self.types = types if types is not None else TypeStore()
        self.attachment: AttachmentLayout = attachment
        self.info = NodeInfo(domain_id, str(session.info.zid()), _next_id(),
                             validate_namespace(namespace), validate_node_name(name), enclave)
        self.token_key = node_token(self.info)
        self._token = session.liveliness().declare_token(self.token_key)
        self._entities: list[Any] = []
        self._closed = False
        log.info("ROS 2 node %s%s on domain %d (attachment %s)",
                 "" if self.info.namespace == "/" else self.info.namespace,
                 "/" + name, domain_id, attachment)

    @property
    def fully_qualified_name(self) -> str:
        ns = self.info.namespace
        return ("" if ns == "/" else ns) + "/" + self.info.name

    def resolve(self, name: str) -> str:
        """``name`` made fully qualified in this node's namespace."""
        return fully_qualified(name, self.info.namespace)

    def _endpoint(self, kind: EntityKind, name: str, type_name: str, qos: QoS) -> EndpointInfo:
        if self._closed:
            raise EntityClosed(f"node {self.fully_qualified_name}")
        return EndpointInfo(self.info, _next_id(), kind, self.resolve(name),
                            self.types.dds_name(type_name), self.types.type_hash(type_name),
                            qos)

    def _keep(self, entity: Any) -> Any:
        self._entities.append(entity)
        return entity

    def create_publisher(self, topic: str, type_name: str, *, qos: QoS = DEFAULT) -> Publisher:
        """A publisher of ``type_name`` (``pkg/msg/Name``) on ``topic``."""
        ep = self._endpoint("MP", topic, type_name, qos)
        return self._keep(Publisher(self.session, ep, self.types, type_name,
                                    attachment=self.attachment))

    def create_subscription(self, topic: str, type_name: str,
                            callback: Callable[[Any, MessageInfo], None], *,
                            qos: QoS = DEFAULT, raw: bool = False) -> Subscription:
        """A subscription to ``topic``; ``callback(msg, info)`` per message (with
        ``raw``, the undecoded CDR: see :class:`Subscription`)."""
        ep = self._endpoint("MS", topic, type_name, qos)
        return self._keep(Subscription(self.session, ep, self.types, type_name, callback,
                                       attachment=self.attachment, raw=raw))

    def create_service(self, name: str, type_name: str, handler: Callable[..., Any], *,
                       deferred: bool = False, qos: QoS = SERVICES_DEFAULT) -> ServiceServer:
        """A server of ``type_name`` (``pkg/srv/Name``) on ``name``; see
        :class:`arduinobot.ros2.wire.services.ServiceServer` for ``handler`` and ``deferred``."""
        ep = self._endpoint("SS", name, type_name, qos)
        return self._keep(ServiceServer(self.session, ep, self.types, type_name, handler,
                                        attachment=self.attachment, deferred=deferred))

    def create_client(self, name: str, type_name: str, *,
                      qos: QoS = SERVICES_DEFAULT) -> ServiceClient:
        """A client of service ``type_name`` on ``name``."""
        ep = self._endpoint("SC", name, type_name, qos)
        return self._keep(ServiceClient(self.session, ep, self.types, type_name,
                                        attachment=self.attachment))

    def graph(self, *, timeout: float = 2.0) -> list[Token]:
        """Every node and endpoint alive on this node's domain (ours included), from their
        liveliness tokens, as ``ros2 node list`` / ``ros2 topic list`` see them."""
        return query_graph(self.session, f"@ros2_lv/{self.info.domain_id}/**",
                           timeout=timeout)

    def close(self) -> None:
        """Close every endpoint, then withdraw the node's token. The session stays open."""
        if self._closed:
            return
        self._closed = True
        for entity in reversed(self._entities):
            entity.close()
        self._token.undeclare()
