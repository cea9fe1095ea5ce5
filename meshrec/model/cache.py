"""An on-disk cache of named numpy arrays, keyed by a mesh file's bytes and parameters.

Every entry is one uncompressed ``.npz`` file named after its key. Besides the caller's
arrays it stores the key itself and a SHA-256 checksum of the arrays, so that a file that
is truncated, corrupt, belongs to another key or version, or lacks arrays is detected on
load: the cache then warns (:class:`CacheWarning`) and reports a miss, and the caller
rebuilds. Writes go through meshrec's one atomic writer, :func:`meshrec.io.files.write_atomic`:
a temporary file in the cache directory, fsynced, moved into place with :func:`os.replace`
and the folder fsynced, so readers never see a half-written entry and concurrent writers
of the same key both succeed (the last one wins, with equal content). Entries get the mode
``open()`` would give them (0666 less the umask).
A cache directory that cannot be created or written is warned about once per operation
and the computation carries on uncached.

Temporary files carry the writer's host name and process id. A writer killed mid-write
leaves its temporary file behind; the next :class:`ArrayCache` that loads or saves in the
folder removes it once its writer is gone (a dead process on this host) or it is older
than ``_STALE_TEMP_SECONDS``. A file a live process is writing is never touched.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import socket
import stat
import time
import warnings
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from meshrec._version import __version__
from meshrec.io.files import write_atomic

__all__ = [
    "ArrayCache",
    "CacheWarning",
    "default_cache_dir",
    "file_sha256",
    "make_key",
    "refuse_model_folder",
    "sweep_abandoned",
]

#: Bumped when the layout of the cache files, or what is cached, changes (2: meshes are
#: cleaned and oriented by meshrec.model.mesh before indexing).
_FORMAT = 3
_KEY_NAME = "__cache_key__"
_CHECKSUM_NAME = "__cache_checksum__"
_RESERVED = (_KEY_NAME, _CHECKSUM_NAME)
_CHUNK = 1 << 20
#: A temporary file this old is abandoned whoever wrote it (also one of another host,
#: whose process cannot be checked): writing a cache entry takes seconds (a 1M-face
#: model's ~200 MB entry), and a writer keeps the file's mtime fresh as it goes.
_STALE_TEMP_SECONDS = 600.0
#: ``.<entry stem>.<host>.<pid>.<random>.tmp``; the stem ends with the 64-hex key. Older
#: versions wrote ``.<entry stem>.<random>.tmp`` (no host or pid: age decides).
_TEMP_RE = re.compile(
    r"\.(?P<stem>(?:.*-)?[0-9a-f]{64})\.(?:(?P<host>[A-Za-z0-9_-]+)\.(?P<pid>[0-9]+)\.)?"
    r"[A-Za-z0-9_]+\.tmp"
)


class CacheWarning(UserWarning):
    """A cache entry was unusable or could not be written; the work is redone uncached."""


def default_cache_dir() -> Path:
    """The cache directory used when none is given.

    ``$MESHREC_CACHE_DIR`` if set and non-empty, else ``$XDG_CACHE_HOME/meshrec``, else
    ``~/.cache/meshrec``. Read from the environment at every call.

    Returns
    -------
    Path
    """
    env = os.environ.get("MESHREC_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg).expanduser() / "meshrec"
    return Path.home() / ".cache" / "meshrec"


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 hex digest of a file's bytes.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    str
        64 hex characters.

    Raises
    ------
    ValueError
        If the file cannot be read.
    """
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            while chunk := f.read(_CHUNK):
                h.update(chunk)
    except OSError as exc:
        raise ValueError(f"cannot read file {str(path)!r}: {exc}") from exc
    return h.hexdigest()


def make_key(file_digest: str, params: Mapping[str, object], kind: str = "index") -> str:
    """The cache key of a file's digest, the build parameters and the package version.

    Parameters
    ----------
    file_digest : str
        :func:`file_sha256` of the mesh file.
    params : mapping of str to JSON-serialisable values
        The parameters the cached arrays depend on.
    kind : str
        What is cached (keeps different kinds of entries apart).

    Returns
    -------
    str
        64 hex characters.

    Raises
    ------
    ValueError
        If ``params`` is not JSON-serialisable.
    """
    try:
        blob = json.dumps(
            {
                "kind": kind,
                "file_sha256": file_digest,
                "params": dict(params),
                "meshrec": __version__,
                "format": _FORMAT,
            },
            sort_keys=True,
            allow_nan=False,
        )
    except (TypeError, ValueError) as exc:
        raise ValueError(f"params must be JSON-serialisable, got {params!r}: {exc}") from exc
    return hashlib.sha256(blob.encode()).hexdigest()


def _checksum(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 over the names, dtypes, shapes and bytes of ``arrays`` (sorted by name)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a)
    return h.hexdigest()


