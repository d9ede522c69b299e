"""QoS profiles and their compact encoding in rmw_zenoh liveliness tokens.

Encoding from ``qos_to_keyexpr`` / ``keyexpr_to_qos`` in
rmw_zenoh_cpp/src/detail/liveliness_utils.cpp (src/arduinobot/ros2/rmw_zenoh @ 3411fdec149fe0c932f24d4d79ef908eb81d7482):
``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:
<liveliness>,<lease s>,<ns>``, each number ``std::to_string`` of the rmw enum and left
empty when it equals rmw_zenoh's default (rmw_zenoh_cpp/src/detail/qos.cpp @
7efeee2b9009b816a4bd4a3148af3cca40f753d5: keep_last, depth 42, reliable, volatile,
infinite durations, automatic liveliness). rmw enum values (rmw/types.h): reliability
reliable 1 / best_effort 2; durability transient_local 1 / volatile 2; history keep_last
1 / keep_all 2; liveliness automatic 1 / manual_by_topic 3.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeVar

from arduinobot.ros2.errors import MalformedToken

Reliability = Literal["reliable", "best_effort"]
Durability = Literal["volatile", "transient_local"]
History = Literal["keep_last", "keep_all"]
Liveliness = Literal["automatic", "manual_by_topic"]

#: RMW_DURATION_INFINITE (rmw/time.h): (sec, nsec).
INFINITE: tuple[int, int] = (9223372036, 854775807)

_RELIABILITY: dict[Reliability, int] = {"reliable": 1, "best_effort": 2}
_DURABILITY: dict[Durability, int] = {"transient_local": 1, "volatile": 2}
_HISTORY: dict[History, int] = {"keep_last": 1, "keep_all": 2}
_LIVELINESS: dict[Liveliness, int] = {"automatic": 1, "manual_by_topic": 3}
_Choice = TypeVar("_Choice", bound=str)  # one of the Literal choices above


@dataclass(frozen=True)
class QoS:
    """A ROS 2 QoS profile (rclcpp's ``QoS(10)`` by default: reliable, volatile,
    keep_last 10). Durations are (sec, nsec)."""

    reliability: Reliability = "reliable"
    durability: Durability = "volatile"
    history: History = "keep_last"
    depth: int = 10
    deadline: tuple[int, int] = INFINITE
    lifespan: tuple[int, int] = INFINITE
    liveliness: Liveliness = "automatic"
    liveliness_lease_duration: tuple[int, int] = INFINITE

    def encode(self) -> str:
        """The token's ``<qos>`` chunk, as ``qos_to_keyexpr`` writes it."""
        d = RMW_ZENOH_DEFAULT

        def num(value: object, default: object, table: dict | None = None) -> str:
            if value == default:
                return ""
            return str(table[value] if table is not None else value)

        return ":".join([
            num(self.reliability, d.reliability, _RELIABILITY),
            num(self.durability, d.durability, _DURABILITY),
            num(self.history, d.history, _HISTORY) + "," + num(self.depth, d.depth),
            num(self.deadline[0], d.deadline[0]) + "," + num(self.deadline[1], d.deadline[1]),
            num(self.lifespan[0], d.lifespan[0]) + "," + num(self.lifespan[1], d.lifespan[1]),
            ",".join([num(self.liveliness, d.liveliness, _LIVELINESS),
                      num(self.liveliness_lease_duration[0],
                          d.liveliness_lease_duration[0]),
                      num(self.liveliness_lease_duration[1],
                          d.liveliness_lease_duration[1])]),
        ])

    @classmethod
    def decode(cls, text: str) -> QoS:
        """The profile a token's ``<qos>`` chunk encodes (``keyexpr_to_qos``)."""
        parts = text.split(":")
        groups = [p.split(",") for p in parts[2:6]] if len(parts) >= 6 else []
        if len(parts) < 6 or [len(g) for g in groups] != [2, 2, 2, 3]:
            raise MalformedToken(text, "a QoS chunk has 6 ':' fields: r:d:h,depth:s,ns:s,ns:"
                                 "kind,s,ns")
        d = RMW_ZENOH_DEFAULT

        def enum(s: str, default: _Choice, table: dict[_Choice, int]) -> _Choice:
            if not s:
                return default
            for name, value in table.items():
                if str(value) == s:
                    return name
            raise MalformedToken(text, f"unknown QoS value {s!r}")

        def integer(s: str, default: int) -> int:
            if not s:
                return default
            if not s.isdigit():
                raise MalformedToken(text, f"QoS number {s!r} is not a non-negative integer")
            return int(s)

        hist, dl, ls, lv = groups
        return cls(
            reliability=enum(parts[0], d.reliability, _RELIABILITY),
            durability=enum(parts[1], d.durability, _DURABILITY),
            history=enum(hist[0], d.history, _HISTORY),
            depth=integer(hist[1], d.depth),
            deadline=(integer(dl[0], d.deadline[0]), integer(dl[1], d.deadline[1])),
            lifespan=(integer(ls[0], d.lifespan[0]), integer(ls[1], d.lifespan[1])),
            liveliness=enum(lv[0], d.liveliness, _LIVELINESS),
            liveliness_lease_duration=(integer(lv[1], d.liveliness_lease_duration[0]),
                                       integer(lv[2], d.liveliness_lease_duration[1])),
        )


#: rclcpp's ``QoS(10)``: what publishers and subscriptions get unless told.
DEFAULT = QoS()
#: rmw_zenoh's own defaults (qos.cpp), the reference the encoding leaves out.
RMW_ZENOH_DEFAULT = QoS(depth=42)
#: rmw_qos_profile_sensor_data (rmw/qos_profiles.h): best effort, keep last 5, what camera
#: drivers publish images and clouds with; a subscription with it matches reliable and
#: best-effort publishers alike (a reliable one would not match a best-effort publisher)
SENSOR_DATA = QoS(reliability="best_effort", depth=5)
#: rmw_qos_profile_services_default (rmw/qos_profiles.h): what services and clients use.
SERVICES_DEFAULT = QoS()
#: rcl_action_qos_profile_status_default (rcl_action/default_qos.h): the action status topic.
ACTION_STATUS = QoS(durability="transient_local", depth=1)
