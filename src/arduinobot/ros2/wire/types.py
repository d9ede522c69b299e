"""Message, service and action types: CDR (de)serialisation and RIHS01 type hashes,
through ``rosbags`` (PyPI) -- no ROS install.

The store starts from rosbags' Jazzy typestore (sensor_msgs, trajectory_msgs, action_msgs,
...) and takes more types from their ``.msg`` / ``.srv`` / ``.action`` text
(:meth:`TypeStore.register_msg` / ``register_srv`` / ``register_action``), e.g. control_msgs
or the course's arduinobot_msgs.

Type hashes are REP-2016's RIHS01 as ``rosidl_generator_type_description`` computes them:
a message's is rosbags' ``hash_rihs01``; a service's hashes a type with the fields
``request_message``, ``response_message``, ``event_message`` (``<Srv>_Event``: ``info``
service_msgs/ServiceEventInfo, ``request`` and ``response`` as sequences of at most one);
an action's hashes ``goal``, ``result``, ``feedback``, ``send_goal_service``,
``get_result_service``, ``feedback_message``. The service layout reproduces rmw_zenoh's
docs/design.md example (example_interfaces/srv/AddTwoInts ->
``RIHS01_e118de6b...``; tests/test_ros2_types.py) once ServiceEventInfo's ``client_gid``
is ``uint8[16]``: the .msg says ``char[16]`` and ROS 2 maps a .msg ``char`` to ``uint8``,
while rosbags' store keeps ``char`` (a different type id in the hash; the same CDR byte).

DDS type names (what keys and tokens carry): ``pkg::msg::dds_::Name_``; a service's and an
action service's drop the ``Request_``/``Response_`` suffix, as rmw_zenoh's
``ServiceData::make`` does (``pkg::srv::dds_::Name_``, ``pkg::action::dds_::Name_SendGoal_``).
"""

from __future__ import annotations

import logging
import re
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from arduinobot.ros2.errors import InvalidTypeDefinition, MalformedCdr, MessageMismatch, UnknownType

log = logging.getLogger(__name__)

_TYPE_NAME = re.compile(r"([A-Za-z][A-Za-z0-9_]*)/(msg|srv|action)/([A-Z][A-Za-z0-9]*)"
                        r"(_[A-Za-z]+)*")
_SEPARATOR = re.compile(r"^---\s*$", re.MULTILINE)
_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"
_UUID = "unique_identifier_msgs/msg/UUID"
_TIME = "builtin_interfaces/msg/Time"


_DTYPES = {"bool": "bool", "byte": "uint8", "char": "uint8", "int8": "int8", "uint8": "uint8",
           "int16": "int16", "uint16": "uint16", "int32": "int32", "uint32": "uint32",
           "int64": "int64", "uint64": "uint64", "float32": "float32", "float64": "float64"}


def _fix_name(name: str) -> str:
    # rosbags files 'pkg/srv/X' as 'pkg/srv/msg/X'; ROS names (and hashes) have no '/msg'.
    return name.replace("/srv/msg/", "/srv/").replace("/action/msg/", "/action/")


def _fix_desc(desc: Any) -> Any:
    kind, rest = desc
    if kind == Nodetype.NAME:
        return (kind, _fix_name(rest))
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return (kind, (_fix_desc(rest[0]), rest[1]))
    return desc


def _split(text: str, parts: int, type_name: str) -> list[str]:
    chunks = _SEPARATOR.split(text)
    if len(chunks) != parts:
        raise InvalidTypeDefinition(type_name, f"expected {parts} parts separated by '---' "
                                    f"lines, found {len(chunks)}")
    return chunks


