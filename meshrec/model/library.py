"""A library of indexed models: every mesh file of a folder, and the bundled libraries."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.io.checks import check_instance
from meshrec.model.cache import default_cache_dir, refuse_model_folder
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.mesh import MESH_SUFFIXES, is_mesh_file

__all__ = [
    "LibraryWarning",
    "ModelLibrary",
    "ProgressCallback",
    "bundled_models_dir",
    "size_outliers",
]

#: ``progress(i, n, name)``: called before model ``i`` (0-based) of ``n`` is indexed, and
#: again as each stage of a build starts, with ``name`` then "NAME (stage)".
ProgressCallback = Callable[[int, int, str], None]

#: The name of a model folder's units note (``{"units": "mm"}``), which libraries ignore;
#: read by :func:`meshrec.recognition.units.read_units_note`.
UNITS_NOTE = "meshrec.json"


class LibraryWarning(UserWarning):
    """A file of a model library was skipped."""


@dataclass(frozen=True, eq=False)
class ModelLibrary:
    """Indexed models, sorted by name, with the files that were skipped and why.

    Attributes
    ----------
    folder : Path or None
        The folder the models came from (``None`` for :meth:`from_files`).
    models : tuple of ModelIndex
        Sorted by name; names are unique.
    skipped : tuple of (Path, str)
        Files that could not be used (not a mesh, unreadable, a repeated name), with the
        reason.
    cache_dir : Path or None
        The index cache the models were read from or written to (the default one when
        none was given): worker processes (``recognize(..., workers=N)``) load the library
        from it. None for a library made by hand.
    """

    folder: Path | None
    models: tuple[ModelIndex, ...]
    skipped: tuple[tuple[Path, str], ...] = ()
    cache_dir: Path | None = None

    @classmethod
    def from_folder(
        cls,
        folder: str | os.PathLike,
        params: IndexParams | None = None,
        cache_dir: str | os.PathLike | None = None,
        force: bool = False,
        progress: ProgressCallback | None = None,
    ) -> ModelLibrary:
        """Index every mesh file directly inside ``folder`` (not recursive).

        Files are taken in sorted order. A file whose ending is not in
        :data:`meshrec.model.mesh.MESH_SUFFIXES` (say ``notes.txt`` or ``part.step``), a mesh
        file that cannot be loaded, or one whose name (stem) repeats an earlier one, is
        skipped with a warning, as are a link to a missing file and a sub-folder that holds
        mesh files (sub-folders are not searched); hidden files (``.name``), the units note
        :data:`UNITS_NOTE` and other sub-folders are ignored.
        Nothing is ever written into ``folder`` (the cache lives in ``cache_dir``).

        Parameters
        ----------
        folder : str or path-like
            The model folder.
        params : IndexParams or None
            Index parameters for every model (``None``: the defaults).
        cache_dir : str or path-like or None
            The index cache (``None``: :func:`meshrec.model.cache.default_cache_dir`).
        force : bool
            Rebuild every index even if cached.
        progress : callable or None
            ``progress(i, n, name)`` called before model ``i`` (0-based) of ``n``, and as
            each stage of a build starts, with ``name`` "NAME (stage)".

        Returns
        -------
        ModelLibrary

        Raises
        ------
        TypeError
            If ``folder`` is not a str or path-like, or ``cache_dir`` neither one nor None.
        ValueError
            If ``folder`` does not exist, is not a directory or cannot be listed, holds no
            mesh file, or none of its mesh files can be loaded; ``params`` is not an
            IndexParams; or the cache directory is ``folder`` or inside it (see
            :func:`meshrec.model.cache.refuse_model_folder`).

        Warns
        -----
        LibraryWarning
            For every skipped file, and for every model none of whose vertices has a
            usable curvature (it can never match a touch; it is kept); issued once the
            models are indexed, and not at all when the ValueError is raised instead (its
            message lists every file and why it failed).
        """
        check_instance(folder, (str, os.PathLike), "folder")
        check_instance(cache_dir, (str, os.PathLike), "cache_dir", optional=True)
        root = Path(folder)
        files, skipped = folder_mesh_files(root)
        refuse_model_folder(cache_dir if cache_dir is not None else default_cache_dir(), root)
        return cls._build(
            root, files, params, cache_dir, force, progress, what=f"{root}", skipped=list(skipped)
        )

    @classmethod
    def from_files(
        cls,
        paths: Iterable[str | os.PathLike],
        params: IndexParams | None = None,
        cache_dir: str | os.PathLike | None = None,
        force: bool = False,
        progress: ProgressCallback | None = None,
    ) -> ModelLibrary:
        """Index the given mesh files (in the given order; the models end up sorted).

        A file that cannot be loaded, or whose name repeats an earlier one, is skipped
        with a warning.

        Parameters
        ----------
        paths : iterable of str or path-like
            Mesh files.
        params, cache_dir, force, progress
            As for :meth:`from_folder`.

        Returns
        -------
        ModelLibrary
            With ``folder = None``.

        Raises
        ------
        ValueError
            If ``paths`` is empty or a string, none of the files can be loaded,
            ``params`` is not an IndexParams, or the cache directory is the folder of one
            of the files.

        Warns
        -----
        LibraryWarning
            For every skipped file, and for every model none of whose vertices has a
            usable curvature (it can never match a touch; it is kept); issued once the
            models are indexed, and not at all when the ValueError is raised instead (its
            message lists every file and why it failed).
        """
        if isinstance(paths, (str, bytes, os.PathLike)):
            raise ValueError(f"paths must be an iterable of paths, got a single path {paths!r}")
        files = [Path(p) for p in paths]
        if not files:
            raise ValueError("paths must name at least one mesh file, got none")
        cache = cache_dir if cache_dir is not None else default_cache_dir()
        for parent in dict.fromkeys(p.parent for p in files):
            refuse_model_folder(cache, parent, subfolders=False)
        return cls._build(None, files, params, cache_dir, force, progress, what="the given files")

    @classmethod
    def _build(
        cls, folder, files, params, cache_dir, force, progress, what, skipped=()
    ) -> ModelLibrary:
        if params is not None and not isinstance(params, IndexParams):
            raise ValueError(f"params must be an IndexParams or None, got {params!r}")
        # The consolidated pack of the whole library (meshrec.model.pack), when valid.
        from meshrec.model import pack

        digests = pack.file_digests(files)
        packed = None
        if digests is not None and not force:
            packed = pack.load_pack(files, digests, params or IndexParams(), cache_dir)
        if packed is not None:
            if progress is not None:  # the pack loads at once; report its models in turn
                for i, path in enumerate(files):
                    progress(i, len(files), path.stem)
            return cls._checked(folder, packed[0], list(skipped) + list(packed[1]), what, cache_dir)
        found = list(skipped)
        models: dict[str, ModelIndex] = {}
        skipped: list[tuple[Path, str]] = []
        n = len(files)
        for i, path in enumerate(files):
            if progress is not None:
                progress(i, n, path.stem)
            if path.stem in models:
                reason = (
                    f"duplicate model name {path.stem!r} "
                    f"(already loaded from {models[path.stem].path.name!r})"
                )
            else:
                try:
                    stage = None
                    if progress is not None:

                        def stage(what, i=i, name=path.stem):
                            progress(i, n, f"{name} ({what})")

                    model = ModelIndex.from_file(
                        path, params=params, cache_dir=cache_dir, force=force, stage=stage
                    )
                except ValueError as exc:
                    reason = str(exc)
                else:
                    models[path.stem] = model
                    continue
            skipped.append((path, reason))
        if models and digests is not None and digests == pack.file_digests(files):
            # (not if a file changed while it was indexed: its digest would not match)
            pack.write_pack(
                files, digests, params or IndexParams(), list(models.values()), skipped, cache_dir
            )
        return cls._checked(folder, list(models.values()), found + skipped, what, cache_dir)

    @classmethod
    def _checked(cls, folder, models, skipped, what, cache_dir=None) -> ModelLibrary:
        """The library of ``models`` (sorted by name), warning of skipped and unusable ones."""
        if not models:  # one error that says it all, rather than a warning per file
            raise ValueError(
                f"no loadable mesh in {what}: " + "; ".join(f"{p.name}: {r}" for p, r in skipped)
            )
        unusable = [
            f"model {m.name!r} ({str(m.path)!r}): no surface site has a usable curvature "
            f"estimate ({len(m.mesh.faces)} faces: too coarse or degenerate), so no "
            "touch will ever match it"
            for m in models
            if not m.curvature.valid.any()
        ]
        for path, reason in skipped:
            warnings.warn(f"skipping {str(path)!r}: {reason}", LibraryWarning, stacklevel=4)
        for message in unusable:
            warnings.warn(message, LibraryWarning, stacklevel=4)
        # the square root of the area, stored with the mesh (a packed library's vertices
        # stay on disk until used)
        sizes = [float(m.mesh.scale) for m in models]
        for k, ratio in size_outliers(sizes):
            warnings.warn(_size_note(models[k].name, sizes[k], ratio), LibraryWarning, stacklevel=4)
        ordered = tuple(sorted(models, key=lambda m: m.name))
        cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        return cls(folder=folder, models=ordered, skipped=tuple(skipped), cache_dir=cache)

    @property
    def names(self) -> tuple[str, ...]:
        """The models' names, sorted."""
        return tuple(m.name for m in self.models)

    def __getitem__(self, name: str) -> ModelIndex:
        """The model called ``name``.

        Raises
        ------
        TypeError
            If ``name`` is not a str (models are looked up by name, not position: use
            ``library.models[i]``).
        KeyError
            If there is no such model.
        """
        if not isinstance(name, str):
            raise TypeError(
                f"a model is looked up by its name (a str), got {type(name).__name__}; "
                "library.models[i] holds them in order"
            )
        for m in self.models:
            if m.name == name:
                return m
        raise KeyError(f"no model named {name!r}; the library holds {list(self.names)}")

    def __contains__(self, name: object) -> bool:
        return any(m.name == name for m in self.models)

    def __len__(self) -> int:
        return len(self.models)

    def __iter__(self) -> Iterator[ModelIndex]:
        return iter(self.models)

    def __repr__(self) -> str:
        where = str(self.folder) if self.folder is not None else "files"
        return f"ModelLibrary({where!r}, models={list(self.names)}, skipped={len(self.skipped)})"


