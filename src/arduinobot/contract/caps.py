"""Every size cap of a request, in one place, and the cheap structural check.

The schemas (``src/arduinobot/contract/schema/*.json``) repeat these figures where a field has one
(``tests/contract/test_schema.py`` checks they agree), and every refusal names its cap
(``details.limit``). :func:`check_structure` runs on the decoded payload before the JSON
Schema validation, so the schema's work is bounded by :data:`MAX_ELEMENTS` whatever
arrives: a 120 KB request of 60,000 array elements is refused in well under a
millisecond instead of being validated element by element for seconds.
"""

from __future__ import annotations

from typing import Any

from arduinobot.contract.errors import InvalidRequest

#: Largest request payload [bytes].
MAX_PAYLOAD = 256 * 1024
#: Largest execute request [bytes]: it carries a whole trajectory, and must take any the
#: service plans (:data:`MAX_SAMPLES` samples as JSON points: ~13 MB for a 7-joint arm;
#: packed, a third of that).
MAX_EXECUTE_PAYLOAD = 16 * 1024 * 1024
#: Deepest nesting of arrays and objects (the root object counts as 1). The deepest
#: valid request, ``obstacles[i].size[j]``, nests 4 deep.
MAX_DEPTH = 8
#: Most values (array elements and object members, all levels together) in one request.
#: 256 obstacles of every field (16 values each) plus every other field fit within 5,000.
MAX_ELEMENTS = 8192
#: Most elements of one array or members of one object: the largest a request needs
#: (:data:`MAX_OBSTACLES`, :data:`MAX_LINKS`).
MAX_ITEMS = 256
#: Longest string, object key included [characters]. Names and ids are at most 64.
MAX_STRING = 1024
#: Most obstacles in a plan or check request.
MAX_OBSTACLES = 256
#: Most joints in a ``{joint: value}`` map.
MAX_JOINTS = 64
#: Most links an fk request may ask for.
MAX_LINKS = 256
#: Longest name (joint, link, group, named state, planner, obstacle id) [characters].
MAX_NAME = 64
#: Smallest velocity or acceleration scaling factor: slower than 1 % of the robot's
#: limits gives motions of tens of minutes (and below ~1e-8, failures inside ruckig and
#: toppra; at 1e-12 sample arrays of hundreds of GiB).
MIN_SCALING = 0.01
#: Most trajectory samples (duration x sample_rate + 1) in one plan reply: about
#: 310 bytes of JSON each for a 4-joint arm, so a reply stays under ~7 MB.
MAX_SAMPLES = 20_000
#: Most points in one point cloud (the scene's ``points`` objects).
MAX_CLOUD_POINTS = 2_000_000
#: Largest decoded point cloud [bytes] (its base64 text is 4/3 of it).
MAX_CLOUD_BYTES = 32 * 2**20
#: Largest scene apply payload [bytes]: the biggest cloud a request may carry, in base64
#: (4/3 of :data:`MAX_CLOUD_BYTES`: 44,739,244), plus 16 MiB for the rest (a few meshes of
#: at most 2 MiB each, other objects): ~58.7 MiB. Below the cloud's own cap, an apply of
#: the biggest allowed cloud would be refused by its size before the cloud's cap said why.
MAX_APPLY_PAYLOAD = 4 * -(-MAX_CLOUD_BYTES // 3) + 16 * 2**20

#: Most inline mesh bytes (decoded) the kept scene holds, all its meshes together: the
#: serving process keeps each mesh's text with its object (and in the scene's reply and
#: file), so without it mesh churn grew it by the scene's size (256 objects of
#: 2 MiB). 16 meshes at the mesh cap; the course workspace's CAD meshes take ~3 MiB.
MAX_SCENE_MESH_BYTES = 32 * 2**20


def check_structure(value: Any, *, counts: bool = True) -> None:
    """Refuse a decoded payload nested deeper than :data:`MAX_DEPTH`, a string longer
    than :data:`MAX_STRING` and, if ``counts``, an array or object of more than
    :data:`MAX_ITEMS` or more than :data:`MAX_ELEMENTS` values in all.

    Iterative (no recursion), and it stops at the first excess, so it visits at most
    :data:`MAX_ELEMENTS` values when ``counts``.

    Args:
        counts: False for a payload that is no plan/fk/ik/check request, such as a
            trajectory to execute, which only its payload cap bounds: its element counts
            and the length of its strings (a packed trajectory's arrays are long base64
            strings) are not capped; its keys and its depth are.

    Raises:
        InvalidRequest: naming the field where the cap was passed and ``details.limit``.
    """
    total = 0
    # (container, its field path, its depth); paths are built only for containers
    stack: list[tuple[Any, tuple[Any, ...], int]] = [(value, (), 1)]
    while stack:
        node, path, depth = stack.pop()
        if isinstance(node, dict):
            items: Any = node.items()
        elif isinstance(node, list):
            items = enumerate(node)
        else:
            if counts:
                _check_scalar(node, path)
            continue
        if depth > MAX_DEPTH:
            raise _over("MAX_DEPTH", f"nested deeper than {MAX_DEPTH} levels of arrays and "
                        "objects", path)
        if counts and len(node) > MAX_ITEMS:
            what = "members" if isinstance(node, dict) else "elements"
            raise _over("MAX_ITEMS", f"{len(node)} {what}, more than the {MAX_ITEMS} any array "
                        "or object may hold", path)
        total += len(node)
        if counts and total > MAX_ELEMENTS:
            raise _over("MAX_ELEMENTS", f"more than {MAX_ELEMENTS} values in the request", path)
        for k, v in items:
            if isinstance(k, str) and len(k) > MAX_STRING:
                raise _over("MAX_STRING", f"a key longer than {MAX_STRING} characters", path)
            if isinstance(v, (dict, list)):
                stack.append((v, (*path, k), depth + 1))
            elif counts and isinstance(v, str) and len(v) > MAX_STRING:
                _check_scalar(v, (*path, k))


def _check_scalar(v: Any, path: tuple[Any, ...]) -> None:
    if isinstance(v, str) and len(v) > MAX_STRING:
        raise _over("MAX_STRING", f"a string of {len(v)} characters, longer than {MAX_STRING}",
                    path)


def _over(cap: str, message: str, path: tuple[Any, ...]) -> InvalidRequest:
    """The refusal for passing ``cap`` (the name of one of this module's caps) at ``path``."""
    return InvalidRequest(message, field=field_path(path) or "(root)",
                          details={"limit": globals()[cap], "cap": cap})


def field_path(parts: Any) -> str:
    """``['obstacles', 0, 'size', 1]`` -> ``'obstacles[0].size[1]'``; a key longer than
    :data:`MAX_NAME` is cut (an error must not echo a 1,000-character key back)."""
    out = ""
    for p in parts:
        if isinstance(p, int):
            out += f"[{p}]"
            continue
        p = str(p)
        if len(p) > MAX_NAME:
            p = p[:MAX_NAME] + "..."
        out += f".{p}" if out else p
    return out
