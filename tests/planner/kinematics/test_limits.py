"""Joint limits: URDF and joint_limits.yaml figures, the derivation rules, each error."""

from __future__ import annotations

import dataclasses
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from arduinobot.contract.errors import InvalidRequest, LimitsError
from arduinobot.description import InvalidModel, load_description
from arduinobot.planner.kinematics.dynamics import InverseDynamics
from arduinobot.planner.kinematics.limits import (
    ACCELERATION_MARGIN,
    DERIVATION_SAMPLES,
    DERIVATION_SEED,
    JERK_RAMP_TIME,
    JointLimits,
    derive_accelerations,
)

ARM = ("joint_1", "joint_2", "joint_3", "joint_4")
FULL = {"has_velocity_limits": True, "max_velocity": 10.0, "has_acceleration_limits": True,
        "max_acceleration": 20.0, "has_jerk_limits": True, "max_jerk": 200.0}


def with_yaml(desc, **entries):
    cfg = {n: dict(FULL) for n in ARM}
    for name, entry in entries.items():
        cfg[name] = entry
    return dataclasses.replace(desc, joint_limits=cfg)


def test_shipped_limits_and_sources(desc):
    lim = JointLimits.from_description(desc)
    assert lim.joint_names == ARM and lim.dof == 4
    np.testing.assert_allclose(lim.lower, [-1.570795] * 3 + [-1.570795])
    np.testing.assert_allclose(lim.upper, [1.570795] * 3 + [0.0])
    np.testing.assert_allclose(lim.velocity, 10.0)
    np.testing.assert_allclose(lim.acceleration, 20.0)
    np.testing.assert_allclose(lim.jerk, 200.0)
    np.testing.assert_allclose(lim.effort, 30.0)
    assert lim.sources["joint_2.acceleration"] == "config/joint_limits.yaml"
    assert lim.sources["joint_2.jerk"] == "config/joint_limits.yaml"
    assert lim.sources["joint_2.effort"] == "urdf"
    assert lim.sources["joint_1.lower"] == "urdf"
    with pytest.raises(ValueError):
        lim.velocity[0] = 1.0  # frozen arrays
    with pytest.raises(TypeError):
        lim.sources["x"] = "y"  # type: ignore[index]


def test_scaling_and_jerk_follows_acceleration(desc):
    lim = JointLimits.from_description(desc, velocity_scaling=0.5, acceleration_scaling=0.25)
    np.testing.assert_allclose(lim.velocity, 5.0)
    np.testing.assert_allclose(lim.acceleration, 5.0)
    np.testing.assert_allclose(lim.jerk, 50.0)
    assert "0.25" in lim.sources["scaling"]


@pytest.mark.parametrize("field,value", [("velocity_scaling", 0.0), ("velocity_scaling", 1.5),
                                         ("acceleration_scaling", -0.1),
                                         ("acceleration_scaling", float("nan")),
                                         ("velocity_scaling", True)])
def test_scaling_out_of_range(desc, field, value):
    with pytest.raises(InvalidRequest) as e:
        JointLimits.from_description(desc, **{field: value})
    assert e.value.field == field


def test_yaml_velocity_may_only_tighten(desc):
    tight = with_yaml(desc, joint_1=dict(FULL, max_velocity=4.0),
                      joint_2=dict(FULL, max_velocity=25.0))
    lim = JointLimits.from_description(tight)
    assert lim.velocity[0] == 4.0
    assert lim.sources["joint_1.velocity"] == "config/joint_limits.yaml"
    assert lim.velocity[1] == 10.0  # the URDF's, not the looser 25
    assert "looser" in lim.sources["joint_2.velocity"]
    no_yaml = with_yaml(desc, joint_3=dict(FULL, has_velocity_limits=False))
    assert JointLimits.from_description(no_yaml).sources["joint_3.velocity"] == "urdf"


def test_missing_acceleration_is_derived_by_the_rule(desc):
    entry = {"has_velocity_limits": True, "max_velocity": 10.0}
    d = with_yaml(desc, joint_2=entry)
    lim = JointLimits.from_description(d)
    assert lim.sources["joint_2.acceleration"].startswith("derived:")
    assert str(DERIVATION_SAMPLES) in lim.sources["joint_2.acceleration"]
    # recompute the rule independently
    dyn = InverseDynamics(desc.robot)
    rng = np.random.default_rng(DERIVATION_SEED)
    bounds = desc.robot.position_limits()
    qs = rng.uniform(bounds[:, 0], bounds[:, 1], size=(DERIVATION_SAMPLES, 4))
    g = max(abs(dyn.gravity(q)[1]) for q in qs[::1])
    m = max(dyn.mass_matrix(q)[1, 1] for q in qs)
    expected = ACCELERATION_MARGIN * (30.0 - g) / m
    assert lim.acceleration[1] == pytest.approx(expected, rel=1e-12)
    assert 0 < lim.acceleration[1] < 30.0 / m
    # jerk derives from it too, since the entry has no jerk either
    assert lim.jerk[1] == pytest.approx(expected / JERK_RAMP_TIME, rel=1e-12)
    assert lim.sources["joint_2.jerk"].startswith("derived: acceleration / 0.1 s")
    # the other joints keep their yaml figures
    assert lim.acceleration[0] == 20.0


