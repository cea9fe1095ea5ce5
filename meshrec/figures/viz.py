"""See a registration in 3D: the model, the registered curves, the contact, the candidates.

The paper's Figure 4 for your own data: the data curves laid onto the model by the
registration's ``T_model_touch`` (one colour), the estimated contact p*, the candidate
points of the table lookup (Figure 1's dots) and, given the ground truth of a simulated
touch, the curves at their true place (a second colour). :func:`show` opens an
interactive open3d window; :func:`render` draws the same scene off-screen into a PNG with
no display at all.

open3d is an optional dependency (``pip install 'meshrec[viz]'``) and is imported only
inside this module's functions. Off-screen rendering with open3d 0.20 runs on Filament's
Vulkan backend; on a machine without a GPU, Mesa's lavapipe (a Vulkan driver on the CPU)
serves, from the Debian/Ubuntu packages ``libvulkan1`` and ``mesa-vulkan-drivers``
(open3d also needs ``libusb-1.0-0`` to import). The scene is drawn without
post-processing, shadows (the key light is a directional light that casts none, not
open3d's sun, whose shadow map is rendered even with shadowing off), ambient occlusion,
anti-aliasing or sky box: on lavapipe those take seconds to a minute per frame, without
them a frame takes a fraction of a second. Without post-processing Filament writes linear
colour, so the picture is sRGB-encoded here. Each picture is drawn in a short-lived child
process: open3d 0.20 aborts the process that destroys a second OffscreenRenderer, and hangs
on a third, so a renderer must never live in the caller's process.
When open3d or a library it needs cannot load, :class:`VizDependencyError` says what to
install.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import importlib
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from meshrec.figures._pixels import check_size, write_png_atomic
from meshrec.model.index import ModelIndex
from meshrec.model.mesh import load_mesh
from meshrec.registration.transform import apply_transform

__all__ = [
    "COLORS",
    "RenderError",
    "Snapshot",
    "VizDependencyError",
    "check_display",
    "check_offscreen",
    "render",
    "show",
]

#: RGB colours (0..1) of the scene's parts.
COLORS: dict[str, tuple[float, float, float]] = {
    "model": (0.80, 0.80, 0.82),
    "registered": (0.95, 0.30, 0.02),  # the registered data curves (orange-red)
    "truth": (0.05, 0.35, 0.95),  # the data curves at their true place (blue)
    "contact": (0.10, 0.10, 0.10),  # the estimated contact p* (black)
    "true_contact": (0.05, 0.35, 0.95),
    "candidates": (0.10, 0.70, 0.20),  # the table lookup's candidate points (green)
    "background": (1.0, 1.0, 1.0),
}

#: Debian/Ubuntu packages providing the shared libraries open3d loads.
_SYSTEM_PACKAGES = {
    "libusb-1.0.so.0": "libusb-1.0-0",
    "libvulkan.so.1": "libvulkan1",
    "libGL.so.1": "libgl1",
    "libEGL.so.1": "libegl1",
    "libgomp.so.1": "libgomp1",
    "libX11.so.6": "libx11-6",
    "libc++.so.1": "libc++1",
    "libc++abi.so.1": "libc++abi1",
}
_VULKAN_PACKAGES = "libvulkan1 mesa-vulkan-drivers"
_PIP_HINT = "pip install 'meshrec[viz]' (or pip install 'open3d>=0.18')"
_FOV_DEG = 30.0  # vertical field of view of the camera
_MARGIN = 1.3  # the contact view shows the curves' radius times this, each way
_TILT_DEG = 30.0  # the camera looks at the contact this far off its normal
_MIN_SIZE, _MAX_SIZE = 16, 8192
_KEY_LIGHT = "meshrec_key_light"


class VizDependencyError(ImportError):
    """open3d (or matplotlib), or a system library it needs, cannot be loaded.

    The message is one line naming what to install.
    """


# ------------------------------------------------------------------------------ loading
def _missing_library_message(package: str, exc: BaseException) -> str:
    text = str(exc)
    match = re.search(r"(lib[\w.+-]+?\.so(?:\.\d+)*)", text)
    if match is None:
        first = text.splitlines()[0] if text else type(exc).__name__
        return f"{package} cannot be imported ({first}); reinstall it: {_PIP_HINT}"
    lib = match.group(1)
    deb = _SYSTEM_PACKAGES.get(lib)
    what = f"the system package {deb}" if deb else "the system package that provides it"
    how = f" (Debian/Ubuntu: apt-get install {deb})" if deb else ""
    return f"{package} cannot load {lib}: install {what}{how}"


def _import_open3d():
    """Import open3d, or raise :class:`VizDependencyError` naming what to install."""
    try:
        o3d = importlib.import_module("open3d")
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] == "open3d":
            raise VizDependencyError(f"open3d is not installed: {_PIP_HINT}") from None
        raise VizDependencyError(_missing_library_message("open3d", exc)) from None
    except (ImportError, OSError) as exc:
        raise VizDependencyError(_missing_library_message("open3d", exc)) from None
    with contextlib.suppress(Exception):
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    return o3d


def _open3d_version(o3d) -> tuple[int, ...]:
    parts = re.findall(r"\d+", str(getattr(o3d, "__version__", "0")))[:2]
    return tuple(int(p) for p in parts) if parts else (0,)


class _VkInstanceCreateInfo(ctypes.Structure):
    _fields_ = (
        ("sType", ctypes.c_int),
        ("pNext", ctypes.c_void_p),
        ("flags", ctypes.c_uint32),
        ("pApplicationInfo", ctypes.c_void_p),
        ("enabledLayerCount", ctypes.c_uint32),
        ("ppEnabledLayerNames", ctypes.c_void_p),
        ("enabledExtensionCount", ctypes.c_uint32),
        ("ppEnabledExtensionNames", ctypes.c_void_p),
    )


def _vulkan_devices(library: str = "libvulkan.so.1") -> int:
    """Count the Vulkan devices, or raise VizDependencyError naming what to install.

    A Vulkan instance is created and its physical devices counted through the Vulkan
    loader with ctypes. open3d's Filament engine aborts the whole process when it cannot
    create one, so this is checked before any renderer is made.
    """
    hint = f"(Debian/Ubuntu: apt-get install {_VULKAN_PACKAGES}, or a GPU's Vulkan driver)"
    try:
        vk = ctypes.CDLL(library)
    except OSError:
        raise VizDependencyError(
            f"off-screen rendering needs the Vulkan loader {library}: install "
            f"libvulkan1 and a Vulkan driver {hint}"
        ) from None
    vk.vkCreateInstance.restype = ctypes.c_int
    vk.vkCreateInstance.argtypes = (
        ctypes.POINTER(_VkInstanceCreateInfo),
        ctypes.c_void_p,
        ctypes.POINTER(ctypes.c_void_p),
    )
    vk.vkEnumeratePhysicalDevices.restype = ctypes.c_int
    vk.vkEnumeratePhysicalDevices.argtypes = (
        ctypes.c_void_p,
        ctypes.POINTER(ctypes.c_uint32),
        ctypes.c_void_p,
    )
    vk.vkDestroyInstance.restype = None
    vk.vkDestroyInstance.argtypes = (ctypes.c_void_p, ctypes.c_void_p)
    info = _VkInstanceCreateInfo(1, None, 0, None, 0, None, 0, None)  # 1: INSTANCE_CREATE_INFO
    instance = ctypes.c_void_p()
    result = vk.vkCreateInstance(ctypes.byref(info), None, ctypes.byref(instance))
    if result != 0:
        raise VizDependencyError(
            f"off-screen rendering needs a Vulkan driver, none found (vkCreateInstance "
            f"returned {result}): install mesa-vulkan-drivers {hint}"
        )
    count = ctypes.c_uint32(0)
    try:
        vk.vkEnumeratePhysicalDevices(instance, ctypes.byref(count), None)
    finally:
        vk.vkDestroyInstance(instance, None)
    if count.value == 0:
        raise VizDependencyError(
            f"off-screen rendering needs a Vulkan device, none found: install "
            f"mesa-vulkan-drivers {hint}"
        )
    return int(count.value)


def check_offscreen():
    """Check that open3d can render off-screen here, and return the open3d module.

    Returns
    -------
    module
        The imported ``open3d``.

    Raises
    ------
    VizDependencyError
        If open3d is not installed, cannot load a shared library (``libusb-1.0.so.0``
        ...), or (open3d 0.20 or newer on Linux) no Vulkan loader or driver is installed.
        The message is one line naming the package to install.
    """
    o3d = _import_open3d()
    if sys.platform.startswith("linux") and _open3d_version(o3d) >= (0, 20):
        _vulkan_devices()
    return o3d


# ------------------------------------------------------------------------------ the scene
@dataclass(frozen=True)
class Snapshot:
    """A rendered picture and the pinhole camera that made it.

    Attributes
    ----------
    path : Path or None
        The PNG written (None when only the image was asked for).
    image : (h, w, 3) uint8
        The picture, rows top to bottom.
    intrinsic : (3, 3) float
        The camera matrix (pixels): ``[[f, 0, cx], [0, f, cy], [0, 0, 1]]``.
    extrinsic : (4, 4) float
        World (model coordinates) to camera; the camera looks along +z, x right, y down.
    model : str
        The model shown.
    contact : (3,) float
        The estimated contact p* shown, model coordinates.
    """

    path: Path | None
    image: np.ndarray = field(repr=False)
    intrinsic: np.ndarray = field(repr=False)
    extrinsic: np.ndarray = field(repr=False)
    model: str = ""
    contact: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the picture in pixels."""
        return int(self.image.shape[1]), int(self.image.shape[0])

    def project(self, points) -> np.ndarray:
        """Project model-coordinate points to pixel coordinates.

        Parameters
        ----------
        points : (n, 3) or (3,) float
            Points in model coordinates.

        Returns
        -------
        (n, 2) float
            Column x (to the right) and row y (down) of each point, pixels; NaN for a
            point behind the camera.

        Raises
        ------
        ValueError
            If ``points`` is not (n, 3) or (3,).
        """
        p = np.asarray(points, dtype=np.float64)
        if p.ndim == 1:
            p = p[None, :]
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must be (n, 3) or (3,), got {np.shape(points)}")
        cam = p @ self.extrinsic[:3, :3].T + self.extrinsic[:3, 3]
        uvw = cam @ self.intrinsic.T
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = uvw[:, :2] / uvw[:, 2:3]
        xy[cam[:, 2] <= 0] = np.nan
        return xy


