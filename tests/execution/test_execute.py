"""Executing trajectories: the executor on the MuJoCo twin, and end to end through a real
`arduinobot serve` and `arduinobot execute` processes (cancel and a lost client)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from arduinobot.execution.executor import ExecuteOptions, Executor, NotAtStart
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.service.process.disk_cache import DiskCache
from tests.helpers.serve import REPO, start_server

#: the twin's mesh pieces, computed once per machine as the command line keeps them
CACHE = DiskCache()


@pytest.fixture(scope="module")
def planned(desc):
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
    mp = MotionPlanner(desc)
    return {name: mp.solve(MotionRequest(goal=NamedGoal(name), seed=11)).trajectory
            for name in ("reach_left", "reach_forward")}


def wait_until(pred, timeout: float = 30.0, what: str = "condition"):
    """Poll ``pred()`` until it holds (returns its value); the timeout only bounds a
    failure, it synchronises nothing."""
    end = time.monotonic() + timeout
    while not (got := pred()):
        assert time.monotonic() < end, f"{what} never held"
        time.sleep(0.005)
    return got


def _body(traj):
    return {"trajectory": traj.to_dict()}


def check_within_limits(report, lim, tol=1e-9):
    """Commanded velocity, acceleration and (finite-difference) jerk within the limits."""
    assert report.peak_ratio["velocity"] <= 1 + tol
    assert report.peak_ratio["acceleration"] <= 1 + tol
    assert report.peak_ratio["jerk"] <= 1 + 1e-6
    assert np.all(report.q >= lim.lower - 1e-9) and np.all(report.q <= lim.upper + 1e-9)


@pytest.mark.parametrize("at", [0.2, 0.5, 0.8])
def test_cancel_stops_at_rest_within_a_second_and_the_limits(desc, planned, at):
    traj = planned["reach_left"]
    cancel = threading.Event()
    sim = SimArduinobot(desc, cache=CACHE)

    def on_tick(tick):
        if tick.phase == "trajectory" and tick.trajectory_time >= traj.duration * at:
            cancel.set()
    ex = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False),
                                  on_tick=on_tick)
    rep = ex.execute(SampledTrajectory.from_json(_body(traj)), cancel=cancel)
    assert rep.outcome == "cancelled"
    assert rep.cancelled_at == pytest.approx(traj.duration * at, abs=0.011)
    stop = np.array(rep.phases) == "stop"
    i0 = int(np.argmax(stop))
    assert np.abs(rep.qd[i0 - 1]).max() > 0.5  # it was moving fast when cancelled
    # braking stays on the planned (collision-checked) path: every stop position is one
    dense = traj.evaluate(np.linspace(0, traj.duration, 20001))[0]
    gap = max(np.min(np.abs(dense - q).max(axis=1)) for q in rep.q[stop])
    assert gap < 1e-3
    assert ex.last_stop in ("path", "finish")  # no need to leave the path here
    if at < 0.5:  # early on, braking on the path stops well short of the goal
        assert ex.last_stop == "path"
        assert np.abs(rep.q[-1] - traj.positions[-1]).max() > 0.05
    assert rep.stop_time < 1.0
    t_rest = rep.times[-1] - rep.times[i0 - 1]
    assert t_rest < 1.0
    assert np.abs(rep.qd[-1]).max() < 1e-9 and np.abs(rep.qdd[-1]).max() < 1e-9
    assert np.abs(rep.measured_velocity[-1]).max() < 0.01  # the twin is at rest too
    check_within_limits(rep, ex.limits)
    st = sim.stats()
    assert max(f / e for f, e in zip(st.peak_force, st.effort)) < 1.0
    assert st.saturated_steps == 0
    # the switch is smooth: the velocity changes by no more than one tick's acceleration
    dv = np.abs(rep.qd[i0] - rep.qd[i0 - 1])
    assert np.all(dv <= ex.limits.acceleration * 0.01 + 1e-9)
    print(f"\ncancel at {rep.cancelled_at:.3f} s (|v| up to {np.abs(rep.qd[i0 - 1]).max():.2f} "
          f"rad/s): {ex.last_stop} stop, commanded at rest after {rep.stop_time:.3f} s; "
          f"peaks {rep.peak_ratio}; peak force {np.round(st.peak_force, 2)}")


def test_a_halt_stops_on_the_path_as_stopped_and_says_where_it_rests(desc, planned):
    """The halt of a scene change (service/execute/react.py): the cancel's stop, its own
    outcome, and the trajectory time it rests at, on the path."""
    traj = planned["reach_left"]
    halt = threading.Event()
    sim = SimArduinobot(desc, cache=CACHE)

    def on_tick(tick):
        if tick.phase == "trajectory" and tick.trajectory_time >= traj.duration * 0.3:
            halt.set()
    ex = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False),
                                  on_tick=on_tick)
    ex.warm_stops()  # the first stop's choice, ahead (nothing moves)
    assert np.abs(sim.state().actuated(sim.joint_names) - traj.positions[0]).max() < 1e-9
    rep = ex.execute(SampledTrajectory.from_json(_body(traj)), halt=halt)
    assert rep.outcome == "stopped"
    assert ex.last_stop == "path"
    assert rep.cancelled_at < ex.last_stop_end < traj.duration
    # it rests where the trajectory is at that time: on the path
    assert np.abs(rep.q[-1] - traj.evaluate(ex.last_stop_end)[0]).max() < 1e-6
    assert ex.stop_sent is not None
    check_within_limits(rep, ex.limits)


def test_refuses_a_start_elsewhere_and_moves_there_on_request(desc, planned):
    traj = SampledTrajectory.from_json(_body(planned["reach_forward"]))
    sim = SimArduinobot(desc, cache=CACHE, initial=[0.5, 0.2, -0.3, 0.0])
    ex = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False))
    with pytest.raises(NotAtStart, match="move-to-start") as e:
        ex.execute(traj)
    assert e.value.details["joint"] == "joint_1"
    assert sim.stats().steps == 0  # nothing moved
    ex = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False,
                                                                     move_to_start=True))
    rep = ex.execute(traj)
    assert rep.outcome == "completed"
    assert "move_to_start" in rep.phases
    check_within_limits(rep, ex.limits)
    assert np.abs(rep.measured[-1] - planned["reach_forward"].positions[-1]).max() < 1e-3


def test_replay_at_another_rate_follows_the_exact_trajectory(planned):
    exact = planned["reach_left"]
    traj = SampledTrajectory.from_json(_body(exact))
    for t in np.linspace(0, exact.duration, 97):
        q, qd, qdd = traj.evaluate(float(t))
        p = exact.at(float(t))
        assert q == pytest.approx(p.positions, abs=1e-6)
        assert qd == pytest.approx(p.velocities, abs=1e-4)
        assert qdd == pytest.approx(p.accelerations, abs=0.05)


# -- end to end: serve + execute processes ---------------------------------------------
@pytest.fixture(scope="module")
def served():
    srv = start_server(["--workers", "1"])
    yield srv
    srv.stop()


class StateListener:
    """Every <prefix>/joint_states message with its arrival time."""

    def __init__(self, endpoint: str) -> None:
        import zenoh

        from arduinobot.contract.zconfig import zenoh_config
        self.session = zenoh.open(zenoh_config(mode="client", connect=[endpoint], listen=[]))
        self.msgs: list[tuple[float, dict]] = []
        self.sub = self.session.declare_subscriber(
            "arduinobot/joint_states",
            lambda s: self.msgs.append((time.monotonic(), json.loads(s.payload.to_bytes()))))

    def wait(self, pred, timeout: float = 30.0) -> float:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for t, m in list(self.msgs):
                if pred(m):
                    return t
            time.sleep(0.005)
        raise AssertionError("condition never met on joint_states")

    def close(self) -> None:
        self.sub.undeclare()
        self.session.close()


def _execute(endpoint: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "arduinobot.cli.main", "execute", "--remote",
                             "--connect", endpoint, *args], cwd=REPO,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _at_rest(msgs, after: float) -> float | None:
    """Arrival time of the first message after ``after`` from which every later one has
    all |velocity| < 0.01 rad/s (None if it never comes to rest)."""
    later = [(t, m) for t, m in msgs if t >= after]
    rest = None
    for t, m in later:
        if max(abs(v) for v in m["velocity"]) < 0.01:
            rest = rest if rest is not None else t
        else:
            rest = None
    return rest


# [s] one state-stream tick of the simulated robot (100 Hz) and some rounding
TICK = 0.02


def _stop_to_rest(msgs, after: float) -> float:
    """Robot-clock seconds (``stamp``) from the first "stop" state after ``after`` to the
    state from which it stays at rest (see :func:`_at_rest`)."""
    later = [m for t, m in msgs if t >= after]
    first = next(m["stamp"] for m in later if m["phase"] == "stop")
    rest = None
    for m in later:
        if max(abs(v) for v in m["velocity"]) < 0.01:
            rest = rest if rest is not None else m["stamp"]
        else:
            rest = None
    assert rest is not None
    return rest - first


@pytest.mark.slow
def test_cancel_through_serve_and_execute(served, tmp_path):
    lis = StateListener(served.endpoint)
    try:
        out = tmp_path / "report.json"
        proc = _execute(served.endpoint, "--named", "reach_left", "--report", str(out))
        lis.wait(lambda m: m["phase"] == "trajectory" and m["progress"] >= 0.5)
        t_cancel = time.monotonic()
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=30)
        assert proc.returncode == 130, stderr
        rep = json.loads(out.read_text())
        assert rep["outcome"] == "cancelled"
        assert rep["stop_time"] < 1.0
        assert all(v <= 1 + 1e-6 for v in rep["peak_ratio"].values()), rep["peak_ratio"]
        # the stop's states at rest have arrived (the stream's, not a guessed delay)
        wait_until(lambda: _at_rest(lis.msgs, t_cancel) is not None
                   and lis.msgs[-1][1]["phase"] in ("stop", "settle"), what="rest")
        rest = _at_rest(lis.msgs, t_cancel)
        assert rest is not None, lis.msgs[-3:]
        # on the robot's own clock (the stamps, not this busy machine's wall clock): at
        # rest within the reported stop time of the stop's first state
        assert _stop_to_rest(lis.msgs, t_cancel) <= rep["stop_time"] + TICK
        assert lis.msgs[-1][1]["phase"] in ("stop", "settle")
        print(f"\nserve+execute: SIGINT at 50%, joint_states at rest "
              f"{rest - t_cancel:.3f} s later; stop {rep['stop_time']:.3f} s; "
              f"peaks {rep['peak_ratio']}")
    finally:
        lis.close()


@pytest.mark.slow
def test_a_lost_client_stops_the_arm(served):
    lis = StateListener(served.endpoint)
    try:
        proc = _execute(served.endpoint, "--named", "reach_right")
        try:
            lis.wait(lambda m: m["phase"] == "trajectory" and m["progress"] >= 0.4)
        except AssertionError:
            proc.kill()
            raise AssertionError(proc.communicate()) from None
        t_kill = time.monotonic()
        proc.kill()  # no cancel sent: only its liveliness token disappears
        proc.wait(10)
        lis.wait(lambda m: m["phase"] == "stop", timeout=5)
        # the stop runs to rest on the robot's own clock: wait for its at-rest states
        wait_until(lambda: _at_rest(lis.msgs, t_kill) is not None
                   and lis.msgs[-1][1]["phase"] in ("stop", "settle"), what="rest")
        rest = _at_rest(lis.msgs, t_kill)
        assert rest is not None, [(round(t - t_kill, 3), m["phase"], m["velocity"])
                                  for t, m in lis.msgs[-5:]]
        assert _stop_to_rest(lis.msgs, t_kill) < 1.0  # the brake itself, robot clock
        assert lis.msgs[-1][1]["phase"] in ("stop", "settle")
        # the robot is free again: the next execution runs to the end
        proc = _execute(served.endpoint, "--named", "home")
        stdout, stderr = proc.communicate(timeout=60)
        assert proc.returncode == 0, stderr
        assert stdout.startswith("completed")
        print(f"\nlost client: killed at 40%, at rest {rest - t_kill:.3f} s later")
    finally:
        lis.close()


@pytest.mark.slow
def test_a_new_goal_blends_in_through_serve(served, tmp_path):
    lis = StateListener(served.endpoint)
    try:
        slow = tmp_path / "slow.json"  # a long motion to blend out of
        slow.write_text(json.dumps({"goal": {"joints": {"joint_1": -1.0, "joint_2": 0.3,
                                                        "joint_3": 0.5}},
                                    "velocity_scaling": 0.03,
                                    "acceleration_scaling": 0.03}))
        out = tmp_path / "report.json"
        first = _execute(served.endpoint, "--request", str(slow), "--report", str(out))
        lis.wait(lambda m: m["phase"] == "trajectory" and 0.1 <= m["progress"] < 0.5)
        second = _execute(served.endpoint, "--named", "home", "--blend")
        stdout2, stderr2 = second.communicate(timeout=60)
        assert second.returncode == 0, stderr2
        assert stdout2.startswith("blended into x")
        stdout, stderr = first.communicate(timeout=60)
        assert first.returncode == 0, stderr
        rep = json.loads(out.read_text())
        assert rep["outcome"] == "completed"
        assert rep["final_positions"][:3] == pytest.approx([0, 0, 0], abs=2e-3)  # home
        assert all(v <= 1 + 1e-6 for v in rep["peak_ratio"].values()), rep["peak_ratio"]
        # the published motion never jumps: consecutive ticks within a tick's motion
        qs = np.array([m["position"][:4] for _, m in lis.msgs])
        assert np.abs(np.diff(qs, axis=0)).max() <= 10.0 * 0.01 + 1e-6
    finally:
        lis.close()


def test_execute_cli_on_the_local_twin(planned, tmp_path):
    f = tmp_path / "traj.json"
    f.write_text(json.dumps({"trajectory": planned["reach_forward"].to_dict()}))
    run = [sys.executable, "-m", "arduinobot.cli.main", "execute", str(f), "--sim", "--fast",
           "--no-publish"]
    r = subprocess.run(run, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "completed" in r.stdout and "torque needed / servo peak / limit" in r.stdout
    moved = dict(planned["reach_forward"].to_dict())
    moved["points"] = [{**p, "positions": [0.3, *p["positions"][1:]]} for p in moved["points"]]
    f.write_text(json.dumps(moved))
    r = subprocess.run(run, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    assert "NOT_AT_START" in r.stderr and "--move-to-start" in r.stderr


def test_a_new_goal_while_moving_blends_in_without_a_jump(desc):
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
    mp = MotionPlanner(desc)
    first = mp.solve(MotionRequest(goal=NamedGoal("reach_left"), seed=11)).trajectory
    sim = SimArduinobot(desc, cache=CACHE)
    done = []

    def on_tick(tick):
        if done or tick.phase != "trajectory" or tick.progress < 0.3:
            return
        k, q, qd, qdd = ex.lookahead(0.2)
        names = ex.robot.joint_names
        new = mp.solve(MotionRequest(goal=NamedGoal("reach_right"), seed=12,
                                     start=dict(zip(names, q.tolist())),
                                     start_velocity=dict(zip(names, qd.tolist())),
                                     start_acceleration=dict(zip(names, qdd.tolist()))))
        ex.switch(SampledTrajectory.from_json({"trajectory": new.trajectory.to_dict()}), k)
        done.append((k, new.trajectory))
        with pytest.raises(Exception, match="has passed"):
            ex.switch(SampledTrajectory.from_json({"trajectory": new.trajectory.to_dict()}),
                      tick.index)
    ex = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False),
                                  on_tick=on_tick)
    rep = ex.execute(SampledTrajectory.from_json(_body(first)))
    assert rep.outcome == "completed" and ex.blends == 1
    k, new = done[0]
    # the switch tick commands the new trajectory's first state, the one before the old's
    assert rep.q[k] == pytest.approx(new.positions[0], abs=1e-12)
    dv = np.abs(np.diff(rep.qd, axis=0)).max(axis=0)
    assert np.all(dv <= ex.limits.acceleration * 0.01 * (1 + 1e-6))  # no velocity jump
    check_within_limits(rep, ex.limits)
    right = desc.srdf.named_state("reach_right").values
    assert rep.measured[-1][:3] == pytest.approx([right[n] for n in rep.joint_names[:3]],
                                                 abs=2e-3)
    st = sim.stats()
    # what the blended motion asks of the motors is within their effort; the servos'
    # feedback on top of a plan at ~99% effort touches the limit for a few ms at most
    assert max(f / e for f, e in zip(st.peak_feedforward, st.effort)) <= 1 + 1e-3
    assert st.saturated_steps <= 0.02 * st.steps


@pytest.mark.slow
def test_the_viewer_follows_a_running_execute(served, desc):
    pytest.importorskip("viser")  # the `view` extra
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.follow import JointStateFollower
    from tests.helpers.serve import free_port
    viewer = RobotViewer(desc, port=free_port())
    follower = JointStateFollower(viewer, served.endpoint)
    try:
        t0 = time.monotonic()
        proc = _execute(served.endpoint, "--named", "reach_forward")
        stdout, stderr = proc.communicate(timeout=60)
        assert proc.returncode == 0, stderr
        goal = desc.srdf.named_state("reach_forward").values
        want = np.array([goal[n] for n in viewer.joint_names[:3]])
        wait_until(lambda: np.abs(np.asarray(viewer.q[:3]) - want).max() <= 2e-3,
                   what="the viewer at the goal")
        elapsed = time.monotonic() - t0
        assert 5 <= follower.shown <= 30 * elapsed + 1  # throttled to 30 Hz
    finally:
        follower.close()
        viewer.close()


# -- the service's robot through the Python client ---------------------------------------
SLOW_PLAN = {"goal": {"named": "reach_left"}, "velocity_scaling": 0.05,
             "acceleration_scaling": 0.05, "seed": 5}


@pytest.mark.slow
def test_a_second_execute_while_moving_is_busy_and_another_client_cancels_it(served):
    from arduinobot.client.client import PlannerClient
    from arduinobot.client.errors import ServiceBusy

    events, outcome = [], {}
    started = threading.Event()

    def on_event(ev):
        events.append(ev)
        if ev.event == "started":
            started.set()

    def run():
        with PlannerClient(served.endpoint, timeout=30) as c1:
            try:
                outcome["done"] = c1.execute(plan=SLOW_PLAN, on_event=on_event)
            except Exception as e:  # noqa: BLE001 -- asserted below
                outcome["error"] = e
    t = threading.Thread(target=run)
    t.start()
    try:
        assert started.wait(60), outcome
        execution = events[0].execution
        with PlannerClient(served.endpoint, timeout=30) as c2:
            # the arm is moving: a second execution is refused, naming the running one
            with pytest.raises(ServiceBusy) as e:
                c2.execute(plan={"goal": {"named": "home"}})
            assert e.value.details["execution"] == execution
            wait_until(lambda: any(ev.event == "progress" for ev in events),
                       what="a progress event")
            # another client stops it by its id; a wrong id stops nothing
            assert c2.cancel_execution("x999") is None
            assert c2.cancel_execution(execution) == execution
    finally:
        t.join(60)
    assert "error" not in outcome, outcome
    done = outcome["done"]
    assert done.event == "finished" and done.execution == execution
    assert done.report["outcome"] == "cancelled" and done.report["stop_time"] < 1.0
    kinds = [ev.event for ev in events]
    assert kinds[0] == "started" and kinds[-1] == "finished" and "progress" in kinds
    # the arm is free again: the next execution runs to its end
    with PlannerClient(served.endpoint, timeout=30) as c:
        assert c.execute(plan={"goal": {"named": "home"}}).report["outcome"] == "completed"
