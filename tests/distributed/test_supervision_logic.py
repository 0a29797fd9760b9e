"""The supervisor's plain classes without Ray: restart policy, launch parsing, state checks, and
the Supervisor over in-process servers."""

from __future__ import annotations

import pytest

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.supervision.health import check_state
from robogym_ray.supervision.launch import parse_launch_cmd
from robogym_ray.supervision.restart_policy import FaultCause, RestartBook, RestartPolicy
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.spawners import InProcessSpawner
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

SP = " " * 9


def test_restart_book_counts_per_cause_backs_off_and_gives_up() -> None:
    book = RestartBook(RestartPolicy(max_restarts=3, window_s=10, backoff_s=1, backoff_factor=2))
    delays = [book.record(c, t).delay_s for c, t in (("connection", 0), ("nan", 1), ("hang", 2))]
    assert delays == [0.0, 1.0, 2.0]
    assert book.record("manual", 3).restart  # manual restarts never count against the limit
    final = book.record("deadline", 4)
    assert not final.restart and book.given_up
    assert "given up after 3 restarts" in final.message and "deadline" in final.message
    assert dict(book.counts) == {"connection": 1, "invalid_state": 1, "hung": 1, "manual": 1}


def test_restart_window_forgets_old_faults() -> None:
    book = RestartBook(RestartPolicy(max_restarts=1, window_s=10))
    assert book.record("hung", 0).restart
    assert book.record("hung", 20).restart  # the first one left the window
    assert not book.record("hung", 21).restart


@pytest.mark.parametrize(
    ("text", "cause"),
    [
        ("connection", FaultCause.CONNECTION),
        ("deadline", FaultCause.DEADLINE),
        ("hang", FaultCause.HUNG),
        ("nan", FaultCause.INVALID_STATE),
        ("manual", FaultCause.MANUAL),
        ("rejected", FaultCause.OTHER),
    ],
)
def test_reported_causes_map_to_the_five_faults(text: str, cause: FaultCause) -> None:
    assert FaultCause.parse(text) is cause


def test_robo_gym_cmd_strings_map_to_robots_and_options() -> None:
    mir = parse_launch_cmd("roslaunch mir100_robot_server sim_robot_server.launch")
    assert (mir.robot, mir.options) == ("mir100", {})
    ur = parse_launch_cmd(
        "roslaunch ur_robot_server ur_robot_server.launch"
        + SP
        + "world_name:=empty.world"
        + SP
        + "reference_frame:=base_link"
        + SP
        + "rviz_gui:=true"
        + SP
        + "gazebo_gui:=true"
        + SP
        + "rs_mode:=only_robot ur_model:=ur5"
    )
    assert ur.robot == "ur5"
    assert ur.options == {
        "world_name": "empty.world",
        "reference_frame": "base_link",
        "rs_mode": "only_robot",
    }
    with pytest.raises(UnknownRobotError, match="panda.launch"):
        parse_launch_cmd("roslaunch panda panda.launch")
    with pytest.raises(UnknownRobotError, match="ur_model"):
        parse_launch_cmd("roslaunch ur_robot_server ur_robot_server.launch")
    with pytest.raises(ConfigError):
        parse_launch_cmd("python serve.py")


def test_check_state_flags_nan_inf_and_out_of_limit_values() -> None:
    assert check_state(pb.State(state=[0.0, 1.0]), limit=10) is None
    assert "more than 1" in check_state(pb.State(state=[0.0]), limit=10)
    assert "nan" in check_state(pb.State(state=[0.0, float("nan")]), limit=10)
    assert "outside" in check_state(pb.State(state=[0.0, 11.0]), limit=10)
    assert "state_dict" in check_state(
        pb.State(state=[0.0, 1.0], state_dict={"x": float("inf")}), limit=10
    )


def test_in_process_supervisor_restarts_then_gives_up() -> None:
    config = SupervisorConfig(
        probe_interval_s=0, probe_deadline_s=0.5, restart=RestartPolicy(max_restarts=1)
    )
    sup = Supervisor(config, InProcessSpawner())
    try:
        sid = sup.start_server(ServerSpec("mir100", scene="empty"))["id"]
        sup.inject_fault(sid, "hang")
        assert sup.probe_once() == []  # one missed probe is not a hang yet
        assert sup.probe_once() == [(sid, "hung")]
        assert sup.info(sid)["restarts"] == {"hung": 1}
        sup.inject_fault(sid, "nan", persistent=True)
        assert sup.probe_once() == [(sid, "invalid_state")]
        info = sup.info(sid)
        assert info["state"] == "given_up" and "given up after 1 restarts" in info["message"]
        assert sup.kill(sid) and not sup.kill(sid)
    finally:
        sup.shutdown()


def test_a_dead_holders_leases_are_released_for_its_replacement() -> None:
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    spec = ServerSpec("mir100", scene="empty")
    try:
        first = sup.acquire(spec, holder="worker-0")
        other = sup.acquire(spec, holder="worker-1")
        assert first["id"] != other["id"] and first["holder"] == "worker-0"
        # worker-0 died without releasing: its server is released by holder, not restarted.
        assert sup.release_holder("worker-0") == 1 and sup.release_holder("worker-0") == 0
        assert sup.release_holder("") == 0  # an unnamed holder never matches
        again = sup.acquire(spec, holder="worker-0")
        assert again["id"] == first["id"] and again["address"] == first["address"]
        assert len(sup.status()) == 2  # the replacement reused the server: none leaked
        assert {s["holder"] for s in sup.status()} == {"worker-0", "worker-1"}
    finally:
        sup.shutdown()