def _host() -> str:
    """This machine's name as it appears in temporary file names."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", socket.gethostname())[:30] or "host"


def _temp_prefix(stem: str) -> str:
    """The prefix of a temporary file of the entry ``stem`` written by this process."""
    return f".{stem}.{_host()}.{os.getpid()}."


def _pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (a zombie counts as alive)."""
    if pid == os.getpid():
        return True
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. PermissionError: it exists, owned by someone else
        return True
    return True


def _abandoned(name: str, mtime: float, now: float) -> bool:
    """Whether the file ``name`` is a temporary file of this cache that nobody will finish."""
    m = _TEMP_RE.fullmatch(name)
    if m is None:
        return False
    if now - mtime > _STALE_TEMP_SECONDS:
        return True
    if m["pid"] is None or m["host"] != _host():
        return False  # age alone decides
    return not _pid_alive(int(m["pid"]))


def _check_npz_sizes(path: Path) -> str | None:
    """Why the arrays of an ``.npz`` file cannot be what their headers declare, if so.

    Each array's header declares its dtype and shape; the data that follows in the zip
    member must be exactly that many bytes. Checked before :func:`numpy.load` allocates
    the array, so a corrupt header declaring a huge shape is refused rather than raising
    MemoryError (or allocating gigabytes).

    Returns
    -------
    str or None
        The problem, or None if every array's size agrees with its header.
    """
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            with zf.open(info) as f:
                version = np.lib.format.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                elif version == (2, 0):
                    shape, _, dtype = np.lib.format.read_array_header_2_0(f)
                else:
                    return f"{info.filename}: unsupported .npy version {version}"
                header = f.tell()
            if dtype.hasobject:
                return f"{info.filename}: object arrays are not cache arrays"
            want = dtype.itemsize
            for d in shape:
                want *= int(d)
            have = info.file_size - header
            if want != have:
                return (
                    f"{info.filename}: its header declares {dtype} {shape} ({want} bytes), "
                    f"the file holds {have} bytes"
                )
    return None


def refuse_model_folder(
    cache_dir: str | os.PathLike, model_folder: str | os.PathLike, subfolders: bool = True
) -> None:
    """Refuse a cache directory that would write cache files among the models.

    Parameters
    ----------
    cache_dir : str or path-like
        The cache directory (need not exist).
    model_folder : str or path-like
        The folder of the model files.
    subfolders : bool
        Also refuse a cache directory inside ``model_folder``.

    Raises
    ------
    ValueError
        If ``cache_dir`` is ``model_folder`` (after resolving links and ``..``), or inside
        it when ``subfolders``; the message names both.
    """
    cache = Path(os.path.realpath(cache_dir))
    folder = Path(os.path.realpath(model_folder))
    if cache == folder:
        raise ValueError(
            f"cache_dir {str(cache_dir)!r} is the model folder {str(model_folder)!r}; "
            "the cache must not be written among the models: choose another cache folder"
        )
    if subfolders and folder in cache.parents:
        raise ValueError(
            f"cache_dir {str(cache_dir)!r} is inside the model folder "
            f"{str(model_folder)!r}; the cache must not be written among the models: "
            "choose a cache folder outside it"
        )


