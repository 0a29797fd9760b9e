"""Where a run's files live: one storage that every node of a cluster reaches.

A run's files (``config.json``, ``summary.json``, TensorBoard events, ``checkpoints/learner.pt``
and its replay snapshot, the timed policy snapshots, ``policy-best.pt``) all go under one root,
``<storage>/<run_name>/``, whichever process on whichever node writes them. The storage is

* a **path** on a file system (the default, ``runs``; in a multi-node run a mount every node
  shares, e.g. NFS): written as before, to a temporary name beside the file and renamed
  (``write_bytes``), so nothing is ever half written;
* or an **object store URI** (``s3://bucket/prefix``, ``gs://...``, anything ``pyarrow.fs``
  knows - the filesystem layer Ray Train's own storage uses): each file is one whole-object
  write, which the store makes visible only once complete. An S3-compatible server other than
  AWS is reached with ``?endpoint_override=HOST:PORT&scheme=http`` in the URI or the
  ``AWS_ENDPOINT_URL`` variable; credentials come from the usual ``AWS_*`` variables.

Code that writes with ``pathlib`` (torch, TensorBoard) writes to ``staging(...)``: the storage's
own directory for a path, a local temporary directory for an object store, uploaded with
``publish``. Readers of a single file (``evaluate``, ``export``, ``--init-from``) call
``local_file``, which downloads an object store's file once and returns a local path.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from robogym_ray.errors import ConfigError, DiskWriteError

RESULTS_ENV = "ROBOGYM_RAY_RESULTS"
"""Where a Ray job's relative --logdir goes on the head (default ``~/robogym_ray_results``)."""
_RAY_WORKING_DIR = os.path.join("runtime_resources", "working_dir_files")


# -- atomic files on a file system ----------------------------------------------------------
def write_bytes(path: str | os.PathLike, data: bytes | memoryview, what: str) -> Path:
    """``data`` to a temporary name beside ``path``, synced, then renamed into place.

    On any failure the temporary file is removed and ``path`` is untouched; an OSError (a full
    disk) becomes a ``DiskWriteError`` naming ``what`` and ``path``.
    """
    with staged_write(path, data, what):
        pass
    return Path(path)


@contextmanager
def staged_write(path: str | os.PathLike, data: bytes | memoryview, what: str) -> Iterator[None]:
    """``write_bytes``, with the rename into place held until the block has run: a file that
    must not appear without a companion (an exported policy and its sidecar) writes that
    companion in the block; if the block fails, ``path`` is untouched."""
    with replacing(Path(path), what) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())  # a write error that shows only on flush: before the rename
        yield


