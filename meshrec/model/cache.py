"""An on-disk cache of named numpy arrays, keyed by a mesh file's bytes and parameters.

Every entry is one uncompressed ``.npz`` file named after its key. Besides the caller's
arrays it stores the key itself and a SHA-256 checksum of the arrays, so that a file that
is truncated, corrupt, belongs to another key or version, or lacks arrays is detected on
load: the cache then warns (:class:`CacheWarning`) and reports a miss, and the caller
rebuilds. Writes go to a temporary file in the cache directory, are fsynced and then
moved into place with :func:`os.replace`, so readers never see a half-written entry and
concurrent writers of the same key both succeed (the last one wins, with equal content).
A cache directory that cannot be created or written is warned about once per operation
and the computation carries on uncached.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import tempfile
import warnings
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from meshrec._version import __version__

#: Bumped when the layout of the cache files, or what is cached, changes (2: meshes are
#: cleaned and oriented by meshrec.model.mesh before indexing).
_FORMAT = 3
_KEY_NAME = "__cache_key__"
_CHECKSUM_NAME = "__cache_checksum__"
_RESERVED = (_KEY_NAME, _CHECKSUM_NAME)
_CHUNK = 1 << 20


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


def _safe_label(label: str) -> str:
    """A file-name-safe version of ``label`` (at most 40 characters)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", label)[:40].strip(".") or "entry"


class ArrayCache:
    """A folder of ``.npz`` entries, each holding named arrays under one key.

    Parameters
    ----------
    directory : str or path-like or None
        The cache folder (created on first write). ``None``: :func:`default_cache_dir`.
    """

    def __init__(self, directory: str | os.PathLike | None = None) -> None:
        self.directory = Path(directory) if directory is not None else default_cache_dir()

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
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as npz:
                arrays = {name: npz[name] for name in npz.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
            self._warn(f"cache file {str(path)!r} is unreadable ({type(exc).__name__}: {exc})")
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
        tmp_name = None
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd, tmp_name = tempfile.mkstemp(
                prefix=f".{path.stem}.", suffix=".tmp", dir=self.directory
            )
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **payload)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp_name, path)
            tmp_name = None
            self._fsync_dir()
        except (OSError, ValueError) as exc:
            self._warn(
                f"cannot write cache file {str(path)!r} ({type(exc).__name__}: {exc}); "
                "continuing without caching"
            )
            return None
        finally:
            if tmp_name is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp_name)
        return path

    def _fsync_dir(self) -> None:
        """Flush the directory entry of a finished write (best effort, POSIX only)."""
        if os.name != "posix":
            return
        try:
            fd = os.open(self.directory, os.O_RDONLY)
        except OSError:
            return
        try:
            os.fsync(fd)
        except OSError:
            pass
        finally:
            os.close(fd)

    @staticmethod
    def _warn(message: str) -> None:
        warnings.warn(message, CacheWarning, stacklevel=3)