@dataclass(frozen=True)
class _Scene:
    """What to draw, in model coordinates, and from where (no open3d objects)."""

    model: str
    vertices: np.ndarray
    faces: np.ndarray
    registered: tuple[np.ndarray, ...]
    truth: tuple[np.ndarray, ...]
    contact: np.ndarray
    true_contact: np.ndarray | None
    candidates: np.ndarray
    center: np.ndarray
    eye: np.ndarray
    up: np.ndarray
    radius: float  # half the height of the view at the centre, model units
    marker: float  # radius of the contact marker, model units


def _check_size(size) -> tuple[int, int]:
    return check_size(size, _MIN_SIZE, _MAX_SIZE)


def _pick_registration(result, model, touch):
    """The registration to show and its touch, from a Recognition or a Registration."""
    from meshrec.recognition.result import Recognition
    from meshrec.registration.register import Registration

    if isinstance(result, Recognition):
        touch = result.touch if touch is None else touch
        if model is None:
            reg = result.best
            if reg is None:
                raise ValueError(
                    "result must have a recognised model to show, got every model rejected"
                )
        else:
            names = [r.model for r in result.ranking]
            if model not in names:
                raise ValueError(f"model must be one of {names}, got {model!r}")
            reg = result.ranking[names.index(model)]
    elif isinstance(result, Registration):
        reg = result
        if model is not None and model != reg.model:
            raise ValueError(f"model must be {reg.model!r} for this registration, got {model!r}")
        if touch is None:
            raise ValueError("touch must be given with a Registration, got None")
    else:
        raise ValueError(
            f"result must be a Recognition or a Registration, got {type(result).__name__}"
        )
    if reg.rejected:
        raise ValueError(f"model {reg.model!r} was rejected by the table lookup: {reg.reason}")
    from meshrec.io.touch import TouchData

    if not isinstance(touch, TouchData):
        raise ValueError(f"touch must be a TouchData, got {type(touch).__name__}")
    return reg, touch


