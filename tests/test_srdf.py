"""SRDF parsing against the URDF, and rewriting the disabled pairs in place."""

from __future__ import annotations

import pytest

from description import SrdfError, load_description
from description.srdf import DisabledCollision, parse_srdf, replace_disabled_collisions


@pytest.fixture(scope="module")
def desc():
    return load_description(env={})


def test_named_states_and_end_effector(desc):
    srdf = desc.srdf
    assert {"home", "gripper_open", "gripper_closed"} <= set(srdf.group_states)
    assert srdf.named_state("gripper_open").group == "gripper"
    with pytest.raises(SrdfError, match="no named state 'nope'"):
        srdf.named_state("nope")
    assert srdf.end_effectors[0].group == "gripper"


def test_chain_group(desc):
    text = ('<robot name="arduinobot"><group name="g"><chain base_link="base_link" '
            'tip_link="claw_support"/></group></robot>')
    srdf = parse_srdf(text, desc.robot)
    assert srdf.groups["g"].joints == ("joint_1", "joint_2", "joint_3")


@pytest.mark.parametrize("text, match", [
    ('<robot name="a"><group name="g"><joint name="joint_9"/></group></robot>', "joint_9"),
    ('<robot name="a"><disable_collisions link1="base_link" link2="ghost"/></robot>', "ghost"),
    ('<robot name="a"><group_state name="s" group="nogroup"/></robot>', "nogroup"),
    ('<robot name="a"><group name="g"', "not well-formed"),
])
def test_bad_names_are_errors(desc, text, match):
    with pytest.raises(SrdfError, match=match):
        parse_srdf(text, desc.robot)


def test_replace_disabled_collisions_keeps_the_rest(desc):
    original = desc.srdf.source.read_text()
    pairs = [DisabledCollision("base_link", "base_plate", "Adjacent"),
             DisabledCollision("gripper_left", "gripper_right", "Never")]
    text = replace_disabled_collisions(original, pairs)
    srdf = parse_srdf(text, desc.robot)
    assert srdf.disabled_collisions == tuple(pairs)
    assert srdf.groups == desc.srdf.groups and srdf.group_states == desc.srdf.group_states
    assert "<!--" in text  # comments survive


def test_rewriting_the_same_pairs_is_the_identity(desc):
    original = desc.srdf.source.read_text()
    assert replace_disabled_collisions(original, desc.srdf.disabled_collisions) == original
