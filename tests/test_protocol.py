"""The protocol files are robo-gym's contract and the committed generated code matches them."""

from __future__ import annotations

from pathlib import Path

import pytest

from robogym_ray.protocol import regen
from robogym_ray.protocol import robot_server_pb2 as rs
from robogym_ray.protocol import server_manager_pb2 as sm


def test_regeneration_gives_the_committed_files(tmp_path: Path) -> None:
    pytest.importorskip("grpc_tools")
    for fresh in regen.regenerate(tmp_path):
        committed = regen.PROTO_DIR / fresh.name
        assert committed.read_text() == fresh.read_text(), f"{fresh.name} is stale: run regen"


def fields(message: type) -> dict[str, tuple[int, int]]:
    return {f.name: (f.number, f.type) for f in message.DESCRIPTOR.fields}


def test_robot_server_schema_matches_robo_gym() -> None:
    svc = rs.DESCRIPTOR.services_by_name["RobotServer"]
    assert rs.DESCRIPTOR.package == "robot_server"
    assert {m.name: (m.input_type.name, m.output_type.name) for m in svc.methods} == {
        "GetState": ("Empty", "State"),
        "SetState": ("State", "Success"),
        "SendAction": ("Action", "Success"),
        "SendActionGetState": ("Action", "State"),
        # robo-gym-server-modules' master (after 0.3.0.1): tests/compat/test_get_arguments.py
        "GetArguments": ("Empty", "Arguments"),
        # Ours: a hardware server's recover_from_errors (tests/distributed/test_franky_robot.py);
        # robo-gym's servers answer it UNIMPLEMENTED (tests/compat/test_get_arguments.py).
        "RecoverFromErrors": ("Empty", "Success"),
    }
    t = rs.Arguments.DESCRIPTOR.fields[0]
    assert fields(rs.Arguments) == {
        "action_cycle_rate": (1, t.TYPE_FLOAT),
        "rs_mode": (2, t.TYPE_STRING),
        "action_mode": (3, t.TYPE_STRING),
        "success": (4, t.TYPE_BOOL),
    }
    f = rs.State.DESCRIPTOR.fields_by_name
    assert [
        (n, f[n].number)
        for n in ("state", "float_params", "string_params", "state_dict", "success")
    ] == [
        ("state", 1),
        ("float_params", 2),
        ("string_params", 3),
        ("state_dict", 4),
        ("success", 5),
    ]
    assert f["state"].type == f["state"].TYPE_FLOAT  # float32 on the wire
    assert fields(rs.Action)["action"][0] == 1 and fields(rs.Action)["success"][0] == 2
    assert fields(rs.Success) == {"success": (1, rs.Success.DESCRIPTOR.fields[0].TYPE_BOOL)}


def test_server_manager_schema_matches_robo_gym() -> None:
    assert sm.DESCRIPTOR.package == "robo_gym_server_manager.grpc_msgs.server_manager"
    svc = sm.DESCRIPTOR.services_by_name["ServerManager"]
    assert [m.name for m in svc.methods] == [
        "StartNewServer",
        "KillServer",
        "KillAllServers",
        "VerifyConnection",
    ]
    assert {n: v[0] for n, v in fields(sm.RobotServer).items()} == {
        "cmd": 1,
        "gui": 2,
        "port": 3,
        "success": 4,
        "info": 5,
    }
    assert fields(sm.Status)["alive"][0] == 1
    assert svc.methods_by_name["VerifyConnection"].input_type.full_name.endswith(
        "server_manager.Empty"
    )
