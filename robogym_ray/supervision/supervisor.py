"""The supervisor's logic: own robot servers, probe them, restart them on faults, give them up.

Plain Python (threads, no Ray): how a server is started and killed is a ``ServerSpawner``
(``InProcessSpawner`` here for tests without Ray; the Ray edge in
``distributed/robot_actors.py`` spawns robot-server actors). Faults come from the periodic
health probe or from clients (``report_fault``); each server's ``RestartBook`` counts them per
cause and decides on backoff and giving up.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

from robogym_ray.errors import RobotServerError
from robogym_ray.supervision.health import probe, wait_ready
from robogym_ray.supervision.restart_policy import FaultCause, RestartBook, RestartPolicy
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.spawners import ServerSpawner, SpawnedServer

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SupervisorConfig:
    """How the supervisor watches its robot servers."""

    probe_interval_s: float = 1.0
    """Seconds between health probes of every server (0 = no probing)."""
    probe_deadline_s: float = 1.0
    """Deadline of a probe's GetState."""
    hung_after_probes: int = 2
    """Consecutive probes without an answer before a server counts as hung (one slow answer on
    a loaded machine is not a hang)."""
    start_timeout_s: float = 60.0
    """Seconds a new server has to answer its first GetState before the start counts as failed."""
    state_limit: float = 1e4
    """No robot's state has a legitimate value beyond +-this; a larger one is a broken state."""
    server_num_cpus: float = 0.25
    """CPUs reserved per robot-server actor (fractional: PyBullet in DIRECT mode is light)."""
    idle_timeout_s: float = 0.0
    """Seconds without a client's SetState or SendAction after which a server started with
    ``reap_idle`` is stopped (0 = never). Probes are GetState calls and do not count."""
    restart: RestartPolicy = field(default_factory=RestartPolicy)


class _StartFailed(Exception):
    def __init__(self, cause: FaultCause, detail: str) -> None:
        super().__init__(detail)
        self.cause = cause