def size_outliers(sizes) -> list[tuple[int, float]]:
    """The models whose size is far from the others': in other units, most likely.

    A folder's models are taken in one unit; a model exported in millimetres among models
    in metres is a thousand times larger than the rest, and silently never fits a touch
    (a black-box probe, stop 36).

    Parameters
    ----------
    sizes : sequence of float
        Each model's size (its bounding box's diagonal, or the square root of its area),
        in one unit.

    Returns
    -------
    list of (int, float)
        ``(index, ratio)`` for each model whose size is more than
        ``defaults.LIBRARY_SIZE_RATIO_WARN`` times the median of every model's (ratio above
        1), or less than its inverse (ratio below 1); of two models, each is compared
        with the other. In the order given; empty for fewer than two models.

    Raises
    ------
    ValueError
        If a size is not a positive finite number.
    """
    a = np.asarray(sizes, dtype=np.float64).reshape(-1)
    if not (np.isfinite(a).all() and (a > 0).all()):
        raise ValueError(f"sizes must be positive finite numbers, got {a.tolist()!r}")
    if len(a) < 2:
        return []
    # against the median of all (robust to the odd one out from three models on), or of
    # two models, each against the other
    ref = a[::-1] if len(a) == 2 else np.full(len(a), np.median(a))
    limit = defaults.LIBRARY_SIZE_RATIO_WARN
    ratios = a / ref
    return [(k, float(r)) for k, r in enumerate(ratios) if r > limit or r < 1.0 / limit]


