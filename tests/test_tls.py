"""TLS on robot servers and the server manager, with a CA and certificates made here.

Real gRPC servers on 127.0.0.1 (free ports), a MiR100 in PyBullet DIRECT; the certificates are
made in each test's tmp_path (nothing committed): a CA, a server certificate it signs for
127.0.0.1 and localhost (subjectAltName), and another CA that signed nothing of the server's.
"""

from __future__ import annotations

import datetime
import ipaddress
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import grpc
import gymnasium as gym
import numpy as np
import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.cli import main
from robogym_ray.errors import ConfigError, RobotServerError
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.protocol.tls import TlsError, open_channel, read_ca, server_tls
from robogym_ray.robots.server import RobotServerHandle, start_robot_server
from robogym_ray.supervision.manager_service import serve_manager
from robogym_ray.supervision.spawners import InProcessSpawner
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

TOKEN = "s3cret"
MIR_ROB = "RoboGymRay/NoObstacleNavigationMir100Rob-v0"


@dataclass(frozen=True)
class Pki:
    """PEM files: the CA, the server's certificate and key, and a CA unrelated to both."""

    ca: Path
    cert: Path
    key: Path
    other_ca: Path


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def _certificate(
    subject: str,
    key: ec.EllipticCurvePrivateKey,
    issuer: x509.Name,
    signer: ec.EllipticCurvePrivateKey,
    *,
    ca: bool,
) -> x509.Certificate:
    now = datetime.datetime.now(datetime.timezone.utc)
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(subject))
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True)
    )
    if not ca:  # what clients check the address they dialled against
        names = [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
        builder = builder.add_extension(x509.SubjectAlternativeName(names), critical=False)
    return builder.sign(signer, hashes.SHA256())


def _write_cert(path: Path, cert: x509.Certificate) -> Path:
    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return path


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> Path:
    path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return path


@pytest.fixture
def pki(tmp_path: Path) -> Pki:
    ca_key, server_key, other_key = (ec.generate_private_key(ec.SECP256R1()) for _ in range(3))
    ca = _certificate("test CA", ca_key, _name("test CA"), ca_key, ca=True)
    server = _certificate("localhost", server_key, ca.subject, ca_key, ca=False)
    other = _certificate("another CA", other_key, _name("another CA"), other_key, ca=True)
    return Pki(
        ca=_write_cert(tmp_path / "ca.pem", ca),
        cert=_write_cert(tmp_path / "server.pem", server),
        key=_write_key(tmp_path / "server.key", server_key),
        other_ca=_write_cert(tmp_path / "other-ca.pem", other),
    )


@pytest.fixture
def tls_server(pki: Pki) -> Iterator[RobotServerHandle]:
    """A MiR100 robot server over TLS that wants the token."""
    tls = server_tls(pki.cert, pki.key)
    handle = start_robot_server("mir100", scene="empty", seed=0, token=TOKEN, tls=tls)
    yield handle
    handle.stop(grace=0.0)


def test_rob_env_runs_over_tls_with_the_token(tls_server: RobotServerHandle, pki: Pki) -> None:
    env = gym.make(MIR_ROB, rs_address=tls_server.address, token=TOKEN, tls_ca=str(pki.ca))
    try:
        obs, info = env.reset(seed=0)
        assert info["server"] == tls_server.address
        for _ in range(3):
            obs, reward, terminated, truncated, _ = env.step(np.array([0.3, 0.0], np.float32))
            assert np.isfinite(reward) and not terminated
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_the_token_is_still_checked_over_tls(tls_server: RobotServerHandle, pki: Pki) -> None:
    client = RobotServerClient(tls_server.address, token="wrong", tls_ca=pki.ca)
    with client, pytest.raises(RobotServerError) as info:
        client.get_state()
    assert info.value.cause == "unauthenticated"


def _refusal(address: str, tls_ca: Path | None) -> TlsError:
    client = RobotServerClient(address, token=TOKEN, tls_ca=tls_ca)
    with client, pytest.raises(TlsError) as info:
        client.get_state()
    error = info.value
    assert error.cause == "tls" and address in str(error) and "\n" not in str(error)
    return error


def test_a_client_without_the_ca_is_told_the_server_requires_tls(
    tls_server: RobotServerHandle,
) -> None:
    assert "the server requires TLS" in str(_refusal(tls_server.address, None))


def test_a_client_with_another_ca_is_refused(tls_server: RobotServerHandle, pki: Pki) -> None:
    error = _refusal(tls_server.address, pki.other_ca)
    assert "TLS verification failed" in str(error) and "not signed" in str(error)


def test_a_tls_client_of_a_plain_server_is_told_so(pki: Pki) -> None:
    plain = start_robot_server("mir100", scene="empty", seed=0)
    try:
        assert "does not speak TLS" in str(_refusal(plain.address, pki.ca))
    finally:
        plain.stop(grace=0.0)


def test_the_manager_serves_a_tls_client(pki: Pki) -> None:
    supervisor = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    server, port = serve_manager(supervisor, "127.0.0.1", 0, tls=server_tls(pki.cert, pki.key))
    address = f"127.0.0.1:{port}"
    try:
        with open_channel(address, read_ca(pki.ca), ()) as channel:
            stub = sm_grpc.ServerManagerStub(channel)
            assert stub.VerifyConnection(sm.Empty(), timeout=10).alive
            cmd = "roslaunch mir100_robot_server sim_robot_server.launch"
            started = stub.StartNewServer(sm.RobotServer(cmd=cmd), timeout=60)
            assert started.success, started.info
            assert stub.KillServer(sm.RobotServer(port=started.port), timeout=10).success
        with open_channel(address, None, ()) as channel, pytest.raises(grpc.RpcError) as info:
            sm_grpc.ServerManagerStub(channel).VerifyConnection(sm.Empty(), timeout=10)
        assert info.value.code() == grpc.StatusCode.UNAVAILABLE  # a plain client gets nothing
    finally:
        supervisor.shutdown()
        server.stop(grace=None)


def _one_line_error(capfd: pytest.CaptureFixture, *argv: str) -> str:
    """``robogym-ray ARGV`` in this process: refused (exit code 2) with one line on stderr."""
    capfd.readouterr()
    try:
        code = main(list(argv))
    except SystemExit as exit:
        code = exit.code
    err = capfd.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    return err


@pytest.mark.usefixtures("ray_must_not_start")
def test_serve_and_manager_refuse_half_a_tls_pair(capfd: pytest.CaptureFixture, pki: Pki) -> None:
    err = _one_line_error(capfd, "serve", "--robot", "mir100", "--tls-cert", str(pki.cert))
    assert "--tls-cert without --tls-key" in err
    err = _one_line_error(capfd, "manager", "--port", "0", "--tls-key", str(pki.key))
    assert "--tls-key without --tls-cert" in err


@pytest.mark.usefixtures("ray_must_not_start")
def test_train_checks_its_tls_ca_before_ray(capfd: pytest.CaptureFixture, pki: Pki) -> None:
    err = _one_line_error(capfd, "train", "--tls-ca", str(pki.ca))
    assert "--tls-ca " in err and "expected only with a real robot (the CA is for its" in err
    missing = str(pki.ca.with_name("missing.pem"))
    err = _one_line_error(capfd, "train", "--real-robot", "127.0.0.1:1", "--tls-ca", missing)
    assert f"--tls-ca {missing}: cannot read it" in err


@pytest.mark.parametrize(
    ("cert", "key", "named", "why"),
    [
        ("missing.pem", "server.key", "missing.pem", "cannot read it"),
        ("server.key", "server.key", "server.key", "no PEM certificate"),
        ("server.pem", "server.pem", "server.pem", "not a PEM private key"),
        ("server.pem", "other.key", "other.key", "does not match"),
    ],
)
def test_bad_certificate_files_are_refused_naming_the_file(
    pki: Pki, cert: str, key: str, named: str, why: str
) -> None:
    _write_key(pki.key.parent / "other.key", ec.generate_private_key(ec.SECP256R1()))
    with pytest.raises(ConfigError) as info:
        server_tls(pki.key.parent / cert, pki.key.parent / key)
    assert named in str(info.value) and why in str(info.value)


def test_a_ca_file_that_is_no_certificate_is_refused(pki: Pki) -> None:
    with pytest.raises(ConfigError, match="server.key: no PEM certificate"):
        RobotServerClient("127.0.0.1:1", tls_ca=pki.key)