def _other_model(name: str, model_name: str) -> bool:
    """Whether a truth names another model than the one shown (then warn: not drawn)."""
    if name and name != model_name:
        warnings.warn(
            f"truth is for model {name!r}, not {model_name!r}: true curves not drawn",
            UserWarning,
            stacklevel=4,
        )
        return True
    return False


def _load_truth(truth, touch, model_name: str):
    """(true curves, true contact) in model coordinates, or ((), None)."""
    if truth is None:
        return (), None
    from meshrec.io.truth import Truth, read_truth
    from meshrec.sim.simulate import SimulatedTouch

    if isinstance(truth, SimulatedTouch):
        name = truth.model
        if _other_model(name, model_name):
            return (), None
        return tuple(np.asarray(c, dtype=np.float64) for c in truth.clean_curves), np.asarray(
            truth.contact, dtype=np.float64
        )
    if isinstance(truth, (str, os.PathLike)):
        truth = read_truth(truth)
    elif isinstance(truth, Mapping):
        truth = Truth.from_dict(truth)
    elif not isinstance(truth, Truth):
        raise ValueError(
            f"truth must be a SimulatedTouch, a Truth, a truth dict or a truth JSON file, "
            f"got {type(truth).__name__}"
        )
    if _other_model(truth.model, model_name):
        return (), None
    T = truth.T_model_touch
    curves = tuple(apply_transform(T, np.asarray(c, dtype=np.float64)) for c in touch.curves)
    return curves, np.array(truth.contact)


