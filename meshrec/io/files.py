"""Files: one atomic writer for everything meshrec writes, and a bounded text reader.

:func:`write_atomic` writes through a temporary file in the destination's folder, flushed
to disk and renamed over the destination (and the folder flushed too), so that a reader
never sees half a file and an interrupted write leaves the old file (or none). The file
gets the mode ``open()`` would give it (0666 less the umask), not the temporary file's
0600.

:func:`read_text` reads a text file of bounded size, refusing folders, pipes, binary and
non-UTF-8 content with a one-line ``ValueError`` that names the file.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from meshrec.io.checks import check_instance, one_line

__all__ = ["read_text", "write_atomic"]


def _umask() -> int:
    """The process's umask (reading it means setting it: put it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(
    path,
    content: str | bytes | Callable[[str], None],
    *,
    prefix: str | None = None,
    suffix: str | None = None,
) -> Path:
    """Write a file atomically: a temporary file in its folder, fsync, then a rename.

    Parameters
    ----------
    path : str or os.PathLike
        The destination; its folder is created if missing.
    content : str or bytes or callable
        Text (written as UTF-8), bytes, or a function ``write(tmp_name)`` that writes the
        file itself (a picture library's ``savefig``, for instance); ``tmp_name`` ends in
        ``suffix``.
    prefix, suffix : str or None
        The temporary file's name is ``prefix + random + suffix``, in the folder of
        ``path`` (a sweeper of abandoned temporary files may recognise its own by them,
        as :class:`meshrec.model.cache.ArrayCache` does). ``None``: ``".<stem>."`` and
        ``".tmp<suffix of path>"`` (picture writers choose the format by the suffix).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        If ``content`` is neither text, bytes nor callable, or ``prefix`` or ``suffix``
        neither a string nor None.
    OSError
        If the folder or the file cannot be written; the temporary file is removed and
        an existing file at ``path`` is left as it was.
    """
    if not isinstance(content, (str, bytes)) and not callable(content):
        raise TypeError(f"content must be str, bytes or callable, got {type(content).__name__}")
    check_instance(prefix, str, "prefix", optional=True)
    check_instance(suffix, str, "suffix", optional=True)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.stem}." if prefix is None else prefix,
        suffix=f".tmp{path.suffix}" if suffix is None else suffix,
        dir=path.parent,
    )
    try:
        if callable(content):
            os.close(fd)
            content(tmp)
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
        else:
            data = content.encode("utf-8") if isinstance(content, str) else content
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; open() would give this
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_dir(path.parent)
    return path


def _fsync_dir(folder: Path) -> None:
    """Flush a folder's entries after a rename (best effort: POSIX only, errors ignored)."""
    if os.name != "posix":
        return
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def read_text(path, *, what: str, max_bytes: int) -> str:
    """Read a UTF-8 text file of at most ``max_bytes`` bytes.

    Parameters
    ----------
    path : str or os.PathLike
    what : str
        What the file is, for messages (``"touch file"``).
    max_bytes : int
        The largest size accepted.

    Returns
    -------
    str
        The text, without a UTF-8 byte-order mark.

    Raises
    ------
    ValueError
        Naming the file (on one line, whatever its name): if it does not exist, is a
        folder or not a regular file, cannot be read, is larger than ``max_bytes``, holds
        NUL bytes (binary) or is not UTF-8.
    """
    path = Path(path)
    label = f"{what} {one_line(path)}"
    try:
        st = path.stat()
    except FileNotFoundError:
        raise ValueError(f"{label}: no such file") from None
    except OSError as exc:
        raise ValueError(f"{label}: cannot be read ({one_line(exc.strerror or exc)})") from None
    if path.is_dir():
        raise ValueError(f"{label}: is a directory, expected a file")
    if not path.is_file():
        raise ValueError(f"{label}: not a regular file (a pipe or device?)")
    if st.st_size > max_bytes:
        raise ValueError(f"{label}: {st.st_size} bytes, larger than the limit of {max_bytes}")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ValueError(f"{label}: cannot be read ({one_line(exc.strerror or exc)})") from None
    if len(raw) > max_bytes:  # grew since stat
        raise ValueError(f"{label}: larger than the limit of {max_bytes} bytes")
    if b"\x00" in raw:
        raise ValueError(f"{label}: binary content, expected text")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{label}: not UTF-8 text ({exc.reason})") from None