def test_has_acceleration_limits_false_is_derived_not_unlimited(desc):
    d = with_yaml(desc, joint_1=dict(FULL, has_acceleration_limits=False))
    lim = JointLimits.from_description(d)
    assert np.isfinite(lim.acceleration[0])
    assert lim.sources["joint_1.acceleration"].startswith("derived:")
    assert lim.sources["joint_1.jerk"] == "config/joint_limits.yaml"


def test_missing_jerk_is_derived_from_yaml_acceleration(desc):
    d = with_yaml(desc, joint_4=dict(FULL, has_jerk_limits=False))
    lim = JointLimits.from_description(d, acceleration_scaling=0.5)
    assert lim.jerk[3] == pytest.approx(0.5 * 20.0 / JERK_RAMP_TIME)
    assert "config/joint_limits.yaml" in lim.sources["joint_4.jerk"]


@pytest.mark.parametrize("entry,limit", [
    (dict(FULL, max_acceleration=-1.0), "acceleration"),
    (dict(FULL, max_jerk="fast"), "jerk"),
    (dict(FULL, has_jerk_limits="yes"), "jerk"),
    (dict(FULL, max_velocity=0.0), "velocity"),
    ({"has_acceleration_limits": True}, "acceleration"),
])
def test_malformed_yaml_entries(desc, entry, limit):
    with pytest.raises(LimitsError) as e:
        JointLimits.from_description(with_yaml(desc, joint_3=entry))
    assert e.value.code == "INVALID_LIMITS"
    assert e.value.details == {"joint": "joint_3", "limit": limit}


def test_subset_and_joint_names(desc):
    lim = JointLimits.from_description(desc, joint_names=("joint_3", "joint_1"))
    assert lim.joint_names == ("joint_3", "joint_1")
    full = JointLimits.from_description(desc)
    sub = full.subset(("joint_2",))
    assert sub.joint_names == ("joint_2",) and sub.velocity.shape == (1,)
    assert set(sub.sources) == {f"joint_2.{k}" for k in
                                ("lower", "upper", "velocity", "acceleration", "jerk",
                                 "effort")} | {"scaling"}
    with pytest.raises(InvalidRequest):
        JointLimits.from_description(desc, joint_names=("joint_5",))  # a mimic
    with pytest.raises(InvalidRequest):
        full.subset(("nope",))


_URDF = """\
<?xml version="1.0"?>
<robot name="weak">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0.5 0 0"/><mass value="{mass}"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="tip"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="{effort}" velocity="{velocity}"/>
  </joint>
  <joint name="wrist" type="revolute">
    <parent link="arm"/><child link="tip"/><origin xyz="1 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="5" velocity="2"/>
  </joint>
</robot>
"""


def _robot(tmp_path, *, mass=2.0, effort=30.0, velocity=1.0):
    path = tmp_path / "weak.urdf"
    path.write_text(textwrap.dedent(_URDF).format(mass=mass, effort=effort,
                                                  velocity=velocity))
    return load_description(path)


def test_derived_acceleration_for_a_robot_without_yaml(tmp_path):
    d = _robot(tmp_path)
    assert d.joint_limits == {}
    # wrist moves no mass (tip has no inertial): no rule applies
    with pytest.raises(LimitsError) as e:
        JointLimits.from_description(d)
    assert e.value.joint == "wrist" and e.value.limit == "acceleration"
    assert "no mass" in str(e.value)
    lim = JointLimits.from_description(d, joint_names=("shoulder",))
    # 2 kg at 0.5 m: worst gravity torque 2*9.81*0.5 at q ~ 0; inertia 0.01 + 2*0.25 = 0.51
    g_max = max(abs(2 * 9.81 * 0.5 * np.cos(q)) for q in
                np.random.default_rng(DERIVATION_SEED).uniform([-1, -1], [1, 1],
                                                               (DERIVATION_SAMPLES, 2))[:, 0])
    assert lim.acceleration[0] == pytest.approx(0.5 * (30.0 - g_max) / 0.51, rel=1e-9)
    assert lim.jerk[0] == pytest.approx(lim.acceleration[0] / JERK_RAMP_TIME)
    assert derive_accelerations(d, ["shoulder"])[0] == pytest.approx(lim.acceleration[0])


