"""The ground truth of a simulated touch, and its JSON file.

``meshrec simulate --truth TRUTH.json`` writes it; ``meshrec show`` and ``meshrec plot
search`` read it to draw the true curves and contact. The file is one JSON object::

    {"model": "ellipsoid", "contact": [x, y, z], "normal": [x, y, z],
     "T_touch_model": 4x4, "T_model_touch": 4x4, "contact_touch": [x, y, z],
     "noise": 0.001, "length": 0.61, "points": 61, "seed": 24}

(plus ``"probe_radius": r`` for a touch simulated with a ball tip of radius r, and
``"noise_direction": "normal"`` for noise along the normal only)

where ``contact`` and ``normal`` are in model coordinates and ``T_model_touch`` maps touch
points onto the model. Only ``contact`` and ``T_model_touch`` are required on reading.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from meshrec import defaults
from meshrec.io.checks import (
    check_choice,
    check_int,
    check_number,
    check_transform,
    check_vector,
    one_line,
)
from meshrec.io.files import read_text, write_atomic

__all__ = ["Truth", "read_truth", "write_truth"]


def _frozen(arr: np.ndarray) -> np.ndarray:
    out = np.array(arr, dtype=np.float64)
    out.setflags(write=False)
    return out


def _rigid(value, name: str) -> np.ndarray:
    """``value`` as a (4, 4) rigid transform; any failure is a ValueError naming ``name``."""
    try:
        return check_transform(value, name, rigid=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a rigid 4x4 transform: {exc}") from None


@dataclass(frozen=True, eq=False)
class Truth:
    """Where a simulated touch really was: its model, contact and rigid motion.

    Attributes
    ----------
    model : str
        The model's name (``""`` when unknown).
    contact : (3,) float64
        The true contact on the model, model coordinates.
    T_model_touch : (4, 4) float64
        The rigid transform mapping touch-frame points into model coordinates.
    T_touch_model : (4, 4) float64
        Its inverse, model points into the touch frame (computed when not given).
    normal : (3,) float64 or None
        The unit outward normal at the contact, model coordinates.
    noise, length : float or None
        The simulation's noise half-width and curve length, model units.
    points : int or None
        Points per curve.
    seed : int or None
        The seed that reproduces the touch.
    probe_radius : float or None
        The radius of the simulated probe's ball tip, model units (None: a point probe).
    noise_direction : str or None
        One of ``defaults.SIM_NOISE_DIRECTIONS`` ("normal": the noise along the normal
        only); None: not recorded (isotropic).

    Raises
    ------
    TypeError, ValueError
        From :meth:`from_dict` checks when built with values of the wrong type or shape.
    """

    model: str
    contact: np.ndarray
    T_model_touch: np.ndarray
    T_touch_model: np.ndarray | None = None
    normal: np.ndarray | None = None
    noise: float | None = None
    length: float | None = None
    points: int | None = None
    seed: int | None = None
    probe_radius: float | None = None
    noise_direction: str | None = None

    def __post_init__(self):
        if not isinstance(self.model, str):
            raise TypeError(f"model must be a str, got {type(self.model).__name__}")
        object.__setattr__(self, "contact", _frozen(check_vector(self.contact, "contact")))
        T = _rigid(self.T_model_touch, "T_model_touch")
        object.__setattr__(self, "T_model_touch", _frozen(T))
        if self.T_touch_model is None:
            inverse = np.eye(4)
            inverse[:3, :3] = T[:3, :3].T
            inverse[:3, 3] = -T[:3, :3].T @ T[:3, 3]
        else:
            inverse = _rigid(self.T_touch_model, "T_touch_model")
            scale = 1.0 + float(np.abs(T[:3, 3]).max())
            if not np.allclose(
                inverse @ T, np.eye(4), rtol=0.0, atol=defaults.RIGID_TOLERANCE * scale
            ):
                raise ValueError("T_touch_model must be the inverse of T_model_touch")
        object.__setattr__(self, "T_touch_model", _frozen(inverse))
        if self.normal is not None:
            normal = check_vector(self.normal, "normal", nonzero=True)
            unit = check_vector(normal, "normal", unit=True)
            if not np.allclose(unit, normal, rtol=0.0, atol=1e-12):  # keep a unit one's bits
                normal = unit
            object.__setattr__(self, "normal", _frozen(normal))
        for key in ("noise", "length", "probe_radius"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, check_number(getattr(self, key), key, minimum=0.0))
        for key in ("points", "seed"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, check_int(getattr(self, key), key, minimum=0))
        if self.noise_direction is not None:
            check_choice(self.noise_direction, defaults.SIM_NOISE_DIRECTIONS, "noise_direction")

    @property
    def contact_touch(self) -> np.ndarray:
        """(3,) float64: the true contact in the touch frame."""
        T = self.T_touch_model
        return T[:3, :3] @ self.contact + T[:3, 3]

    def __repr__(self) -> str:
        return (
            f"Truth(model={self.model!r}, contact={np.round(self.contact, 6).tolist()}, "
            f"points={self.points}, noise={self.noise}, seed={self.seed})"
        )

    # ------------------------------------------------------------------ dict and file
    def to_dict(self) -> dict:
        """The JSON-ready dictionary of the truth file (see the module docstring).

        Returns
        -------
        dict
        """
        return {
            "model": self.model,
            "contact": self.contact.tolist(),
            "normal": None if self.normal is None else self.normal.tolist(),
            "T_touch_model": self.T_touch_model.tolist(),
            "T_model_touch": self.T_model_touch.tolist(),
            "contact_touch": self.contact_touch.tolist(),
            "noise": self.noise,
            "length": self.length,
            "points": self.points,
            "seed": self.seed,
            **({} if self.probe_radius is None else {"probe_radius": self.probe_radius}),
            **(
                {}
                if self.noise_direction is None
                else {"noise_direction": self.noise_direction}
            ),
        }

    @classmethod
    def from_dict(cls, data, where: str = "truth") -> Truth:
        """Check and convert a truth dictionary (a parsed truth file).

        Parameters
        ----------
        data : Mapping
            With at least ``contact`` and ``T_model_touch``; ``model``,
            ``T_touch_model``, ``normal``, ``noise``, ``length``, ``points``, ``seed``,
            ``probe_radius`` and ``noise_direction`` are optional; the derived
            ``contact_touch`` is ignored.
        where : str
            The name of ``data`` in messages.

        Returns
        -------
        Truth

        Raises
        ------
        TypeError
            If ``data`` is not a mapping.
        ValueError
            Naming the entry (``truth['contact']``): if ``T_model_touch`` or ``contact``
            is missing, a value has the wrong type or shape, or the transform is not rigid.
        """
        if not isinstance(data, Mapping):
            raise TypeError(f"{where} must be a mapping (a truth dict), got {type(data).__name__}")
        keys = one_line(sorted(map(str, data)))
        if "T_model_touch" not in data:
            raise ValueError(f"{where} must have a 'T_model_touch' entry, got keys {keys}")
        T_model_touch = _rigid(data["T_model_touch"], f"{where}['T_model_touch']")
        if "contact" not in data:
            raise ValueError(f"{where} must have a 'contact' entry, got keys {keys}")
        model = data.get("model") or ""
        if not isinstance(model, str):
            raise ValueError(f"{where}['model'] must be a string, got {one_line(model)}")
        try:
            contact = check_vector(data["contact"], f"{where}['contact']")
        except (TypeError, ValueError):
            raise ValueError(
                f"{where}['contact'] must be 3 finite numbers, got {one_line(data['contact'])}"
            ) from None
        values = {}
        for key, check in (
            ("normal", lambda v, n: check_vector(v, n, nonzero=True)),
            ("noise", lambda v, n: check_number(v, n, minimum=0.0)),
            ("length", lambda v, n: check_number(v, n, minimum=0.0)),
            ("points", lambda v, n: check_int(v, n, minimum=0)),
            ("seed", lambda v, n: check_int(v, n, minimum=0)),
            ("probe_radius", lambda v, n: check_number(v, n, minimum=0.0)),
            ("noise_direction", lambda v, n: check_choice(v, defaults.SIM_NOISE_DIRECTIONS, n)),
        ):
            if data.get(key) is not None:
                try:
                    values[key] = check(data[key], f"{where}[{key!r}]")
                except TypeError as exc:
                    raise ValueError(str(exc)) from None
        if data.get("T_touch_model") is not None:
            values["T_touch_model"] = _rigid(data["T_touch_model"], f"{where}['T_touch_model']")
        try:
            return cls(
                model=model,
                contact=contact,
                T_model_touch=T_model_touch,
                **values,
            )
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None

    def to_file(self, path) -> None:
        """Write the truth JSON file atomically (see :func:`write_truth`)."""
        write_truth(path, self)


def read_truth(path) -> Truth:
    """Read a truth JSON file (``meshrec simulate --truth``).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Truth

    Raises
    ------
    ValueError
        Naming the file: if it cannot be read, is larger than
        ``defaults.TRUTH_MAX_BYTES``, is not JSON, or its content fails
        :meth:`Truth.from_dict`.
    """
    label = f"truth file {one_line(path)}"
    try:
        text = read_text(path, what="truth file", max_bytes=defaults.TRUTH_MAX_BYTES)
    except ValueError as exc:  # "truth file X: no such file" -> "... cannot be read: ..."
        reason = str(exc).removeprefix(f"{label}: ")
        raise ValueError(f"{label} cannot be read: {reason}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{label} is not JSON ({exc.msg})") from None
    except RecursionError:
        raise ValueError(f"{label} is not JSON: nested too deeply") from None
    try:
        return Truth.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{label}: {exc}") from None


def write_truth(path, truth: Truth) -> None:
    """Write ``truth`` as a JSON file, atomically (:func:`meshrec.io.files.write_atomic`).

    Parameters
    ----------
    path : str or os.PathLike
    truth : Truth

    Raises
    ------
    TypeError
        If ``truth`` is not a :class:`Truth`.
    OSError
        If the file cannot be written.
    """
    if not isinstance(truth, Truth):
        raise TypeError(f"truth must be a Truth, got {type(truth).__name__}")
    write_atomic(path, json.dumps(truth.to_dict(), indent=2) + "\n")