@dataclass
class ManagedServer:
    """A supervised server across its restarts."""

    id: str
    spec: ServerSpec
    owner: str
    book: RestartBook
    server: SpawnedServer | None = None
    generation: int = 0
    state: str = "running"  # running | restarting | given_up | stopped
    leased: bool = False
    holder: str = ""
    """Who holds the lease (a training run's worker): a replacement worker releases it."""
    keep_port: bool = False
    reap_idle: bool = False
    calls: int = 0
    """Its client-call count when last looked at (``reap_idle``); changed since = in use."""
    active_at: float = field(default_factory=time.monotonic)
    missed_probes: int = 0
    message: str = ""
    recoveries: list[tuple[str, float]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def info(self) -> dict[str, Any]:
        s = self.server
        return {
            "id": self.id,
            "robot": self.spec.robot,
            "scene": self.spec.scene,
            "emulated": self.spec.emulation is not None,
            "owner": self.owner,
            "state": self.state,
            "generation": self.generation,
            "address": s.address if s else "",
            "port": s.port if s else 0,
            "pid": s.pid if s else 0,
            "node_id": s.node_id if s else "",
            "leased": self.leased,
            "holder": self.holder,
            "message": self.message,
            "restarts": dict(self.book.counts),
            "recoveries": list(self.recoveries),
        }


class Supervisor:
    """Spawns, checks, restarts and kills robot servers and hands out their addresses."""

    def __init__(self, config: SupervisorConfig, spawner: ServerSpawner) -> None:
        self.config = config
        self.spawner = spawner
        self._servers: dict[str, ManagedServer] = {}
        self._table_lock = threading.Lock()  # guards _servers only; never held while spawning
        self._ids = itertools.count(1)
        self.reaped = 0
        """Servers stopped for being idle (``SupervisorConfig.idle_timeout_s``)."""
        self._next_reap = 0.0
        self._stop = threading.Event()
        self._pool = ThreadPoolExecutor(max_workers=8, thread_name_prefix="probe")
        self._prober: threading.Thread | None = None
        if config.probe_interval_s > 0:
            self._prober = threading.Thread(target=self._probe_loop, daemon=True)
            self._prober.start()

    # -- starting and handing out -----------------------------------------------------------
    def start_server(
        self,
        spec: ServerSpec,
        owner: str = "user",
        keep_port: bool = False,
        reap_idle: bool = False,
        holder: str = "",
    ) -> dict[str, Any]:
        """Start a supervised server; returns its info once it answers GetState.

        ``keep_port``: restarts rebind the same port (for clients that cannot be told a new
        address, like robo-gym's). Otherwise a restart gets a fresh port: gRPC clients share
        connections per address process-wide, and one that failed during the outage backs off
        before reconnecting, so a new address is served sooner.
        ``reap_idle``: stop it once idle for ``idle_timeout_s`` (for clients that may vanish
        without stopping their server, like robo-gym's through the ServerManager).
        ``holder``: who leases it (``owner="lease"``), entered with it so that a concurrent
        ``release_holder`` never sees a leased server without its holder.
        """
        sid = f"{spec.robot}-{next(self._ids)}"
        try:
            server = self._spawn_ready(spec)
        except _StartFailed as exc:
            raise RobotServerError(
                f"could not start a {spec.robot} server ({exc.cause.value}): {exc}", cause="start"
            ) from None
        book = RestartBook(self.config.restart, name=f"robot server {sid} ({spec.robot})")
        entry = ManagedServer(
            sid, spec, owner, book, server, leased=owner == "lease", keep_port=keep_port,
            reap_idle=reap_idle, holder=holder,
        )  # fmt: skip
        with self._table_lock:
            self._servers[sid] = entry
        log.info("started %s at %s (pid %d)", sid, server.address, server.pid)
        return entry.info()

    def acquire(self, spec: ServerSpec, holder: str = "") -> dict[str, Any]:
        """Lease an idle running server made for the same spec, or start a new one."""
        with self._table_lock:
            for entry in self._servers.values():
                if (
                    entry.owner == "lease"
                    and not entry.leased
                    and entry.state == "running"
                    and entry.spec.key() == spec.key()
                ):
                    entry.leased, entry.holder = True, holder
                    return entry.info()
        return self.start_server(spec, owner="lease", holder=holder)

    def release(self, server_id: str) -> None:
        """End a lease; the server stays up for the next ``acquire``."""
        with self._table_lock:  # as acquire: a lease changes hands under the table's lock
            entry = self._servers.get(server_id)
            if entry is not None:
                entry.leased, entry.holder = False, ""

    def release_holder(self, holder: str) -> int:
        """End every lease ``holder`` has (its process died without releasing); returns how
        many. The servers stay up for the next ``acquire``, e.g. the holder's replacement."""
        with self._table_lock:
            held = [e for e in self._servers.values() if holder and e.leased and e.holder == holder]
            for entry in held:
                entry.leased, entry.holder = False, ""
        return len(held)

    # -- faults -------------------------------------------------------------------------------
    def report_fault(
        self, server_id: str, cause: str, generation: int | None = None, detail: str = ""
    ) -> dict[str, Any]:
        """A client saw ``cause``; restart unless that generation was already replaced.

        Returns the server's info after the restart (``state == "given_up"`` if it was given up).
        """
        entry = self._entry(server_id)
        with entry.lock:
            if entry.state == "running" and generation in (None, entry.generation):
                self._handle_fault(entry, FaultCause.parse(cause), detail or "reported by client")
            return entry.info()

    def restart(self, server_id: str) -> dict[str, Any]:
        """Manual restart (counted as ``manual``, never against the limit)."""
        return self.report_fault(server_id, FaultCause.MANUAL.value, detail="manual request")

    def probe_once(self) -> list[tuple[str, str]]:
        """Probe every running server now (in parallel); returns (id, cause) of faults handled."""
        with self._table_lock:
            entries = [e for e in self._servers.values() if e.state == "running"]
        results = self._pool.map(self._probe_entry, entries)
        return [(e.id, cause) for e, cause in zip(entries, results, strict=True) if cause]

    def _probe_entry(self, entry: ManagedServer) -> str | None:
        if not entry.lock.acquire(blocking=False):
            return None  # being restarted or probed already
        try:
            if entry.state != "running" or entry.server is None:
                return None
            cfg = self.config
            health = probe(entry.server.address, cfg.probe_deadline_s, cfg.state_limit)
            entry.missed_probes = entry.missed_probes + 1 if health.fault is FaultCause.HUNG else 0
            if health.fault is None or 0 < entry.missed_probes < cfg.hung_after_probes:
                return None
            entry.missed_probes = 0
            self._handle_fault(entry, health.fault, health.detail)
            return health.fault.value
        finally:
            entry.lock.release()

    def _probe_loop(self) -> None:
        while not self._stop.wait(self.config.probe_interval_s):
            try:
                self.probe_once()
                if self.config.idle_timeout_s > 0 and time.monotonic() >= self._next_reap:
                    # A tenth of the timeout is precise enough and keeps the asking cheap.
                    self._next_reap = time.monotonic() + self.config.idle_timeout_s / 10
                    self.reap_idle()
            except Exception:  # noqa: BLE001 - the prober must outlive any one bad probe
                log.exception("health probe failed")

    def reap_idle(self) -> list[str]:
        """Stop each ``reap_idle`` server without client calls for ``idle_timeout_s``; returns
        their ids. One whose count cannot be read (dead, restarting) is left to the probes."""
        with self._table_lock:
            entries = [e for e in self._servers.values() if e.reap_idle and e.state == "running"]
        counts = self._pool.map(self._activity, entries)
        now, reaped = time.monotonic(), []
        for entry, calls in zip(entries, counts, strict=True):
            if calls is not None and calls != entry.calls:
                entry.calls, entry.active_at = calls, now
            elif now - entry.active_at >= self.config.idle_timeout_s and self.kill(entry.id):
                log.warning(
                    "%s: stopped, %.0f s without a client call", entry.id, now - entry.active_at
                )
                reaped.append(entry.id)
        self.reaped += len(reaped)
        return reaped

    def _activity(self, entry: ManagedServer) -> int | None:
        server = entry.server
        try:
            return None if server is None else self.spawner.activity(server)
        except Exception:  # noqa: BLE001 - unreadable now; the probes judge its health
            log.debug("activity of %s unreadable", entry.id, exc_info=True)
            return None

    def _handle_fault(self, entry: ManagedServer, cause: FaultCause, detail: str) -> None:
        """Kill and restart ``entry`` (its lock held) until it serves or is given up."""
        began = time.monotonic()
        log.warning("%s: fault %s: %s", entry.id, cause.value, detail)
        decision = entry.book.record(cause, began)
        old, entry.server, entry.state = entry.server, None, "restarting"
        port = old.port if old and entry.keep_port else entry.spec.port
        if old is not None:
            self._kill_quietly(old)
        while decision.restart:
            time.sleep(decision.delay_s)
            try:
                entry.server = self._spawn_ready(entry.spec.with_port(port))
                break
            except _StartFailed as exc:
                log.warning("%s: restart failed (%s): %s", entry.id, exc.cause.value, exc)
                decision = entry.book.record(exc.cause, time.monotonic())
        if entry.server is None:
            entry.state, entry.message = "given_up", decision.message
            log.error("%s", decision.message)
            return
        entry.generation += 1
        entry.state, entry.message = "running", decision.message
        entry.recoveries.append((cause.value, time.monotonic() - began))
        log.warning("%s: restarted at %s after %s", entry.id, entry.server.address, cause.value)

    def _spawn_ready(self, spec: ServerSpec) -> SpawnedServer:
        cfg = self.config
        try:
            server = self.spawner.spawn(spec)
        except Exception as exc:  # noqa: BLE001 - any start failure is a failed start
            raise _StartFailed(FaultCause.CONNECTION, f"{type(exc).__name__}: {exc}") from None
        health = wait_ready(
            server.address, cfg.start_timeout_s, cfg.probe_deadline_s, cfg.state_limit
        )
        if health.fault is not None:
            self._kill_quietly(server)
            raise _StartFailed(health.fault, health.detail)
        return server

    def _kill_quietly(self, server: SpawnedServer) -> None:
        try:
            self.spawner.kill(server)
        except Exception:  # noqa: BLE001 - it may be gone already; that is what we want
            log.debug("kill of %s failed", server.address, exc_info=True)

    # -- stopping -----------------------------------------------------------------------------
    def kill(self, server_id: str) -> bool:
        """Stop a server for good; False if it is unknown (already killed)."""
        with self._table_lock:
            entry = self._servers.pop(server_id, None)
        if entry is None:
            return False
        with entry.lock:
            if entry.server is not None:
                self._kill_quietly(entry.server)
            entry.server, entry.state = None, "stopped"
        return True

    def kill_port(self, port: int) -> bool:
        """Stop the server listening on ``port``; False if none is known there."""
        with self._table_lock:
            ids = [e.id for e in self._servers.values() if e.server and e.server.port == port]
        return any([self.kill(sid) for sid in ids])

    def kill_all(self, owner: str | None = None) -> int:
        """Stop every server (of ``owner``, if given); returns how many were stopped."""
        with self._table_lock:
            ids = [e.id for e in self._servers.values() if owner in (None, e.owner)]
        return sum(self.kill(sid) for sid in ids)

    def shutdown(self) -> None:
        self._stop.set()
        self.kill_all()
        self._pool.shutdown(wait=False)

    # -- inspection and testing hooks ----------------------------------------------------------
    def info(self, server_id: str) -> dict[str, Any]:
        return self._entry(server_id).info()

    def status(self) -> list[dict[str, Any]]:
        with self._table_lock:
            entries = list(self._servers.values())
        return [e.info() for e in entries]

    def inject_fault(
        self, server_id: str, fault: str, stall_s: float | None = None, persistent: bool = False
    ) -> None:
        """Testing hook: make a server misbehave (``hang``, ``nan``, ``stall``).

        ``persistent``: every restart of it comes up with the same fault (a server that fails
        every restart, to exercise giving up).
        """
        entry = self._entry(server_id)
        if entry.server is None:
            raise RobotServerError(f"server {server_id} is not running", cause="state")
        if persistent:
            entry.spec = replace(entry.spec, fault=fault)
        self.spawner.inject_fault(entry.server, fault, stall_s)

    def _entry(self, server_id: str) -> ManagedServer:
        try:
            return self._servers[server_id]
        except KeyError:
            raise RobotServerError(
                f"no supervised server {server_id!r}; known: {sorted(self._servers)}",
                cause="unknown",
            ) from None
