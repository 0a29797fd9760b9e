"""TLS for the robot servers and the server manager: credentials, channels, and refusals.

A robot server on a lab network moves a robot, and its token (gRPC metadata) travels in clear
unless the connection is encrypted. ``serve`` and ``manager`` take ``--tls-cert``/``--tls-key``
(PEM) and listen with gRPC's own ``ssl_server_credentials``; clients take ``--tls-ca`` (or
``tls_ca=``), the PEM of the CA that signed the server's certificate, and verify the server
against it. Without any of them everything is as before: a plain port, as robo-gym's own client
(which has no TLS) expects.

Files are read and checked here, with Python's ``ssl`` module, before anything starts: gRPC
refuses a bad certificate or key only when binding, as a bare ``Failed to bind`` after its C core
has logged the reason on stderr. A client that fails a handshake is told why in one line
(``TlsError``), not with gRPC's ``failed to connect to all addresses``.
"""

from __future__ import annotations

import os
import re
import socket
import ssl
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import grpc

from robogym_ray.errors import ConfigError, RobotServerError
from robogym_ray.text import clip_text

PROBE_TIMEOUT_S = 2.0
"""Seconds the check 'does this server speak TLS?' may take (connect plus handshake)."""


class TlsError(RobotServerError):
    """A TLS connection to a server was refused: its certificate failed verification against
    the client's CA, or one side speaks TLS and the other does not (``cause="tls"``)."""

    def __init__(self, message: str, *, address: str = "", cause: str = "tls") -> None:
        super().__init__(message, address=address, cause=cause)


@dataclass(frozen=True)
class ServerTls:
    """A server's certificate chain and private key (PEM bytes), checked to belong together.

    Bytes, not paths: they cross to a Ray actor (the manager's supervisor) as they are.
    """

    cert_chain: bytes
    private_key: bytes
    cert_file: str = ""
    key_file: str = ""

    def credentials(self) -> grpc.ServerCredentials:
        """gRPC's server credentials: TLS, no client certificate asked for."""
        return grpc.ssl_server_credentials([(self.private_key, self.cert_chain)])

    def __repr__(self) -> str:  # never the key in a log line
        return f"ServerTls(cert_file={self.cert_file!r}, key_file={self.key_file!r})"


def server_tls(cert: str | os.PathLike | None, key: str | os.PathLike | None) -> ServerTls | None:
    """``--tls-cert``/``--tls-key`` read and checked; None when neither is given.

    Raises:
        ConfigError: only one of them given; a file unreadable, not PEM, an encrypted key, or
            a key that does not match the certificate. One line, naming the file.
    """
    if cert is None and key is None:
        return None
    if cert is None or key is None:
        given, missing = ("--tls-cert", "--tls-key") if key is None else ("--tls-key", "--tls-cert")
        raise ConfigError(f"{given} without {missing}: TLS needs both (the server's PEM "
                          "certificate chain and its private key), or neither")  # fmt: skip
    chain = _read(cert, "--tls-cert")
    _check_certificates(chain, "--tls-cert", cert)
    private_key = _read(key, "--tls-key")
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    try:
        # ssl wants files; a password callback that returns nothing refuses an encrypted key
        # instead of asking on the terminal (gRPC cannot use one either).
        context.load_cert_chain(cert, key, password=lambda: b"")
    except ssl.SSLError as exc:
        why = (
            "does not match the certificate in --tls-cert"
            if "KEY_VALUES_MISMATCH" in str(exc)
            else "is not a PEM private key (an encrypted key cannot be used: none is asked for)"
        )
        raise ConfigError(f"--tls-key {key}: the key {why}") from None
    return ServerTls(chain, private_key, str(cert), str(key))


