"""src/arduinobot/contract/ranges.py: one table of request ranges, equal to every JSON schema that carries
one of its fields, and the one check every planner site uses."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.ranges import RANGES, Range, check_range
from arduinobot.planner.timing.trajectory import sample_times

SCHEMAS = Path(__file__).resolve().parents[2] / "src" / "arduinobot" / "contract" / "schema"


def _fields(node, path=""):
    """(schema path, property name, property schema) of every property, at any depth."""
    if isinstance(node, dict):
        for name, sub in (node.get("properties") or {}).items():
            yield f"{path}.{name}", name, sub
        for key, sub in node.items():
            yield from _fields(sub, f"{path}/{key}")
    elif isinstance(node, list):
        for i, sub in enumerate(node):
            yield from _fields(sub, f"{path}[{i}]")


def _range_of(prop: dict) -> Range:
    if "exclusiveMinimum" in prop:
        return Range(float(prop["exclusiveMinimum"]), float(prop["maximum"]), "",
                     open_lo=True)
    return Range(float(prop["minimum"]), float(prop["maximum"]), "")


def test_every_schema_field_of_the_table_has_its_range():
    seen = set()
    for schema in sorted(SCHEMAS.glob("*.json")):
        for where, name, prop in _fields(json.loads(schema.read_text())):
            if name not in RANGES or not isinstance(prop, dict) or "maximum" not in prop:
                continue
            rng = RANGES[name]
            got = _range_of(prop)
            assert (got.lo, got.hi, got.open_lo) == (rng.lo, rng.hi, rng.open_lo), \
                f"{schema.name}{where}: {got} in the schema, {rng} in src/arduinobot/contract/ranges.py"
            # and the schema's words say the same interval, as the table prints it
            if "description" in prop:
                assert str(got) in prop["description"], \
                    f"{schema.name}{where}: {prop['description']!r} does not say {got}"
            seen.add(name)
    assert seen == set(RANGES), f"no schema carries {set(RANGES) - seen}"


def test_check_range_takes_the_ends_the_table_says():
    for name, rng in RANGES.items():
        assert check_range(rng.hi, name) == rng.hi
        with pytest.raises(InvalidRequest) as e:
            check_range(rng.hi * 1.001 + 1e-9, name)
        assert e.value.field == name and str(rng) in str(e.value)
        if rng.open_lo:
            with pytest.raises(InvalidRequest):
                check_range(rng.lo, name)
            assert check_range(math.nextafter(rng.lo, math.inf), name) > rng.lo
        else:
            assert check_range(rng.lo, name) == rng.lo
            with pytest.raises(InvalidRequest):
                check_range(math.nextafter(rng.lo, -math.inf), name)
        for bad in (math.nan, math.inf, True, "1", None):
            with pytest.raises(InvalidRequest, match="not a finite number"):
                check_range(bad, name, field=f"x.{name}")


def test_the_sampler_refuses_by_the_table():
    rng = RANGES["sample_rate"]
    assert len(sample_times(1.0, rng.lo)) == 2 and len(sample_times(0.01, rng.hi)) == 11
    for bad in (math.nextafter(rng.lo, 0.0), math.nextafter(rng.hi, math.inf)):
        with pytest.raises(InvalidRequest) as e:
            sample_times(1.0, bad)
        assert e.value.field == "sample_rate" and str(rng) in str(e.value)
    assert np.all(np.diff(sample_times(0.5, 100.0)) > 0)