def _size_note(name: str, size: float, ratio: float) -> str:
    """The warning of one :func:`size_outliers` model."""
    how = f"{ratio:.3g} times larger" if ratio > 1 else f"{1.0 / ratio:.3g} times smaller"
    return (
        f"model {name!r} (size {size:.4g}, the square root of its area) is {how} than the "
        "median of the folder's models: "
        "every model of a folder is taken in one unit, and a model in other units (mm among "
        "m: 1,000 times) never fits a touch of the object; convert it if so (more than "
        f"defaults.LIBRARY_SIZE_RATIO_WARN = {defaults.LIBRARY_SIZE_RATIO_WARN:g} times)"
    )


def folder_mesh_files(
    folder: str | os.PathLike,
) -> tuple[tuple[Path, ...], tuple[tuple[Path, str], ...]]:
    """The mesh files directly inside a model folder, as :meth:`ModelLibrary.from_folder`
    takes them, and the other files it skips (with the reason).

    Hidden files (``.name``) and the units note :data:`UNITS_NOTE` are left out of both.
    Sub-folders are not searched: one that holds mesh files is skipped with that reason
    (so that models kept one level down are not lost without a word), others silently; a
    link whose target does not exist is skipped with that reason.

    Parameters
    ----------
    folder : str or path-like

    Returns
    -------
    files : tuple of Path
        Sorted mesh files (by ending, see :data:`meshrec.model.mesh.MESH_SUFFIXES`).
    skipped : tuple of (Path, str)
        The other files, with why they are not used.

    Raises
    ------
    ValueError
        If ``folder`` does not exist, is not a directory or cannot be listed, or holds no
        mesh file.
    """
    root = Path(folder)
    if not root.exists():
        raise ValueError(f"model folder {str(root)!r} does not exist")
    if not root.is_dir():
        raise ValueError(f"model folder {str(root)!r} is not a directory")
    try:
        listed = sorted(p for p in root.iterdir() if not p.name.startswith("."))
        entries = [p for p in listed if p.is_file()]
    except OSError as exc:
        raise ValueError(f"model folder {str(root)!r} cannot be listed ({exc.strerror})") from exc
    files = [p for p in entries if is_mesh_file(p)]
    others = [p for p in entries if not is_mesh_file(p) and p.name != UNITS_NOTE]
    broken = [p for p in listed if p.is_symlink() and not p.exists()]
    nested = [(p, n) for p in listed if p.is_dir() and (n := _mesh_files_in(p))]
    if not files:
        held = [p.name for p in others[:5]] + [f"{p.name}/ ({n} mesh files)" for p, n in nested]
        raise ValueError(
            f"model folder {str(root)!r} holds no mesh file "
            f"({', '.join(MESH_SUFFIXES)})"
            + (f"; it holds {', '.join(held)}" if held else "")
            + ("; sub-folders are not searched: give one as the folder" if nested else "")
        )
    skipped = []
    for p in others:
        ending = repr(p.suffix) if p.suffix else "none"
        reason = f"not a mesh file (ending {ending}, expected {', '.join(MESH_SUFFIXES)})"
        skipped.append((p, reason))
    for p in broken:
        skipped.append((p, "a link to a file that does not exist"))
    for p, n in nested:
        skipped.append(
            (
                p,
                f"a sub-folder holding {n} mesh file(s); sub-folders are not searched (give it "
                "as a model folder of its own)",
            )
        )
    return tuple(files), tuple(skipped)


