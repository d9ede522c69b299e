"""SRDF parsing against the URDF, and rewriting the disabled pairs in place."""

from __future__ import annotations

import pytest

from arduinobot.description import SrdfError
from arduinobot.description.srdf import DisabledCollision, parse_srdf, replace_disabled_collisions


def test_named_states_and_end_effector(desc):
    srdf = desc.srdf
    assert {"home", "gripper_open", "gripper_closed"} <= set(srdf.state_names())
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
    assert srdf.groups == desc.srdf.groups and srdf.states == desc.srdf.states
    assert "<!--" in text  # comments survive


def test_rewriting_the_same_pairs_is_the_identity(desc):
    original = desc.srdf.source.read_text()
    assert replace_disabled_collisions(original, desc.srdf.disabled_collisions) == original


# A setup assistant SRDF as the course leaves it: a virtual joint, a fixed joint and a
# <link> in groups, a subgroup declared after its user, `home` in two groups, and a
# disabled pair naming a link the model no longer has.
COURSE_SRDF = """<robot name="arduinobot">
  <virtual_joint name="vj" type="fixed" parent_frame="world" child_link="base_link"/>
  <group name="both"><group name="arm"/><group name="gripper"/></group>
  <group name="arm">
    <joint name="vj"/><joint name="virtual_joint"/><joint name="joint_1"/>
    <joint name="joint_2"/><joint name="joint_3"/><joint name="horizontal_arm_to_claw_support"/>
  </group>
  <group name="gripper"><link name="gripper_right"/><joint name="joint_5"/></group>
  <group_state name="home" group="arm"><joint name="joint_1" value="0"/></group_state>
  <group_state name="home" group="gripper"><joint name="joint_4" value="0"/></group_state>
  <group_state name="open" group="gripper"><joint name="joint_4" value="-1"/></group_state>
  <disable_collisions link1="base_link" link2="old_camera" reason="Never"/>
  <disable_collisions link1="base_link" link2="base_plate" reason="Adjacent"/>
</robot>"""


def test_groups_ignore_fixed_and_virtual_joints_and_find_their_tip(desc):
    srdf = parse_srdf(COURSE_SRDF, desc.robot)
    assert srdf.groups["arm"].joints == ("joint_1", "joint_2", "joint_3")
    assert srdf.groups["arm"].tip_link == "claw_support"
    assert srdf.groups["gripper"].joints == ("joint_4", "joint_5")
    assert srdf.groups["both"].joints == ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5")
    assert srdf.default_group() == "arm" and srdf.tip_link("arm") == "claw_support"


def test_a_name_two_groups_use_is_looked_up_per_group(desc):
    srdf = parse_srdf(COURSE_SRDF, desc.robot)
    assert srdf.named_state("home", "arm").values == {"joint_1": 0.0}
    assert srdf.named_state("home", "gripper").values == {"joint_4": 0.0}
    assert srdf.named_state("open").group == "gripper"
    with pytest.raises(SrdfError, match="ambiguous: groups arm, gripper") as e:
        srdf.named_state("home")
    assert "set group" in e.value.hint
    with pytest.raises(SrdfError, match="group 'arm' has no named state 'open'") as e:
        srdf.named_state("open", "arm")
    assert "gripper" in e.value.hint
    assert set(srdf.labelled_states()) == {"arm/home", "gripper/home", "open"}


def test_pairs_naming_lost_links_are_skipped_with_a_warning(desc):
    srdf = parse_srdf(COURSE_SRDF, desc.robot)
    assert srdf.disabled_pairs() == {frozenset(("base_link", "base_plate"))}
    assert len(srdf.warnings) == 1 and "old_camera" in srdf.warnings[0]


def test_a_subgroup_cycle_is_an_error(desc):
    text = ('<robot name="a"><group name="x"><group name="y"/></group>'
            '<group name="y"><group name="x"/></group></robot>')
    with pytest.raises(SrdfError, match="cycle"):
        parse_srdf(text, desc.robot)