def read_ca(tls_ca: str | os.PathLike | bytes | None, what: str = "--tls-ca") -> bytes | None:
    """The PEM of the CA a client verifies servers against: a file's (a path) or ``tls_ca``
    itself (bytes); None for none (a plain channel).

    Raises:
        ConfigError: unreadable, or no PEM certificate in it (one line, naming the file).
    """
    if tls_ca is None:
        return None
    if isinstance(tls_ca, bytes):
        _check_certificates(tls_ca, what, "(PEM given as bytes)")
        return tls_ca
    pem = _read(tls_ca, what)
    _check_certificates(pem, what, tls_ca)
    return pem


def open_channel(address: str, tls_ca: bytes | None, options: Sequence[tuple]) -> grpc.Channel:
    """The one place a client channel is made: TLS verified against ``tls_ca``, else plain."""
    if tls_ca is None:
        return grpc.insecure_channel(address, options=options)
    credentials = grpc.ssl_channel_credentials(root_certificates=tls_ca)
    return grpc.secure_channel(address, credentials, options=options)


_TLS_PART = re.compile(r"(?i)(tls|ssl|handshake).*")
_SECURE_REFUSALS = (
    # (words in gRPC's details, what they mean) for a TLS channel, most specific first
    ("CERTIFICATE_VERIFY_FAILED", "TLS verification failed: the server's certificate is not "
     "signed by the CA given as --tls-ca (tls_ca=)"),
    ("not in peer certificate", "TLS verification failed: the server's certificate does not "
     "name the host connected to (its subjectAltName must)"),
    ("WRONG_VERSION_NUMBER", "TLS handshake failed: the server does not speak TLS (started "
     "without --tls-cert/--tls-key?); connect to it without --tls-ca"),
    ("andshake", "TLS handshake failed"),  # Handshake, handshaker: anything else of TLS's
)  # fmt: skip


def tls_refusal(address: str, details: str, secure: bool) -> TlsError | None:
    """The TLS reason behind a call that failed ``UNAVAILABLE`` with ``details``, or None.

    Args:
        address: the server's ``host:port``.
        details: gRPC's status details of the failed call.
        secure: whether the client's channel is TLS (``tls_ca`` given).
    """
    if secure:
        for words, meaning in _SECURE_REFUSALS:
            if words in details:
                found = _TLS_PART.search(details)  # gRPC's words from the TLS library on
                said = clip_text(found.group(0) if found else details, 200)
                return TlsError(f"{meaning} ({said})", address=address)
        return None
    # A plain client's HTTP/2 preface makes a TLS server close the connection ('Socket closed'),
    # in gRPC's words the same as a server going away: ask the server which protocol it speaks.
    if "Connection refused" not in details and speaks_tls(address):
        return TlsError("the server requires TLS: pass --tls-ca (tls_ca=) with the PEM of the "
                        "CA that signed its certificate", address=address)  # fmt: skip
    return None


def speaks_tls(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> bool:
    """Whether the server at ``host:port`` completes a TLS handshake (nothing is verified:
    the answer only says which protocol it speaks)."""
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        return False
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.check_hostname, context.verify_mode = False, ssl.CERT_NONE
    context.set_alpn_protocols(["h2"])  # gRPC's servers insist on HTTP/2
    try:
        with (
            socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s) as raw,
            context.wrap_socket(raw),
        ):
            return True
    except (OSError, ssl.SSLError):  # ssl.SSLError is an OSError; named for the reader
        return False


def _read(path: str | os.PathLike, what: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise ConfigError(f"{what} {path}: cannot read it ({exc.strerror or exc})") from None


def _check_certificates(pem: bytes, what: str, path: str | os.PathLike) -> None:
    """ConfigError unless ``pem`` holds at least one PEM certificate that ssl can parse."""
    try:
        ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT).load_verify_locations(cadata=pem.decode("ascii"))
    except (UnicodeDecodeError, ssl.SSLError, ValueError):
        raise ConfigError(
            f"{what} {path}: no PEM certificate in it (expected '-----BEGIN CERTIFICATE-----')"
        ) from None
