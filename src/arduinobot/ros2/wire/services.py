"""Service servers and clients on rmw_zenoh keys (docs/design.md, "Service Clients" and
"Service Servers", src/arduinobot/ros2/rmw_zenoh @ 99a6a2bd10b949052f4f12c5854825dc005e95a5).

A server is a queryable declared *complete* on the service key; a request is a ``get``
with target ``ALL_COMPLETE``, the CDR request as payload and the client's attachment; the
reply carries the response and an attachment with the request's sequence number, a new
source timestamp and the *client's* GID, which is how the client matches it.

Bad requests (no or a malformed attachment, malformed CDR) are logged with their code,
counted in ``rejected`` and answered with ``reply_err`` (a ROS 2 client sees no reply
and times out, as it would with rmw_zenoh's own server, which fails ``take_request``); a
handler's exception is logged and answered the same way. The server keeps serving.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from arduinobot.ros2.attachment import Attachment, AttachmentLayout
from arduinobot.ros2.errors import EntityClosed, Ros2Error, ServiceFailed
from arduinobot.ros2.wire.graph import (
    EndpointInfo,
    endpoint_selector,
    endpoint_token,
    gid_of,
    query_graph,
    topic_key,
)
from arduinobot.ros2.wire.topics import MessageInfo
from arduinobot.ros2.wire.types import TypeStore

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger(__name__)


class PendingRequest:
    """A request a deferred handler answers later, from any thread, exactly once."""

    def __init__(self, server: ServiceServer, query: Any, request: Any,
                 info: MessageInfo, attachment: Attachment) -> None:
        self.request, self.info = request, info
        self._server, self._query, self._att = server, query, attachment
        self._lock = threading.Lock()
        self._done = False

    @property
    def done(self) -> bool:
        return self._done

    def reply(self, response: Any) -> None:
        """Send ``response`` (a ``<Srv>_Response`` message)."""
        payload = self._server._types.serialize(response, self._server.response_type)
        att = Attachment(self._att.sequence_number, time.time_ns(), self._att.gid)
        self._finish(lambda q: q.reply(self._server.key, payload,
                                       attachment=att.encode(self._server._layout)))

    def fail(self, reason: str) -> None:
        """Answer with a Zenoh error reply (ROS 2 clients see no response)."""
        self._finish(lambda q: q.reply_err(reason.encode()))

    def _finish(self, send: Callable[[Any], None]) -> None:
        with self._lock:
            if self._done:
                raise EntityClosed("this request (already answered)")
            self._done = True
            try:
                send(self._query)
            finally:
                self._query.drop()  # finalises the query: the client stops waiting


class ServiceServer:
    """Serves ``type_name`` (``pkg/srv/Name``, or an action's ``..._SendGoal``) on one name.

    ``handler(request, info)`` returns the response; with ``deferred=True`` it gets a
    :class:`PendingRequest` instead and replies when it likes (the queryable's callback
    runs on one Zenoh thread: a handler that waits must defer).
    """

    def __init__(self, session: zenoh.Session, endpoint: EndpointInfo, types: TypeStore,
                 type_name: str, handler: Callable[..., Any], *,
                 attachment: AttachmentLayout, deferred: bool = False) -> None:
        self.endpoint, self.type_name, self._types = endpoint, type_name, types
        self.request_type, self.response_type = f"{type_name}_Request", f"{type_name}_Response"
        self.key = topic_key(endpoint.node.domain_id, endpoint.name, endpoint.dds_type,
                             endpoint.type_hash)
        self.token_key = endpoint_token(endpoint)
        self._layout, self._handler, self._deferred = attachment, handler, deferred
        self.served = 0
        self.rejected = 0
        self.handler_errors = 0
        self.last_error: Ros2Error | None = None
        self._qable = session.declare_queryable(self.key, self._on_query, complete=True)
        self._token = session.liveliness().declare_token(self.token_key)
        self._closed = False

    def _on_query(self, query: Any) -> None:
        # exact queries only: a wildcard (``0/**``) reaches every service key it
        # intersects, past an access rule written for the key, and would start an
        # action's goal (a task) for whoever asked for everything; rmw_zenoh's clients
        # ask the exact key. Left unanswered, as if the key were hidden.
        if str(query.key_expr) != self.key:
            log.debug("%s: not answering a query on '%s' (only its own key)",
                      self.endpoint.name, query.key_expr)
            return
        try:
            raw_att = query.attachment
            att = Attachment.decode(None if raw_att is None else raw_att.to_bytes(),
                                    self._layout)
            payload = query.payload
            request = self._types.deserialize(b"" if payload is None else payload.to_bytes(),
                                              self.request_type)
        except Ros2Error as e:
            self.rejected += 1
            self.last_error = e
            log.warning("%s: rejected a request on %s: %s", e.code, self.endpoint.name, e)
            query.reply_err(str(e).encode())
            query.drop()
            return
        info = MessageInfo(att.sequence_number, att.source_timestamp, att.gid,
                           str(query.key_expr))
        pending = PendingRequest(self, query, request, info, att)
        try:
            if self._deferred:
                self._handler(pending)
            else:
                pending.reply(self._handler(request, info))
            self.served += 1
        except Exception as e:
            # A handler's bug must not take the queryable down: log it and answer.
            self.handler_errors += 1
            log.exception("service %s: the handler failed", self.endpoint.name)
            if not pending.done:
                pending.fail(f"handler failed: {type(e).__name__}: {e}")

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._token.undeclare()
        self._qable.undeclare()


class ServiceClient:
    """Calls service ``type_name`` on one name. Thread-safe."""

    def __init__(self, session: zenoh.Session, endpoint: EndpointInfo, types: TypeStore,
                 type_name: str, *, attachment: AttachmentLayout) -> None:
        self.endpoint, self.type_name, self._types = endpoint, type_name, types
        self.request_type, self.response_type = f"{type_name}_Request", f"{type_name}_Response"
        self.key = topic_key(endpoint.node.domain_id, endpoint.name, endpoint.dds_type,
                             endpoint.type_hash)
        self.token_key = endpoint_token(endpoint)
        self.gid = gid_of(self.token_key)
        self._session, self._layout = session, attachment
        self._token = session.liveliness().declare_token(self.token_key)
        self._lock = threading.Lock()
        self._seq = 1
        self._closed = False

    def call(self, request: Any, *, timeout: float = 5.0) -> Any:
        """The response to ``request``; :class:`ServiceFailed` on no reply within
        ``timeout`` [s], an error reply, or a reply that does not decode."""
        import zenoh

        payload = self._types.serialize(request, self.request_type)
        with self._lock:
            if self._closed:
                raise EntityClosed(f"client of {self.endpoint.name}")
            seq = self._seq
            self._seq += 1
        att = Attachment(seq, time.time_ns(), self.gid).encode(self._layout)
        replies = self._session.get(self.key, payload=payload, attachment=att,
                                    target=zenoh.QueryTarget.ALL_COMPLETE, timeout=timeout)
        errors: list[str] = []
        for reply in replies:
            sample = reply.ok
            if sample is None:
                err = reply.err  # a reply is either ok or err
                errors.append("" if err is None else
                              err.payload.to_bytes().decode(errors="replace"))
                continue
            raw = sample.attachment
            try:
                back = Attachment.decode(None if raw is None else raw.to_bytes(), self._layout)
                if back.sequence_number != seq or back.gid != self.gid:
                    raise ServiceFailed(self.endpoint.name, "a reply for another request "
                                        f"(sequence {back.sequence_number}, ours {seq})")
                return self._types.deserialize(sample.payload.to_bytes(), self.response_type)
            except Ros2Error as e:
                log.warning("%s: unusable reply from %s: %s", e.code, self.endpoint.name, e)
                errors.append(str(e))
        raise ServiceFailed(self.endpoint.name, "; ".join(errors) if errors else
                            f"no reply within {timeout:g} s (no server, or it is busy)")

    def server_ready(self, *, timeout: float = 2.0) -> bool:
        """Whether a server of this service and type announces itself now (its ``SS``
        liveliness token), as ``rclcpp::Client::service_is_ready``."""
        ep = self.endpoint
        selector = endpoint_selector(ep.node.domain_id, "SS", ep.name, ep.dds_type,
                                     ep.type_hash)
        return bool(query_graph(self._session, selector, timeout=timeout))

    def wait_for_server(self, timeout: float) -> bool:
        """Poll :meth:`server_ready` for up to ``timeout`` [s]."""
        end = time.monotonic() + timeout
        while True:
            if self.server_ready(timeout=min(1.0, max(0.1, end - time.monotonic()))):
                return True
            if time.monotonic() >= end:
                return False
            time.sleep(0.05)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._token.undeclare()