def _mesh_files_in(folder: Path) -> int:
    """How many mesh files lie directly in ``folder`` (0 if it cannot be listed)."""
    try:
        return sum(1 for p in folder.iterdir() if p.is_file() and is_mesh_file(p))
    except OSError:
        return 0


def _bundled_roots() -> tuple[Path, ...]:
    """Where bundled libraries may live: the installed copy first, then the repository's."""
    package = Path(__file__).resolve().parents[1]
    return (package / "_bundled_models", package.parent / "models")


def bundled_model_sets() -> tuple[str, ...]:
    """The names of the bundled model libraries (for example ``("objects", "surfaces")``).

    Returns
    -------
    tuple of str
        Sorted; the folders found by :func:`bundled_models_dir`.
    """
    roots = _bundled_roots()
    return tuple(
        sorted(
            {
                p.name
                for root in roots
                if root.is_dir()
                for p in root.iterdir()
                if p.is_dir() and not p.name.startswith((".", "_"))
            }
        )
    )


def bundled_models_dir(name: str = "surfaces") -> Path:
    """The folder of a bundled model library.

    Looks in the installed package (``meshrec/_bundled_models/<name>``) first, then in the
    source repository (``models/<name>``).

    Parameters
    ----------
    name : str
        The library, e.g. ``"surfaces"`` (the paper's surfaces) or ``"objects"``.

    Returns
    -------
    Path
        An existing directory.

    Raises
    ------
    ValueError
        If ``name`` is not a plain folder name or no bundled library has that name (the
        message lists the available ones).
    """
    if not isinstance(name, str) or not name or name in (".", "..") or Path(name).name != name:
        raise ValueError(f"name must be a plain library name such as 'surfaces', got {name!r}")
    roots = _bundled_roots()
    for root in roots:
        candidate = root / name
        if candidate.is_dir():
            return candidate
    available = bundled_model_sets()
    raise ValueError(
        f"no bundled model library named {name!r}; available: "
        + (", ".join(available) if available else "none (no bundled models found)")
    )