def _mesh_arrays(mesh, reg) -> tuple[np.ndarray, np.ndarray]:
    if mesh is None:
        mesh = reg.path
    if isinstance(mesh, ModelIndex):
        mesh = mesh.mesh
    if isinstance(mesh, (str, os.PathLike)):
        V, F = load_mesh(mesh)
        return np.array(V, dtype=np.float64), np.array(F, dtype=np.int64)
    try:
        V = np.array(mesh.vertices, dtype=np.float64)
        F = np.array(mesh.faces, dtype=np.int64)
    except AttributeError:
        raise ValueError(
            f"mesh must be a mesh file or have vertices and faces, got {type(mesh).__name__}"
        ) from None
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise ValueError(
            f"mesh must have (n, 3) vertices and (m, 3) faces, got {V.shape}, {F.shape}"
        )
    return V, F


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _perpendicular(v: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """The unit part of ``hint`` perpendicular to unit ``v`` (a world axis if too small)."""
    options = [hint, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])]
    parts = [h - np.dot(h, v) * v for h in options]
    norms = [float(np.linalg.norm(p)) for p in parts]
    k = 0 if norms[0] > 0.3 else int(np.argmax(norms))
    return parts[k] / norms[k]


def _make_scene(reg, touch, truth, mesh, view: str) -> _Scene:
    V, F = _mesh_arrays(mesh, reg)
    T = np.asarray(reg.T_model_touch, dtype=np.float64)
    registered = tuple(apply_transform(T, np.asarray(c, dtype=np.float64)) for c in touch.curves)
    true_curves, true_contact = _load_truth(truth, touch, reg.model)
    contact = np.asarray(reg.contact, dtype=np.float64)
    pts = np.vstack(registered)
    curve_radius = float(np.linalg.norm(pts - contact, axis=1).max())
    extent = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    curve_radius = max(curve_radius, 1e-3 * extent, 1e-12)
    normal = reg.normal if reg.normal is not None else np.array([0.0, 0.0, 1.0])
    n = _unit(np.asarray(normal, dtype=np.float64))
    side = _perpendicular(n, np.array([0.0, 0.0, 1.0]))
    tilt = np.radians(_TILT_DEG)
    direction = np.cos(tilt) * n + np.sin(tilt) * side  # from the centre to the eye
    if view == "contact":
        center, radius = contact, _MARGIN * curve_radius
    else:
        center = 0.5 * (V.max(axis=0) + V.min(axis=0))
        radius = 0.5 * _MARGIN * extent / 1.2
    distance = radius / np.tan(np.radians(_FOV_DEG) / 2.0)
    eye = center + distance * direction
    up = _perpendicular(-direction, np.array([0.0, 0.0, 1.0]))
    return _Scene(
        model=reg.model,
        vertices=V,
        faces=F,
        registered=registered,
        truth=true_curves,
        contact=contact,
        true_contact=true_contact,
        candidates=np.asarray(reg.candidate_points, dtype=np.float64).reshape(-1, 3),
        center=center,
        eye=eye,
        up=up,
        radius=radius,
        marker=0.035 * radius,
    )


