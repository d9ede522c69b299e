"""What a camera image could not give, one exception class each, under
:class:`arduinobot.contract.errors.PlanningError` (the service answers with their codes)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from arduinobot.contract.codes import Code
from arduinobot.contract.errors import PlanningError


class ImageInvalid(PlanningError):
    """The image does not decode as PNG/JPEG, or is all one colour (nothing to see)."""

    code: Code = Code.IMAGE_INVALID

    def __init__(self, problem: str, *, field: str = "image") -> None:
        self.field = field
        super().__init__(f"{field}: {problem}", details={"field": field})


class NoMarker(PlanningError):
    """The image decodes, but no marker of the dictionary is in it."""

    code: Code = Code.NO_MARKER

    def __init__(self, dictionary: str) -> None:
        self.dictionary = dictionary
        super().__init__(f"image: no {dictionary} marker is seen",
                         details={"field": "image", "dictionary": dictionary})


class UnknownMarker(PlanningError):
    """Markers are seen whose ids the map does not have: nothing is guessed for them."""

    code: Code = Code.UNKNOWN_MARKER

    def __init__(self, markers: Sequence[int], known: Sequence[int]) -> None:
        self.markers = sorted(markers)
        super().__init__(
            f"markers.objects: marker id(s) {', '.join(map(str, self.markers))} seen but "
            "not in the map", details={"field": "markers.objects", "markers": self.markers,
                                       "known": sorted(known)})


class MarkerRefused(PlanningError):
    """A marker is seen, but too small or too oblique to give a pose worth planning with.

    ``reason``: ``too_small`` (``details.side_px`` < ``details.min_side_px``) or
    ``grazing`` (``details.angle`` > ``details.max_angle`` [rad], between the marker's
    normal and the ray to it)."""

    code: Code = Code.MARKER_REFUSED

    def __init__(self, marker: int, reason: str, message: str,
                 details: Mapping[str, object]) -> None:
        self.marker, self.reason = marker, reason
        super().__init__(f"marker {marker}: {message}",
                         details={"field": "image", "marker": marker, "reason": reason,
                                  **details})