def _safe_label(label: str) -> str:
    """A file-name-safe version of ``label`` (at most 40 characters)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", label)[:40].strip(".") or "entry"


def sweep_abandoned(directory: str | os.PathLike) -> None:
    """Remove the abandoned temporary files of killed writers from a cache folder.

    A temporary file is abandoned when its writer (named in it: host and process id) is
    this host's and no longer runs, or when it is older than ``_STALE_TEMP_SECONDS``.
    Best effort: a folder that cannot be listed, or a file that cannot be removed (or was
    removed by another sweeper), is left alone.

    Parameters
    ----------
    directory : str or path
        The cache folder (a missing one is left alone).
    """
    now = time.time()
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return
    for entry in entries:
        if not entry.name.endswith(".tmp"):
            continue
        try:
            st = entry.stat(follow_symlinks=False)
            if stat.S_ISREG(st.st_mode) and _abandoned(entry.name, st.st_mtime, now):
                os.unlink(entry.path)
        except OSError:
            continue


class ArrayCache:
    """A folder of ``.npz`` entries, each holding named arrays under one key.

    Parameters
    ----------
    directory : str or path-like or None
        The cache folder (created on first write). ``None``: :func:`default_cache_dir`.
    """

    def __init__(self, directory: str | os.PathLike | None = None) -> None:
        self.directory = Path(directory) if directory is not None else default_cache_dir()
        self._swept = False

    def __repr__(self) -> str:
        return f"ArrayCache({str(self.directory)!r})"

    def path_for(self, key: str, label: str = "") -> Path:
        """The file that holds (or would hold) the entry ``key``.

        Parameters
        ----------
        key : str
            A :func:`make_key` digest (hex).
        label : str
            A readable prefix for the file name, e.g. the model's name.

        Returns
        -------
        Path

        Raises
        ------
        ValueError
            If ``key`` is not a non-empty hex string.
        """
        if not isinstance(key, str) or not re.fullmatch(r"[0-9a-f]+", key):
            raise ValueError(f"key must be a non-empty lowercase hex string, got {key!r}")
        prefix = f"{_safe_label(label)}-" if label else ""
        return self.directory / f"{prefix}{key}.npz"

    def load(
        self, key: str, required: Iterable[str], label: str = ""
    ) -> dict[str, np.ndarray] | None:
        """Load and verify the entry ``key``.

        Parameters
        ----------
        key : str
            The entry's key.
        required : iterable of str
            Array names the entry must hold.
        label : str
            The label given to :meth:`save`.

        Returns
        -------
        dict of str to ndarray or None
            The arrays (without the bookkeeping ones), or ``None`` on a miss. A missing
            file is a silent miss; an unreadable, corrupt, truncated, mismatched or
            incomplete file is a miss with a :class:`CacheWarning`.

        Raises
        ------
        ValueError
            If ``key`` is not a hex string.
        """
        path = self.path_for(key, label)
        self._sweep()
        if not path.is_file():
            return None
        try:
            problem = _check_npz_sizes(path)
            if problem is None:
                with np.load(path, allow_pickle=False) as npz:
                    arrays = {name: npz[name] for name in npz.files}
        except Exception as exc:  # whatever a corrupt file raises (even MemoryError): a miss
            problem = f"{type(exc).__name__}: {exc}"
        if problem is not None:
            self._warn(f"cache file {str(path)!r} is unreadable ({problem})")
            return None
        stored_key = arrays.pop(_KEY_NAME, None)
        stored_sum = arrays.pop(_CHECKSUM_NAME, None)
        if stored_key is None or stored_sum is None:
            self._warn(f"cache file {str(path)!r} lacks its key or checksum")
            return None
        if str(stored_key) != key:
            self._warn(f"cache file {str(path)!r} belongs to another key or version")
            return None
        missing = sorted(set(required) - set(arrays))
        if missing:
            self._warn(f"cache file {str(path)!r} lacks arrays {missing}")
            return None
        if str(stored_sum) != _checksum(arrays):
            self._warn(f"cache file {str(path)!r} fails its checksum (corrupt)")
            return None
        return arrays

    def save(self, key: str, arrays: Mapping[str, np.ndarray], label: str = "") -> Path | None:
        """Write the entry ``key`` atomically.

        Parameters
        ----------
        key : str
            The entry's key.
        arrays : mapping of str to array_like
            Arrays to store (no object dtypes; names must not start with ``__cache_``).
        label : str
            A readable prefix for the file name.

        Returns
        -------
        Path or None
            The entry's file, or ``None`` (with a :class:`CacheWarning`) if it could not be
            written, e.g. in a read-only directory.

        Raises
        ------
        ValueError
            If ``key`` is not a hex string or an array name is reserved.
        """
        path = self.path_for(key, label)
        clash = sorted(set(arrays) & set(_RESERVED))
        if clash:
            raise ValueError(f"arrays must not use the reserved names {clash}")
        payload = {name: np.asarray(a) for name, a in arrays.items()}
        payload[_KEY_NAME] = np.array(key)
        payload[_CHECKSUM_NAME] = np.array(_checksum({n: payload[n] for n in arrays}))

        def write(tmp_name: str) -> None:
            # through a file object: np.savez given a name would append ".npz" to it
            with open(tmp_name, "wb") as f:
                np.savez(f, **payload)

        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            # The same text for every entry: shown once, not once per model.
            self._warn(
                f"cannot create the cache folder {str(self.directory)!r} "
                f"({type(exc).__name__}: {exc}); continuing without caching"
            )
            return None
        try:
            self._sweep()
            # the temporary name is the one _sweep recognises (_TEMP_RE): host and pid
            write_atomic(path, write, prefix=_temp_prefix(path.stem), suffix=".tmp")
        except (OSError, ValueError) as exc:
            self._warn(
                f"cannot write cache file {str(path)!r} ({type(exc).__name__}: {exc}); "
                "continuing without caching"
            )
            return None
        return path

    def _sweep(self) -> None:
        """Remove abandoned temporary files of killed writers (once per instance)."""
        if self._swept:
            return
        self._swept = True
        sweep_abandoned(self.directory)

    @staticmethod
    def _warn(message: str) -> None:
        warnings.warn(message, CacheWarning, stacklevel=3)