def _camera(scene: _Scene, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole intrinsic (3, 3) and world-to-camera extrinsic (4, 4), OpenCV axes."""
    f = 0.5 * height / np.tan(np.radians(_FOV_DEG) / 2.0)
    K = np.array([[f, 0.0, 0.5 * width], [0.0, f, 0.5 * height], [0.0, 0.0, 1.0]])
    z = _unit(scene.center - scene.eye)
    y = -_perpendicular(z, scene.up)
    x = np.cross(y, z)
    E = np.eye(4)
    E[:3, :3] = np.vstack([x, y, z])
    E[:3, 3] = -E[:3, :3] @ scene.eye
    return K, E


def _geometries(o3d, scene: _Scene, width: int):
    """The open3d geometries and materials of the scene: [(name, geometry, material)]."""
    R = o3d.visualization.rendering
    out = []

    def material(shader, color, **kw):
        m = R.MaterialRecord()
        m.shader = shader
        m.base_color = (*color, 1.0)
        for k, v in kw.items():
            setattr(m, k, v)
        return m

    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(scene.vertices), o3d.utility.Vector3iVector(scene.faces)
    )
    mesh.compute_vertex_normals()
    out.append(("model", mesh, material("defaultLit", COLORS["model"], base_roughness=0.7)))

    # Lift the curves a little towards the camera so the surface does not hide them.
    towards_eye = _unit(scene.eye - scene.center)
    lift = 0.02 * scene.radius * towards_eye
    line_width = float(max(2.0, width / 220.0))
    for key, curves in (("truth", scene.truth), ("registered", scene.registered)):
        if not curves:
            continue
        points, lines, start = [], [], 0
        for c in curves:
            points.append(c + lift)
            lines.append(np.column_stack([np.arange(len(c) - 1), np.arange(1, len(c))]) + start)
            start += len(c)
        ls = o3d.geometry.LineSet(
            o3d.utility.Vector3dVector(np.vstack(points)),
            o3d.utility.Vector2iVector(np.vstack(lines).astype(np.int32)),
        )
        out.append((f"{key}_curves", ls, material("unlitLine", COLORS[key], line_width=line_width)))

    def spheres(centers, radius):
        merged = o3d.geometry.TriangleMesh()
        for c in centers:
            s = o3d.geometry.TriangleMesh.create_sphere(radius=radius, resolution=12)
            s.translate(np.asarray(c, dtype=np.float64))
            merged += s
        return merged

    if len(scene.candidates):
        out.append(
            (
                "candidates",
                spheres(scene.candidates, 0.6 * scene.marker),
                material("defaultUnlit", COLORS["candidates"]),
            )
        )
    if scene.true_contact is not None:
        out.append(
            (
                "true_contact",
                spheres([scene.true_contact], 0.8 * scene.marker),
                material("defaultUnlit", COLORS["true_contact"]),
            )
        )
    out.append(
        (
            "contact",
            spheres([scene.contact], scene.marker),
            material("defaultUnlit", COLORS["contact"]),
        )
    )
    return out


def _prepare(result, touch, model, truth, mesh, size, view):
    w, h = _check_size(size)
    if view not in ("contact", "model"):
        raise ValueError(f"view must be 'contact' or 'model', got {view!r}")
    reg, touch = _pick_registration(result, model, touch)
    return _make_scene(reg, touch, truth, mesh, view), w, h


#: Seconds a child process may take to render one picture before it is given up.
_RENDER_TIMEOUT = 600.0


class RenderError(RuntimeError):
    """Off-screen rendering failed or timed out in its child process."""


def _draw(o3d, scene: _Scene, K: np.ndarray, E: np.ndarray, width: int, height: int):
    """Draw the scene with one OffscreenRenderer: (height, width, 3) uint8, linear colour."""
    R = o3d.visualization.rendering
    renderer = R.OffscreenRenderer(width, height)
    s = renderer.scene
    s.set_background([*COLORS["background"], 1.0])
    with contextlib.suppress(Exception):
        s.show_skybox(False)
    view = s.view
    view.set_post_processing(False)
    view.set_shadowing(False, R.View.ShadowType.PCF)
    view.set_ambient_occlusion(False)
    view.set_antialiasing(False)
    light = _unit(_unit(scene.center - scene.eye) - 0.5 * scene.up)
    # A directional light that casts no shadow, not the sun: the sun renders its shadow
    # map even with the view's shadowing off, which on lavapipe sometimes takes a minute
    # per frame.
    s.scene.enable_sun_light(False)
    s.scene.add_directional_light(_KEY_LIGHT, [1.0, 1.0, 1.0], light, 90000, False)
    s.scene.set_indirect_light_intensity(20000)
    for name, geometry, mat in _geometries(o3d, scene, width):
        s.add_geometry(name, geometry, mat)
    renderer.setup_camera(K, E, width, height)
    return np.array(renderer.render_to_image(), dtype=np.uint8)[..., :3]


def _save_job(path: Path, scene: _Scene, K: np.ndarray, E: np.ndarray, w: int, h: int):
    """Write what the child process needs to draw the scene (plain arrays, no pickle)."""
    curves = {}
    for key in ("registered", "truth"):
        parts = getattr(scene, key)
        curves[f"{key}_points"] = (
            np.concatenate(parts, axis=0) if parts else np.zeros((0, 3), dtype=np.float64)
        )
        curves[f"{key}_lengths"] = np.array([len(c) for c in parts], dtype=np.int64)
    np.savez(
        path,
        model=np.array(scene.model),
        vertices=scene.vertices,
        faces=scene.faces,
        contact=scene.contact,
        true_contact=(
            np.full(3, np.nan) if scene.true_contact is None else scene.true_contact
        ),
        candidates=scene.candidates,
        center=scene.center,
        eye=scene.eye,
        up=scene.up,
        radius=np.array(scene.radius),
        marker=np.array(scene.marker),
        K=K,
        E=E,
        size=np.array([w, h], dtype=np.int64),
        **curves,
    )


def _load_job(path: str):
    with np.load(path, allow_pickle=False) as z:
        d = {k: z[k] for k in z.files}

    def split(key):
        cuts = np.cumsum(d[f"{key}_lengths"])[:-1]
        pts = d[f"{key}_points"]
        return tuple(np.split(pts, cuts)) if len(d[f"{key}_lengths"]) else ()

    true_contact = None if np.isnan(d["true_contact"]).any() else d["true_contact"]
    scene = _Scene(
        model=str(d["model"]),
        vertices=d["vertices"],
        faces=d["faces"],
        registered=split("registered"),
        truth=split("truth"),
        contact=d["contact"],
        true_contact=true_contact,
        candidates=d["candidates"],
        center=d["center"],
        eye=d["eye"],
        up=d["up"],
        radius=float(d["radius"]),
        marker=float(d["marker"]),
    )
    w, h = (int(v) for v in d["size"])
    return scene, d["K"], d["E"], w, h


def _render_child(job: str, out: str) -> None:
    """Child process: draw the job's scene into ``out`` (.npy), then leave at once.

    open3d 0.20 cannot hold two OffscreenRenderers in one process (destroying them
    aborts it with Filament's "MaterialInstance ... still in use", and a third one
    hangs), so every picture is drawn by one renderer in its own process, which exits
    with ``os._exit`` so that no renderer is ever destroyed.
    """
    scene, K, E, w, h = _load_job(job)
    o3d = check_offscreen()
    image = _draw(o3d, scene, K, E, w, h)
    np.save(out, image)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _render_scene(scene: _Scene, width: int, height: int) -> Snapshot:
    """Render in a child process (see :func:`_render_child`); the parent never draws."""
    import subprocess

    K, E = _camera(scene, width, height)
    with tempfile.TemporaryDirectory(prefix="meshrec-render-") as tmp:
        job, out = Path(tmp) / "job.npz", Path(tmp) / "image.npy"
        _save_job(job, scene, K, E, width, height)
        code = (
            "import sys; from meshrec.figures.viz import _render_child; "
            "_render_child(*sys.argv[1:])"
        )
        try:
            proc = subprocess.run(
                [sys.executable, "-c", code, str(job), str(out)],
                capture_output=True,
                text=True,
                timeout=_RENDER_TIMEOUT,
                check=False,
            )
        except subprocess.TimeoutExpired:
            raise RenderError(
                f"off-screen rendering took more than {_RENDER_TIMEOUT:.0f} s and was stopped"
            ) from None
        if proc.returncode != 0 or not out.exists():
            lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
            last = lines[-1] if lines else "no message"
            raise RenderError(
                f"off-screen rendering failed (exit status {proc.returncode}): {last}"
            )
        linear = np.load(out, allow_pickle=False)
    return Snapshot(
        path=None,
        image=_SRGB[linear],
        intrinsic=K,
        extrinsic=E,
        model=scene.model,
        contact=scene.contact,
    )


def _srgb_table() -> np.ndarray:
    """Linear 0..255 to sRGB-encoded 0..255 (without post-processing Filament writes linear)."""
    c = np.arange(256) / 255.0
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(255.0 * s).astype(np.uint8)


_SRGB = _srgb_table()


def render(
    result,
    path=None,
    *,
    touch=None,
    model: str | None = None,
    truth=None,
    mesh=None,
    size=(1024, 768),
    view: str = "contact",
) -> Snapshot:
    """Render a registration off-screen (no display needed), optionally to a PNG file.

    Parameters
    ----------
    result : Recognition or Registration
        What to show. For a Recognition, the recognised model (or ``model``).
    path : str or os.PathLike, optional
        The PNG to write; its folder is created. Without it the picture is only returned.
    touch : TouchData, optional
        The touch data registered; required with a Registration (a Recognition has it).
    model : str, optional
        The model to show, by name (default: the recognised one).
    truth : SimulatedTouch or dict or str or os.PathLike, optional
        The ground truth (a simulated touch, its :meth:`~SimulatedTouch.truth_dict`, or
        the truth JSON file written by ``meshrec simulate --truth``): the curves are
        also drawn at their true place, in ``COLORS["truth"]``, with the true contact.
    mesh : trimesh.Trimesh or ModelIndex or str or os.PathLike, optional
        The model's mesh (anything with ``vertices`` and ``faces``, or a file); default:
        loaded from the registration's model file.
    size : (2,) int
        (width, height) of the picture, pixels, each 16..8192.
    view : {"contact", "model"}
        Frame the contact region (the curves fill the middle of the picture), or the
        whole model.

    Returns
    -------
    Snapshot
        The picture (``image``, (height, width, 3) uint8) with its camera, for projecting
        model points into it.

    Raises
    ------
    ValueError
        If ``size`` or ``view`` is invalid, ``result`` is not a Recognition or
        Registration, ``model`` is not in it or was rejected, ``touch`` is missing or not
        a TouchData, ``truth`` or ``mesh`` cannot be read, or ``path`` does not end in
        ``.png``.
    VizDependencyError
        If open3d or a library it needs (libusb, a Vulkan driver) cannot load; the
        message names what to install.
    RenderError
        If the child process that draws the picture fails or takes longer than
        ``_RENDER_TIMEOUT`` seconds.
    """
    if path is not None and Path(path).suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    scene, w, h = _prepare(result, touch, model, truth, mesh, size, view)
    o3d = check_offscreen()
    snap = _render_scene(scene, w, h)
    if path is None:
        return snap
    image = o3d.geometry.Image(np.ascontiguousarray(snap.image))

    def write(tmp):
        if not o3d.io.write_image(tmp, image):
            raise ValueError(f"path {str(path)!r} cannot be written")

    return dataclasses.replace(snap, path=write_png_atomic(path, write))


def check_display() -> None:
    """Check that an interactive window can open (a display on Linux).

    Raises
    ------
    ValueError
        On Linux, if neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set; the message
        points to off-screen rendering instead.
    """
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise ValueError(
            "show needs a display, got none (DISPLAY and WAYLAND_DISPLAY are unset): "
            "render to a file instead (meshrec show ... --screenshot OUT.png)"
        )


def show(
    result,
    *,
    touch=None,
    model: str | None = None,
    truth=None,
    mesh=None,
    size=(1024, 768),
    view: str = "contact",
) -> None:
    """Open an interactive open3d window on a registration (returns when it is closed).

    The scene and the initial camera are those of :func:`render`; the window can be
    rotated and zoomed.

    Parameters
    ----------
    result : Recognition or Registration
    touch : TouchData, optional
        Required with a Registration.
    model : str, optional
        The model to show, by name (default: the recognised one).
    truth : SimulatedTouch or dict or str or os.PathLike, optional
        The ground truth, drawn as the true curves and contact.
    mesh : trimesh.Trimesh or ModelIndex or str or os.PathLike, optional
        The model's mesh (default: loaded from the registration's model file).
    size : (2,) int
        (width, height) of the window, pixels.
    view : {"contact", "model"}
        The initial framing.

    Raises
    ------
    ValueError
        As :func:`render`, and if there is no display (``DISPLAY`` and
        ``WAYLAND_DISPLAY`` unset on Linux): use :func:`render` instead.
    VizDependencyError
        If open3d or a library it needs cannot load.
    """
    scene, w, h = _prepare(result, touch, model, truth, mesh, size, view)
    check_display()
    o3d = check_offscreen()
    items = [
        {"name": name, "geometry": g, "material": m} for name, g, m in _geometries(o3d, scene, w)
    ]
    o3d.visualization.draw(
        items,
        title=f"meshrec: {scene.model}",
        width=w,
        height=h,
        lookat=scene.center,
        eye=scene.eye,
        up=scene.up,
        field_of_view=_FOV_DEG,
        bg_color=(*COLORS["background"], 1.0),
        show_skybox=False,
    )
