"""Generated model libraries for the benchmark scripts."""

from __future__ import annotations

from pathlib import Path


def blob_folder(data: Path, n: int, name: str) -> Path:
    """A folder ``data / name`` holding the first ``n`` blobs of :mod:`meshrec.bench.blobs`.

    The blobs are written once into ``data / "blobs"`` (deterministic: blob ``i`` depends
    only on its seed and ``i``) and linked into the folder (hard links: no copies), so
    libraries of several sizes share their files and their index cache.

    Parameters
    ----------
    data : Path
        Where the blobs and the folder live.
    n : int
        Blobs in the folder.
    name : str
        The folder's name under ``data``.

    Returns
    -------
    Path
        The folder.
    """
    from meshrec.bench import write_blobs

    files = write_blobs(n, data / "blobs")
    folder = data / name
    folder.mkdir(parents=True, exist_ok=True)
    for f in files:
        link = folder / f.name
        if not link.exists():
            link.hardlink_to(f)
    return folder