def copy_file(source: str | os.PathLike, path: str | os.PathLike, what: str) -> Path:
    """``source`` copied to ``path`` the way ``write_bytes`` writes (a temporary name beside
    it, synced, renamed): a full disk leaves no partial ``path`` behind."""
    path = Path(path)
    with replacing(path, what) as tmp:
        shutil.copyfile(source, tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
    return path


@contextmanager
def replacing(path: Path, what: str) -> Iterator[Path]:
    """Yields a temporary name beside ``path`` to write; renames it to ``path`` after the block,
    removes it when the block (or the rename) fails."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise DiskWriteError.of(what, path, exc) from None
        raise


# -- a run's storage -------------------------------------------------------------------------
def is_uri(location: str) -> bool:
    """Whether ``location`` names an object store (``scheme://...``), not a file-system path.

    ``file://`` URIs are paths.
    """
    scheme, sep, _ = str(location).partition("://")
    return bool(sep) and scheme.isalnum() and scheme.lower() != "file"


def in_ray_job_copy(cwd: str | None = None) -> bool:
    """Whether this process runs inside Ray's temporary copy of a job's working dir (a relative
    path there points into a directory Ray deletes when the job's files are no longer used)."""
    return _RAY_WORKING_DIR in (cwd or os.getcwd())


def resolve_root(location: str, cwd: str | None = None) -> str:
    """``location`` as every process of the run must see it: a URI unchanged; a path made
    absolute here, on the driver's machine. A relative path in a submitted Ray job (whose
    working directory is Ray's temporary copy) is put under ``$ROBOGYM_RAY_RESULTS`` or
    ``~/robogym_ray_results`` on the head instead, as Ray itself keeps ``~/ray_results``."""
    if is_uri(location):
        return location
    path = Path(str(location).removeprefix("file://")).expanduser()
    if path.is_absolute():
        return str(path)
    if in_ray_job_copy(cwd):
        results = os.environ.get(RESULTS_ENV) or str(Path.home() / "robogym_ray_results")
        return str(Path(results).expanduser().absolute() / path)
    return str(Path(cwd or os.getcwd()).absolute() / path)


def _split_query(uri: str) -> tuple[str, str]:
    base, _, query = uri.partition("?")
    return base.rstrip("/"), query


@dataclass(frozen=True)
class RunStorage:
    """One run's root (``<storage>/<run_name>``, absolute path or URI). Picklable: actors get it
    as an argument and open the file system where they run."""

    root: str

    @property
    def is_local(self) -> bool:
        """A file-system path (on this node; shared with the others in a multi-node run)."""
        return not is_uri(self.root)

    @property
    def path(self) -> Path:
        """The root as a local path (only for a file-system storage)."""
        if not self.is_local:
            raise ConfigError(f"{self.root} is an object store, not a local path")
        return Path(self.root)

    def location(self, rel: str = "") -> str:
        """Where ``rel`` is, as a user would name it (a path or a URI)."""
        if self.is_local:
            return str(self.path / rel) if rel else self.root
        base, query = _split_query(self.root)
        full = f"{base}/{rel}" if rel else base
        return f"{full}?{query}" if query else full

    def child(self, name: str) -> RunStorage:
        return RunStorage(self.location(name))

    # -- the object store ---------------------------------------------------------------------
    def _fs(self, rel: str = "") -> tuple[Any, str]:
        """(pyarrow file system, the path of ``rel`` in it)."""
        import pyarrow.fs as pafs

        base, query = _split_query(self.root)
        try:
            fs, root = pafs.FileSystem.from_uri(f"{base}?{query}" if query else base)
        except (ValueError, OSError) as exc:
            raise ConfigError(f"storage {self.root}: {str(exc).splitlines()[0][:200]}") from None
        return fs, str(PurePosixPath(root) / rel) if rel else root

    # -- files --------------------------------------------------------------------------------
    def write_bytes(self, rel: str, data: bytes | memoryview, what: str) -> str:
        """``data`` as ``rel``, atomically (a path: temporary name and rename; an object
        store: one whole-object write). A failure is a ``DiskWriteError`` naming ``what``."""
        if self.is_local:
            return str(write_bytes(self.path / rel, data, what))
        fs, key = self._fs(rel)
        try:
            with fs.open_output_stream(key) as out:
                out.write(data)
        except OSError as exc:
            raise DiskWriteError.of(what, self.location(rel), exc) from None
        return self.location(rel)

    def upload(self, local: Path, rel: str, what: str) -> str:
        """The local file ``local`` as ``rel`` (nothing to do when ``rel`` is that file)."""
        if self.is_local and (self.path / rel).resolve() == local.resolve():
            return str(local)
        if self.is_local:
            return str(copy_file(local, self.path / rel, what))
        fs, key = self._fs(rel)
        try:  # streamed: a replay snapshot can be gigabytes
            with open(local, "rb") as src, fs.open_output_stream(key) as out:
                while chunk := src.read(8 << 20):
                    out.write(chunk)
        except OSError as exc:
            raise DiskWriteError.of(what, self.location(rel), exc) from None
        return self.location(rel)

    def exists(self, rel: str) -> bool:
        if self.is_local:
            return (self.path / rel).is_file()
        import pyarrow.fs as pafs

        fs, key = self._fs(rel)
        return fs.get_file_info(key).type == pafs.FileType.File

    def read_bytes(self, rel: str) -> bytes:
        if self.is_local:
            return (self.path / rel).read_bytes()
        fs, key = self._fs(rel)
        with fs.open_input_stream(key) as src:
            return bytes(src.read())

    def download(self, rel: str, local: Path) -> bool:
        """Copy ``rel`` to the local file ``local``; False when there is no such file."""
        if not self.exists(rel):
            return False
        local.parent.mkdir(parents=True, exist_ok=True)
        if self.is_local:
            if (self.path / rel).resolve() != local.resolve():
                copy_file(self.path / rel, local, "local copy")
            return True
        fs, key = self._fs(rel)
        tmp = local.with_name(f".{local.name}.{os.getpid()}.part")
        with fs.open_input_stream(key) as src, open(tmp, "wb") as out:
            while chunk := src.read(8 << 20):
                out.write(chunk)
        os.replace(tmp, local)
        return True

    def delete(self, rel: str) -> None:
        if self.is_local:
            (self.path / rel).unlink(missing_ok=True)
            return
        import pyarrow.fs as pafs

        fs, key = self._fs(rel)
        if fs.get_file_info(key).type == pafs.FileType.File:
            fs.delete_file(key)

    def names(self, rel: str = "") -> list[str]:
        """File names directly under ``rel`` (empty when there is no such folder)."""
        return self._listed(rel, folders=False)

    def folders(self, rel: str = "") -> list[str]:
        """Folder names directly under ``rel`` (empty when there is no such folder)."""
        return self._listed(rel, folders=True)

    def _listed(self, rel: str, folders: bool) -> list[str]:
        if self.is_local:
            folder = self.path / rel
            if not folder.is_dir():
                return []
            return sorted(
                p.name for p in folder.iterdir() if (p.is_dir() if folders else p.is_file())
            )
        import pyarrow.fs as pafs

        kind = pafs.FileType.Directory if folders else pafs.FileType.File
        fs, key = self._fs(rel)
        infos = fs.get_file_info(pafs.FileSelector(key, allow_not_found=True))
        return sorted(PurePosixPath(i.path).name for i in infos if i.type == kind)

    def holds_run(self) -> bool:
        """Whether a run has written here already (its config, summary or checkpoint)."""
        return any(
            self.exists(rel) for rel in ("config.json", "summary.json", "checkpoints/learner.pt")
        )

    # -- local staging ------------------------------------------------------------------------
    def staging(self, rel: str) -> Path:
        """A local folder for ``rel``'s files: the storage's own folder for a path (nothing to
        upload), a fresh temporary folder on this node for an object store (``publish`` it)."""
        if self.is_local:
            folder = self.path / rel
        else:
            folder = Path(tempfile.mkdtemp(prefix="robogym-ray-stage-")) / rel
        folder.mkdir(parents=True, exist_ok=True)
        return folder

    def publish(self, local: Path, rel: str, what: str) -> None:
        """After a write to ``staging``: upload ``local`` as ``rel``, or, when ``local`` no
        longer exists (a stale file removed), delete ``rel`` too."""
        if self.is_local:
            return
        if local.exists():
            self.upload(local, rel, what)
        else:
            self.delete(rel)


STORAGE_MARKER = ".robogym-ray-storage-check"
"""The start of the names of the files the storage checks write and remove again."""


def write_marker(storage: RunStorage, name: str, data: bytes, what: str) -> None:
    """``data`` as ``name`` under ``storage``, or a one-line ConfigError saying why it cannot be
    written (``what``: the storage as the user gave it, e.g. ``--storage``): the first step of
    the storage checks, before anything of a run starts."""
    try:
        storage.write_bytes(name, data, "storage check")
    except (DiskWriteError, ConfigError) as exc:  # ConfigError: a URI pyarrow cannot open
        why = exc.reason if isinstance(exc, DiskWriteError) and exc.reason else str(exc)
        raise ConfigError(f"{what} {storage.location()}: cannot write there ({why})") from None


def check_writable(storage: RunStorage, what: str = "storage") -> None:
    """ConfigError unless a file can be written under ``storage``: one is written and removed
    again, with the folders writing it made, so that a run that a later check refuses leaves
    nothing behind."""
    made = _outermost_missing(storage.path) if storage.is_local else None
    name = f"{STORAGE_MARKER}-{os.getpid()}"
    write_marker(storage, name, b"", what)
    storage.delete(name)
    if made is not None:
        for folder in (storage.path, *storage.path.parents):
            try:
                folder.rmdir()  # only an empty one: nothing another writer put there
            except OSError:
                break
            if folder == made:
                break


def _outermost_missing(path: Path) -> Path | None:
    """The outermost folder on ``path`` that does not exist yet (None: ``path`` exists)."""
    missing = None
    for folder in (path, *path.parents):
        if folder.exists():
            return missing
        missing = folder
    return missing


def local_file(location: str | os.PathLike, what: str = "file") -> str:
    """A local path to read ``location`` from: a path as it is; an object store's file
    downloaded into a temporary folder, with what readers look for beside it: a checkpoint's
    replay snapshot and an exported policy's sidecar, and for a file in a run's
    ``checkpoints/``, the run's ``config.json`` (its env id) where ``export`` looks for it.
    A missing object is a ConfigError naming it."""
    location = str(location)
    if not is_uri(location):
        return location
    base, query = _split_query(location)
    scheme, _, rest = base.partition("://")
    segs = rest.split("/")  # bucket, folders..., file name
    run_file = len(segs) >= 4 and segs[-2] == "checkpoints"  # BUCKET/.../RUN/checkpoints/FILE
    n_tail = min(3 if run_file else 2, len(segs) - 1)  # the folder it is in, the bucket kept
    top = f"{scheme}://{'/'.join(segs[:-n_tail])}"
    store = RunStorage(f"{top}?{query}" if query else top)
    tail = "/".join(segs[-n_tail:])
    local = Path(tempfile.mkdtemp(prefix="robogym-ray-fetch-")) / tail
    if not store.download(tail, local):
        raise ConfigError(f"{what} {location}: no such object")
    for companion in store.names(tail.rpartition("/")[0]):  # e.g. learner.pt.replay.npz
        if companion.startswith(f"{local.name}.") and not companion.endswith(".tmp"):
            store.download(f"{tail}{companion[len(local.name) :]}", local.parent / companion)
    sidecar = tail.rsplit(".", 1)[0] + ".json"
    store.download(sidecar, local.parent / Path(sidecar).name)
    if run_file:
        run = tail.split("/")[0]
        store.download(f"{run}/config.json", local.parent.parent / "config.json")
    return str(local)


def local_run(location: str | os.PathLike) -> Path:
    """A run folder to read: a path as it is; an object store's run (every file under it, its
    replay snapshots left out) downloaded into a temporary folder."""
    location = str(location)
    if not is_uri(location):
        return Path(location)
    import pyarrow.fs as pafs

    store = RunStorage(location)
    fs, root = store._fs()
    infos = fs.get_file_info(pafs.FileSelector(root, recursive=True, allow_not_found=True))
    files = [i.path for i in infos if i.type == pafs.FileType.File]
    if not files:
        raise ConfigError(f"run {location}: no such run (no files under it)")
    local = Path(tempfile.mkdtemp(prefix="robogym-ray-run-")) / PurePosixPath(root).name
    for path in files:
        rel = str(PurePosixPath(path).relative_to(root))
        if not rel.endswith(".replay.npz"):
            store.download(rel, local / rel)
    return local


def read_text(location: str | os.PathLike) -> str:
    """A text file (a summary, a curve) at a path or an object store's URI."""
    location = str(location)
    if not is_uri(location):
        return Path(location).read_text()
    base, query = _split_query(location)
    parent, _, name = base.rpartition("/")
    return RunStorage(f"{parent}?{query}" if query else parent).read_bytes(name).decode()
