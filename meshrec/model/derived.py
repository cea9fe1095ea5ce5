"""A model's quantities that are computed on first use, kept on disk beside its index.

A model's resolution, vertex scatter and near-symmetries are not part of its index:
a recognition needs them for the few models it names or reports on, and building them for
every model of a thousand-model library would cost more than it saves. Each is computed
when first asked for, which took 0.02 to 0.1 s each on the bundled 80,000-face models,
up to 0.15 s per model together. A command-line call is a new process, so each call paid
that again for the model it named.

So each one is also written to the index's cache folder as a small entry of its own. The
entry is keyed like the index: by the mesh file's SHA-256, the index parameters, the
package version, and also every value of :mod:`meshrec.defaults` (they tune these
computations). The next process reads it back bit for bit. An unreadable, corrupt or
mismatched entry is computed again, with the cache's :class:`CacheWarning`, and rewritten.
An entry that cannot be written (a read-only cache) is silently skipped: it is only a
saving.

:class:`DerivedStore` is the handle an index gets from the place it was loaded from
(:meth:`meshrec.model.index.ModelIndex.from_file` or the library pack). An index made
otherwise has none and computes as before, once per process.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from meshrec import defaults
from meshrec.model.cache import ArrayCache, CacheWarning, make_key
from meshrec.model.resolution import Resolution
from meshrec.model.symmetry import NearSymmetries

__all__ = ["DERIVED_VERSION", "KINDS", "DerivedStore", "defaults_digest"]

#: Bumped when what an entry holds, or how it is encoded, changes.
DERIVED_VERSION = 1

_FLOAT_FIELDS = tuple(
    f.name for f in dataclasses.fields(Resolution) if f.name not in ("too_coarse", "reasons")
)

#: What a store keeps: the names of the ModelIndex properties.
KINDS = ("resolution", "vertex_scatter", "near_symmetries")
_NAMES = {
    "resolution": ("floats", "too_coarse", "reasons"),
    "vertex_scatter": ("value",),
    "near_symmetries": ("half_turns", "axes"),
}


def defaults_digest() -> str:
    """SHA-256 of every upper-case value of :mod:`meshrec.defaults`, read now.

    A value changed at run time (a test, a user tuning a tolerance) gives another digest,
    so an entry computed under other defaults is never read back.

    Returns
    -------
    str
        64 hex characters.
    """
    values = {k: v for k, v in vars(defaults).items() if k.isupper()}
    blob = json.dumps(values, sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()


def _encode(what: str, value) -> dict[str, np.ndarray]:
    """The arrays of one value (see :meth:`DerivedStore.kept`)."""
    if what == "resolution":
        return {
            "floats": np.array([getattr(value, f) for f in _FLOAT_FIELDS], dtype=np.float64),
            "too_coarse": np.array(bool(value.too_coarse)),
            "reasons": np.array(json.dumps(list(value.reasons))),
        }
    if what == "vertex_scatter":
        return {"value": np.array(float(value), dtype=np.float64)}
    if what == "near_symmetries":
        axes = [np.stack([np.asarray(a, float), np.asarray(t, float)]) for a, t in value.axes]
        return {
            "half_turns": np.array(value.half_turns, dtype=np.float64).reshape(-1, 4, 4),
            "axes": np.array(axes, dtype=np.float64).reshape(-1, 2, 3),
        }
    raise ValueError(f"what must be one of {KINDS}, got {what!r}")


def _decode(what: str, arrays: dict[str, np.ndarray]):
    """The value of the arrays of :func:`_encode`; raises ValueError if they do not fit."""
    if what == "resolution":
        floats = arrays["floats"]
        if floats.shape != (len(_FLOAT_FIELDS),) or floats.dtype != np.float64:
            raise ValueError(f"floats must be ({len(_FLOAT_FIELDS)},) float64, got {floats.shape}")
        reasons = json.loads(str(arrays["reasons"]))
        if not isinstance(reasons, list) or not all(isinstance(r, str) for r in reasons):
            raise ValueError("reasons must be a list of strings")
        numbers = {f: float(x) for f, x in zip(_FLOAT_FIELDS, floats, strict=True)}
        return Resolution(**numbers, too_coarse=bool(arrays["too_coarse"]), reasons=tuple(reasons))
    if what == "vertex_scatter":
        value = arrays["value"]
        if value.shape != () or not np.isfinite(value):
            raise ValueError(f"value must be one finite number, got {value!r}")
        return float(value)
    if what == "near_symmetries":
        half_turns, axes = arrays["half_turns"], arrays["axes"]
        if half_turns.ndim != 3 or half_turns.shape[1:] != (4, 4):
            raise ValueError(f"half_turns must be (k, 4, 4), got {half_turns.shape}")
        if axes.ndim != 3 or axes.shape[1:] != (2, 3):
            raise ValueError(f"axes must be (k, 2, 3), got {axes.shape}")
        return NearSymmetries(
            half_turns=tuple(np.array(S) for S in half_turns),
            axes=tuple((np.array(a[0]), np.array(a[1])) for a in axes),
        )
    raise ValueError(f"what must be one of {KINDS}, got {what!r}")


@dataclass(frozen=True)
class DerivedStore:
    """Where one model's derived quantities are kept: its index's cache folder and key.

    Attributes
    ----------
    directory : Path or None
        The cache folder; None: :func:`meshrec.model.cache.default_cache_dir` at each use.
    file_sha256 : str
        The mesh file's SHA-256 (hex).
    params : dict
        The index parameters (``dataclasses.asdict`` of its ``IndexParams``).
    label : str
        The model's name, the entries' readable prefix.
    """

    directory: Path | None
    file_sha256: str
    params: dict
    label: str

    def key(self, what: str) -> str:
        """The entry key of ``what`` (one of :data:`KINDS`) under the defaults as they are.

        Raises
        ------
        ValueError
            If ``what`` is not one of :data:`KINDS`.
        """
        if what not in KINDS:
            raise ValueError(f"what must be one of {KINDS}, got {what!r}")
        params = {
            **self.params,
            "what": what,
            "derived": DERIVED_VERSION,
            "defaults": defaults_digest(),
        }
        return make_key(self.file_sha256, params, kind="model-derived")

    def kept(self, what: str, compute):
        """The value of ``what``: read from its entry, else ``compute()`` and written.

        Parameters
        ----------
        what : str
            One of :data:`KINDS`.
        compute : callable
            ``compute()`` returns the value (a :class:`Resolution`, a float, a
            :class:`NearSymmetries`).

        Returns
        -------
        Resolution or float or NearSymmetries
            The value, equal to ``compute()``'s bit for bit.

        Raises
        ------
        ValueError
            If ``what`` is not one of :data:`KINDS`.

        Warns
        -----
        CacheWarning
            If the entry is unreadable, corrupt or does not decode (it is computed again
            and rewritten).
        """
        key = self.key(what)
        cache = ArrayCache(self.directory)
        label = f"{self.label}.{what}"
        arrays = cache.load(key, _NAMES[what], label=label)
        if arrays is not None:
            try:
                return _decode(what, arrays)
            except (ValueError, KeyError, TypeError) as exc:
                warnings.warn(
                    f"cache entry {str(cache.path_for(key, label))!r} does not decode "
                    f"({exc}); computing it again",
                    CacheWarning,
                    stacklevel=2,
                )
        value = compute()
        with warnings.catch_warnings():
            # a saving only: a read-only cache (a deployment's) is not worth a warning
            warnings.simplefilter("ignore", CacheWarning)
            cache.save(key, _encode(what, value), label=label)
        return value