class TypeStore:
    """Types by ROS name (``sensor_msgs/msg/JointState``), their CDR and their hashes."""

    def __init__(self) -> None:
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        defs = dict(jazzy.fielddefs)
        consts, fields = defs[_EVENT_INFO]
        defs[_EVENT_INFO] = (consts, [
            (n, (Nodetype.ARRAY, ((Nodetype.BASE, ("uint8", 0)), 16)))
            if n == "client_gid" else (n, d) for n, d in fields])
        self._store = get_typestore(Stores.EMPTY)
        self._store.register(defs)
        self._kinds: dict[str, str] = {n: "msg" for n in defs}
        self._hashes: dict[str, str] = {}

    # -- registration ---------------------------------------------------------------
    def _register(self, text: str, name: str) -> None:
        try:
            parsed = get_types_from_msg(text, name)
            fixed = {_fix_name(k): (c, [(f, _fix_desc(d)) for f, d in fl])
                     for k, (c, fl) in parsed.items()}
            self._store.register(fixed)
        except Exception as e:  # rosbags raises its own and parser errors of several kinds
            raise InvalidTypeDefinition(name, str(e)) from e
        self._kinds[name] = "msg"

    def _check_name(self, name: str, kind: str) -> None:
        m = _TYPE_NAME.fullmatch(name)
        if not m or m.group(2) != kind or m.group(4):
            raise InvalidTypeDefinition(name, f"a {kind} type is named 'pkg/{kind}/Name'")

    def register_msg(self, name: str, text: str) -> None:
        """Add message ``name`` (``pkg/msg/Name``) from its .msg text."""
        self._check_name(name, "msg")
        self._register(text, name)

    def register_srv(self, name: str, text: str) -> None:
        """Add service ``name`` (``pkg/srv/Name``) from its .srv text."""
        self._check_name(name, "srv")
        request, response = _split(text, 2, name)
        self._add_service(name, request, response)

    def _add_service(self, name: str, request: str, response: str) -> None:
        req, res, ev = f"{name}_Request", f"{name}_Response", f"{name}_Event"
        self._register(request, req)
        self._register(response, res)
        self._register(f"{_EVENT_INFO} info\n{req}[<=1] request\n{res}[<=1] response", ev)
        self._register(f"{req} request_message\n{res} response_message\n{ev} event_message",
                       name)
        self._kinds[name] = "srv"

    def register_action(self, name: str, text: str) -> None:
        """Add action ``name`` (``pkg/action/Name``) from its .action text, with the types
        its three services and feedback topic carry."""
        self._check_name(name, "action")
        goal, result, feedback = _split(text, 3, name)
        g, r, f = f"{name}_Goal", f"{name}_Result", f"{name}_Feedback"
        self._register(goal, g)
        self._register(result, r)
        self._register(feedback, f)
        self._add_service(f"{name}_SendGoal", f"{_UUID} goal_id\n{g} goal",
                          f"bool accepted\n{_TIME} stamp")
        self._add_service(f"{name}_GetResult", f"{_UUID} goal_id",
                          f"int8 status\n{r} result")
        self._register(f"{_UUID} goal_id\n{f} feedback", f"{name}_FeedbackMessage")
        self._register(f"{g} goal\n{r} result\n{f} feedback\n"
                       f"{name}_SendGoal send_goal_service\n"
                       f"{name}_GetResult get_result_service\n"
                       f"{name}_FeedbackMessage feedback_message", name)
        self._kinds[name] = "action"

    # -- lookups --------------------------------------------------------------------
    def __contains__(self, name: str) -> bool:
        return name in self._store.fielddefs

    def kind(self, name: str) -> str:
        """``"msg"``, ``"srv"`` or ``"action"``."""
        self._require(name)
        return self._kinds.get(name, "msg")

    def _require(self, name: str) -> None:
        if name not in self._store.fielddefs:
            raise UnknownType(name, hint="register it with register_msg/_srv/_action")

    def type_hash(self, name: str) -> str:
        """``RIHS01_<64 hex>`` of message, service or action ``name``."""
        self._require(name)
        if name not in self._hashes:
            self._hashes[name] = self._store.hash_rihs01(name)
        return self._hashes[name]

    def dds_name(self, name: str) -> str:
        """The DDS type name rmw_zenoh puts in keys and tokens (``pkg::msg::dds_::Name_``)."""
        self._require(name)
        pkg, kind, rest = name.split("/")
        return f"{pkg}::{kind}::dds_::{rest}_"

    def message(self, type_name: str, /, **fields: Any) -> Any:
        """A ``type_name`` message object with ``fields`` (every field must be given)."""
        self._require(type_name)
        try:
            return self._store.types[type_name](**fields)
        except TypeError as e:
            raise MessageMismatch(type_name, str(e)) from e

    def default(self, type_name: str) -> Any:
        """A ``type_name`` message with every field zero, false, empty or default-built
        (default values a .msg declares are not applied)."""
        import numpy as np

        self._require(type_name)

        def base(typ: str) -> Any:
            return "" if typ in ("string", "wstring") else False if typ == "bool" else 0

        def value(desc: Any) -> Any:
            kind, rest = desc
            if kind == Nodetype.BASE:
                return base(rest[0])
            if kind == Nodetype.NAME:
                return self.default(rest)
            (sub_kind, sub), count = rest
            numeric = sub_kind == Nodetype.BASE and sub[0] not in ("string", "wstring")
            n = count if kind == Nodetype.ARRAY else 0
            if numeric:
                return np.zeros(n, dtype=_DTYPES.get(sub[0], np.uint8))
            return [value((sub_kind, sub)) for _ in range(n)]

        fields = {name: value(desc) for name, desc in self._store.fielddefs[type_name][1]}
        return self.message(type_name, **fields)

    # -- CDR ------------------------------------------------------------------------
    def serialize(self, msg: Any, name: str) -> bytes:
        """``msg`` as little-endian CDR with its 4-byte encapsulation header, as ROS
        typesupport (Fast-CDR) writes it."""
        self._require(name)
        try:
            return bytes(self._store.serialize_cdr(msg, name))
        except Exception as e:  # rosbags raises struct/attribute/type errors on bad fields
            raise MessageMismatch(name, f"{type(e).__name__}: {e}") from e

    def deserialize(self, raw: bytes | memoryview, name: str) -> Any:
        """The ``name`` message in ``raw``; :class:`MalformedCdr` for anything else."""
        self._require(name)
        data = bytes(raw)
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1) or data[2:4] != b"\0\0":
            raise MalformedCdr(name, "no CDR encapsulation header (00 00|01 00 00)",
                               size=len(data))
        try:
            return self._store.deserialize_cdr(data, name)
        except Exception as e:  # truncation, bad lengths, bad UTF-8: all the same to us
            raise MalformedCdr(name, f"{type(e).__name__}: {e}", size=len(data)) from e
