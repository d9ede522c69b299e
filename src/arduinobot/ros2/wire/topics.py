"""Publishers and subscriptions on rmw_zenoh keys, each with its liveliness token.

A publisher ``put``s CDR on the topic key with an attachment (docs/design.md,
"Publishers"); rmw_zenoh's subscriptions drop samples without a readable attachment, so
the layout must be the receiving release's (:mod:`arduinobot.ros2.attachment`). The sequence number
starts at 1 (``PublisherData``'s ``sequence_number_(1)`` in
rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp @ 3e19ec730c529035a648aec80c0ae0a056943b8c).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from arduinobot.ros2.attachment import Attachment, AttachmentLayout
from arduinobot.ros2.errors import EntityClosed, Ros2Error
from arduinobot.ros2.wire.graph import EndpointInfo, endpoint_token, gid_of, topic_key
from arduinobot.ros2.wire.types import TypeStore

if TYPE_CHECKING:
    import zenoh
    import zenoh.ext

log = logging.getLogger(__name__)


def _zenoh() -> Any:
    import zenoh
    return zenoh


@dataclass(frozen=True)
class MessageInfo:
    """What came with a message: the sender's attachment and the key it arrived on."""

    sequence_number: int
    source_timestamp: int
    publisher_gid: bytes
    key: str


class Publisher:
    """Publishes ``type_name`` messages on one topic. Thread-safe; ``close()`` withdraws
    the liveliness token, then the Zenoh publisher."""

    def __init__(self, session: zenoh.Session, endpoint: EndpointInfo, types: TypeStore,
                 type_name: str, *, attachment: AttachmentLayout) -> None:
        z = _zenoh()
        self.endpoint, self.type_name, self._types = endpoint, type_name, types
        self.key = topic_key(endpoint.node.domain_id, endpoint.name, endpoint.dds_type,
                             endpoint.type_hash)
        self.token_key = endpoint_token(endpoint)
        self.gid = gid_of(self.token_key)
        self._layout = attachment
        qos = endpoint.qos
        reliable = qos.reliability == "reliable"
        # As PublisherData::make: BLOCK only for reliable keep_all, else DROP.
        block = reliable and qos.history == "keep_all"
        options = dict(
            reliability=z.Reliability.RELIABLE if reliable else z.Reliability.BEST_EFFORT,
            congestion_control=(z.CongestionControl.BLOCK if block
                                else z.CongestionControl.DROP))
        self._pub: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        if qos.durability == "transient_local":
            # As PublisherData::make: an advanced publisher caching `depth` samples for
            # late joiners, detectable, with sporadic heartbeats when reliable (500 ms).
            import zenoh.ext as ze
            miss = (ze.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=0.5)
                    if reliable else None)
            self._pub = ze.declare_advanced_publisher(
                session, self.key, cache=ze.CacheConfig(qos.depth), publisher_detection=True,
                sample_miss_detection=miss, **options)
        else:
            self._pub = session.declare_publisher(self.key, **options)
        self._token = session.liveliness().declare_token(self.token_key)
        self._lock = threading.Lock()
        self._seq = 1
        self._closed = False

    @property
    def published(self) -> int:
        """How many messages went out."""
        return self._seq - 1

    def publish(self, msg: Any) -> None:
        """Serialise ``msg`` (a :meth:`TypeStore.message`) and put it."""
        self.publish_cdr(self._types.serialize(msg, self.type_name))

    def publish_cdr(self, payload: bytes) -> None:
        """Put already serialised CDR (with its encapsulation header)."""
        with self._lock:
            if self._closed:
                raise EntityClosed(f"publisher on {self.endpoint.name}")
            att = Attachment(self._seq, time.time_ns(), self.gid).encode(self._layout)
            self._seq += 1
            self._pub.put(payload, attachment=att)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._token.undeclare()
            self._pub.undeclare()


class Subscription:
    """Calls ``callback(msg, info)`` for each ``type_name`` message on one topic.

    Runs on Zenoh's callback thread: keep ``callback`` short. A sample whose attachment
    or CDR is malformed is logged with its code and counted in ``rejected`` (rmw_zenoh
    drops those too); an exception from ``callback`` is logged and counted in
    ``callback_errors``, and the subscription keeps going.

    With ``raw``, ``msg`` is the sample's payload as Zenoh gave it (``zenoh.ZBytes``:
    the CDR, not copied, not decoded; :meth:`TypeStore.deserialize` of its
    ``to_bytes()`` when wanted): for large messages of which only the latest matters
    (camera images, point clouds), so no message is decoded that nobody reads.
    """

    def __init__(self, session: zenoh.Session, endpoint: EndpointInfo, types: TypeStore,
                 type_name: str, callback: Callable[[Any, MessageInfo], None], *,
                 attachment: AttachmentLayout, raw: bool = False) -> None:
        self.endpoint, self.type_name, self._types = endpoint, type_name, types
        self.key = topic_key(endpoint.node.domain_id, endpoint.name, endpoint.dds_type,
                             endpoint.type_hash)
        self.token_key = endpoint_token(endpoint)
        self.gid = gid_of(self.token_key)
        self._layout, self._callback, self._raw = attachment, callback, raw
        self.received = 0
        self.rejected = 0
        self.callback_errors = 0
        self.last_error: Ros2Error | None = None
        self._sub: zenoh.Subscriber[None] | zenoh.ext.AdvancedSubscriber[None]
        if endpoint.qos.durability == "transient_local":
            # design.md "Subscriptions": an advanced subscriber querying the cached history
            # of (late-detected) transient_local publishers.
            import zenoh.ext as ze
            self._sub = ze.declare_advanced_subscriber(
                session, self.key, self._on_sample,
                history=ze.HistoryConfig(detect_late_publishers=True,
                                         max_samples=endpoint.qos.depth))
        else:
            self._sub = session.declare_subscriber(self.key, self._on_sample)
        self._token = session.liveliness().declare_token(self.token_key)
        self._closed = False

    def _on_sample(self, sample: Any) -> None:
        raw_att = sample.attachment
        try:
            att = Attachment.decode(None if raw_att is None else raw_att.to_bytes(),
                                    self._layout)
            msg = (sample.payload if self._raw
                   else self._types.deserialize(sample.payload.to_bytes(), self.type_name))
        except Ros2Error as e:
            self.rejected += 1
            self.last_error = e
            log.warning("%s: dropped a sample on %s: %s", e.code, self.endpoint.name, e)
            return
        self.received += 1
        info = MessageInfo(att.sequence_number, att.source_timestamp, att.gid,
                           str(sample.key_expr))
        try:
            self._callback(msg, info)
        except Exception:
            # Zenoh's callback thread must survive a subscriber's bug; the traceback is logged.
            self.callback_errors += 1
            log.exception("subscription callback on %s failed", self.endpoint.name)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._token.undeclare()
        self._sub.undeclare()