def test_effort_below_gravity_cannot_derive(tmp_path):
    d = _robot(tmp_path, effort=5.0)
    with pytest.raises(LimitsError) as e:
        JointLimits.from_description(d, joint_names=("shoulder",))
    assert e.value.details["gravity_torque"] > 5.0
    assert "gravity" in str(e.value)


def test_no_effort_or_velocity_is_an_error(tmp_path):
    with pytest.raises(LimitsError) as e:
        JointLimits.from_description(_robot(tmp_path, effort=0.0), joint_names=("shoulder",))
    assert e.value.limit == "effort"
    with pytest.raises(LimitsError) as e:
        JointLimits.from_description(_robot(tmp_path, velocity=0.0),
                                     joint_names=("shoulder",))
    assert e.value.limit == "velocity"
    # a yaml velocity fills the gap
    d = _robot(tmp_path, velocity=0.0)
    d = dataclasses.replace(d, joint_limits={"shoulder": {"has_velocity_limits": True,
                                                          "max_velocity": 1.5}})
    lim = JointLimits.from_description(d, joint_names=("shoulder",))
    assert lim.velocity[0] == 1.5


def test_shape_checked_on_construction():
    with pytest.raises(InvalidRequest):
        JointLimits(("a",), *[np.zeros(2)] * 6)


# -- joint_limits.yaml min_position/max_position (issue 26 item 9) -----------------------------

def _limits_yaml(tmp_path: Path, entries: dict) -> Path:
    p = tmp_path / "joint_limits.yaml"
    p.write_text(yaml.safe_dump({"joint_limits": entries}))
    return p


def test_min_max_position_narrow_the_urdf_range_everywhere(tmp_path):
    p = _limits_yaml(tmp_path, {"joint_2": {"min_position": -0.5, "max_position": 0.25},
                                "joint_1": {"max_position": 1.0}})
    d = load_description(joint_limits=p, env={})
    lim = d.robot.position_limits(("joint_1", "joint_2", "joint_3"))
    np.testing.assert_allclose(lim[0], [-np.pi / 2, 1.0], atol=1e-5)
    np.testing.assert_allclose(lim[1], [-0.5, 0.25])
    np.testing.assert_allclose(lim[2], [-np.pi / 2, np.pi / 2], atol=1e-5)
    jl = JointLimits.from_description(d)
    i2 = jl.joint_names.index("joint_2")
    assert (jl.lower[i2], jl.upper[i2]) == (-0.5, 0.25)
    assert jl.sources["joint_2.lower"] == jl.sources["joint_2.upper"] == \
        jl.sources["joint_1.upper"] == "config/joint_limits.yaml"
    assert jl.sources["joint_1.lower"] == "urdf"
    assert not d.warnings


def test_a_wider_position_range_keeps_the_urdfs_and_warns(tmp_path):
    p = _limits_yaml(tmp_path, {"joint_3": {"min_position": -3.0, "max_position": 3.0}})
    d = load_description(joint_limits=p, env={})
    np.testing.assert_allclose(d.robot.position_limits(("joint_3",))[0],
                               [-np.pi / 2, np.pi / 2], atol=1e-5)
    assert len(d.warnings) == 2
    assert "min_position -3" in d.warnings[0] and "max_position 3" in d.warnings[1]


def test_an_empty_or_malformed_position_range_is_refused(tmp_path):
    with pytest.raises(InvalidModel, match="empty range"):
        load_description(joint_limits=_limits_yaml(
            tmp_path, {"joint_1": {"min_position": 0.5, "max_position": 0.4}}), env={})
    with pytest.raises(InvalidModel) as e:
        load_description(joint_limits=_limits_yaml(
            tmp_path, {"joint_1": {"max_position": "high"}}), env={})
    assert e.value.element == "joint_limits.joint_1.max_position"


def test_check_reports_a_position_range_it_cannot_apply(tmp_path):
    from arduinobot.description.checks import check_model
    p = _limits_yaml(tmp_path, {"joint_3": {"max_position": 3.0}})
    report = check_model(joint_limits=p, env={})
    warns = [f for f in report.findings if f.check == "joint_limits"]
    assert len(warns) == 1 and "max_position 3" in warns[0].message
    bad = _limits_yaml(tmp_path, {"joint_1": {"min_position": 1.0, "max_position": 0.0}})
    assert check_model(joint_limits=bad, env={}).failed
