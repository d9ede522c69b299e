"""ROS 2 names: validation and the fully qualified name a key expression carries.

The rules are ROS 2's (design.ros2.org, "Topic and Service name mapping"; rcl's
``rmw_validate_full_topic_name`` / ``rmw_validate_namespace`` / ``rmw_validate_node_name``):
tokens of ``[A-Za-z0-9_]`` that do not start with a digit, no ``__``, no empty token, no
trailing ``/``. Private (``~``) names and substitutions (``{node}``) are not supported.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping

from arduinobot.ros2.errors import InvalidName, InvalidOption

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _check_tokens(text: str, *, kind: str, original: str) -> None:
    for token in text.split("/"):
        if not token:
            raise InvalidName(original, "has an empty token ('//' or a trailing '/')",
                              kind=kind)
        if not _TOKEN.fullmatch(token):
            raise InvalidName(original, f"token {token!r} must be letters, digits and '_', "
                              "not starting with a digit", kind=kind)
        if "__" in token:
            raise InvalidName(original, f"token {token!r} has a double underscore",
                              kind=kind)


def validate_namespace(namespace: str) -> str:
    """``namespace`` as ROS 2 stores it: ``"/"`` or ``"/a/b"`` (a missing leading ``/`` is
    added, as rcl does for ``--ros-args -r __ns:=a``)."""
    ns = namespace.strip()
    if ns in ("", "/"):
        return "/"
    if not ns.startswith("/"):
        ns = "/" + ns
    _check_tokens(ns[1:], kind="namespace", original=namespace)
    return ns


def validate_node_name(name: str) -> str:
    """A node name: one token."""
    if "/" in name:
        raise InvalidName(name, "a node name has no '/'", kind="node name")
    _check_tokens(name, kind="node name", original=name)
    return name


def fully_qualified(name: str, namespace: str = "/") -> str:
    """The fully qualified topic or service name: ``name`` if absolute, else under
    ``namespace`` (``fully_qualified("joint_states", "/arm") == "/arm/joint_states"``)."""
    if not name:
        raise InvalidName(name, "is empty", kind="topic or service name")
    if name.startswith("~") or "{" in name:
        raise InvalidName(name, "private names and substitutions are not supported",
                          kind="topic or service name")
    if name.startswith("/"):
        full = name
    else:
        ns = validate_namespace(namespace)
        full = ("" if ns == "/" else ns) + "/" + name
    _check_tokens(full[1:], kind="topic or service name", original=name)
    return full


def mangle(name: str) -> str:
    """rmw_zenoh's ``mangle_name``: every ``/`` becomes ``%`` (liveliness tokens)."""
    return name.replace("/", "%")


def demangle(name: str) -> str:
    """rmw_zenoh's ``demangle_name``: every ``%`` becomes ``/``."""
    return name.replace("%", "/")


def domain_id_from_env(environ: Mapping[str, str] | None = None) -> int:
    """The ROS 2 domain as rcl reads it: ``ROS_DOMAIN_ID`` (0 when unset or empty).

    Raises:
        InvalidOption: a value that is not an integer in 0..232.
    """
    env = (os.environ if environ is None else environ).get("ROS_DOMAIN_ID", "").strip()
    if not env:
        return 0
    if not env.isdigit() or not 0 <= int(env) <= 232:
        raise InvalidOption("ROS_DOMAIN_ID", env, "a ROS 2 domain id, 0..232")
    return int(env)
