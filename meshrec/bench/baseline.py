"""The baseline a user would otherwise reach for: Open3D's point-cloud registration.

Two registrations of the touch points onto a model, both finished by point-to-plane ICP:

* ``"fpfh"``: FPFH features and RANSAC feature matching (Open3D's global registration
  pipeline), then ICP;
* ``"multistart"``: ICP from many random poses (a random rotation, the data's centroid
  placed on a random point of the surface), keeping the best.

The model is a point cloud sampled uniformly on the mesh with its face normals. The
result is scored with meshrec's own measure (mean point-to-surface distance per data
point, from the mesh) so that the two methods are compared on the same footing. Open3D is
imported only when a baseline runs (``pip install open3d``; on Debian it also needs the
system library ``libusb-1.0-0``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from meshrec import defaults
from meshrec.io.touch import TouchData
from meshrec.registration.objective import mean_distances
from meshrec.registration.transform import apply_transform

__all__ = [
    "BASELINE_METHODS",
    "BaselineModel",
    "BaselineResult",
    "baseline_register",
    "load_open3d",
]

BASELINE_METHODS = ("fpfh", "multistart")


@dataclass(frozen=True, eq=False)
class BaselineResult:
    """A baseline registration of touch data onto one model.

    Attributes
    ----------
    model : str
        Model name.
    method : str
        ``"fpfh"`` or ``"multistart"``.
    error : float
        Mean point-to-surface distance per data point, model units (meshrec's measure).
    T_model_touch : (4, 4) float
        Maps touch-frame points to model coordinates.
    seconds : float
        Wall time (the model's samples and features are prepared once, not counted, as
        meshrec's index is not).
    """

    model: str
    method: str
    error: float
    T_model_touch: np.ndarray
    seconds: float

    def __repr__(self) -> str:
        return (
            f"BaselineResult({self.model!r}, {self.method}, error={self.error:.6g}, "
            f"seconds={self.seconds:.3f})"
        )


def load_open3d():
    """Import Open3D, or raise an error naming what to install.

    Returns
    -------
    module
        The ``open3d`` module.

    Raises
    ------
    ImportError
        If open3d or a system library it needs is missing; the message names them.
    """
    try:
        import open3d
    except ImportError as exc:  # also OSError-like failures surface as ImportError here
        raise ImportError(
            "the Open3D baseline needs open3d (pip install open3d; on Debian also "
            f"apt-get install libusb-1.0-0): {exc}"
        ) from exc
    open3d.utility.set_verbosity_level(open3d.utility.VerbosityLevel.Error)
    return open3d


@dataclass(frozen=True, eq=False)
class BaselineModel:
    """A model prepared for the baseline once, as a user would: samples and features.

    Build it with :meth:`from_index`.

    Attributes
    ----------
    index : ModelIndex
        The model (its mesh scores the results).
    cloud : open3d.geometry.PointCloud
        Points sampled uniformly by area, with their face normals.
    features : dict
        FPFH features of ``cloud`` by radius (filled on first use).
    seconds : float
        Time the sampling took.
    """

    index: object
    cloud: object
    features: dict
    seconds: float

    @classmethod
    def from_index(cls, model, rng: np.random.Generator | int | None = None) -> BaselineModel:
        """Sample ``defaults.BASELINE_MODEL_POINTS`` points on the model's mesh.

        Parameters
        ----------
        model : ModelIndex
        rng : numpy.random.Generator or int or None

        Returns
        -------
        BaselineModel

        Raises
        ------
        ImportError
            If Open3D cannot be imported.
        """
        o3d = load_open3d()
        rng = np.random.default_rng(rng)
        t0 = time.perf_counter()
        # Uniform samples by area with their face's normal. (trimesh.sample does the same
        # on a Trimesh; the index holds bare arrays, so sample barycentrically here.)
        v, f = model.mesh.vertices, model.mesh.faces
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        n = defaults.BASELINE_MODEL_POINTS
        face = rng.choice(len(f), size=n, p=area / area.sum())
        s, r2 = np.sqrt(rng.random(n)), rng.random(n)
        bary = np.column_stack([1 - s, s * (1 - r2), s * r2])
        samples = np.einsum("ni,nij->nj", bary, v[f[face]])
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(samples))
        cloud.normals = o3d.utility.Vector3dVector(model.mesh.face_normals[face])
        return cls(index=model, cloud=cloud, features={}, seconds=time.perf_counter() - t0)

    def fpfh(self, radius: float):
        """FPFH features of the cloud at ``radius`` (computed once per radius)."""
        key = round(float(radius), 12)
        if key not in self.features:
            o3d = load_open3d()
            param = o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=100)
            self.features[key] = o3d.pipelines.registration.compute_fpfh_feature(
                self.cloud, param
            )
        return self.features[key]


def baseline_register(
    touch: TouchData,
    target: BaselineModel,
    method: str = "multistart",
    starts: int = defaults.BASELINE_STARTS,
    rng: np.random.Generator | int | None = None,
) -> BaselineResult:
    """Register touch data onto one model with Open3D (see the module docstring).

    Parameters
    ----------
    touch : TouchData
        The curves, in the touch frame.
    target : BaselineModel
        The model, prepared.
    method : {"fpfh", "multistart"}
        The baseline.
    starts : int
        Random starts of the multi-start ICP (ignored by ``"fpfh"``).
    rng : numpy.random.Generator or int or None
        Randomness (starts, RANSAC's seed).

    Returns
    -------
    BaselineResult

    Raises
    ------
    ValueError
        If ``method`` is unknown or ``starts`` is not a positive integer.
    ImportError
        If Open3D cannot be imported.
    """
    if method not in BASELINE_METHODS:
        raise ValueError(f"method must be one of {BASELINE_METHODS}, got {method!r}")
    if not isinstance(starts, (int, np.integer)) or starts < 1:
        raise ValueError(f"starts must be a positive integer, got {starts!r}")
    o3d = load_open3d()
    reg = o3d.pipelines.registration
    rng = np.random.default_rng(rng)
    t0 = time.perf_counter()
    model, dst = target.index, target.cloud
    points = touch.points
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    src.estimate_normals(
        o3d.geometry.KDTreeSearchParamHybrid(
            radius=defaults.BASELINE_NORMAL_RADIUS * extent, max_nn=30
        )
    )
    icp_dist = defaults.BASELINE_ICP_DISTANCE * extent
    criteria = reg.ICPConvergenceCriteria(max_iteration=defaults.BASELINE_ICP_ITERATIONS)
    p2l = reg.TransformationEstimationPointToPlane()

    def icp(T0):
        return reg.registration_icp(src, dst, icp_dist, T0, p2l, criteria)

    if method == "fpfh":
        radius = defaults.BASELINE_FPFH_RADIUS * extent
        param = o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=100)
        f_src = reg.compute_fpfh_feature(src, param)
        f_dst = target.fpfh(radius)
        o3d.utility.random.seed(int(rng.integers(2**31 - 1)))
        ransac_dist = defaults.BASELINE_RANSAC_DISTANCE * extent
        coarse = reg.registration_ransac_based_on_feature_matching(
            src, dst, f_src, f_dst, False, ransac_dist,
            reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(ransac_dist)],
            reg.RANSACConvergenceCriteria(defaults.BASELINE_RANSAC_ITERATIONS, 0.999),
        )
        candidates = [icp(coarse.transformation).transformation]
    else:
        centroid = touch.points.mean(axis=0)
        targets = np.asarray(dst.points)[rng.integers(len(dst.points), size=starts)]
        rotations = Rotation.random(starts, random_state=rng).as_matrix()
        results = []
        for R, q in zip(rotations, targets, strict=True):
            T0 = np.eye(4)
            T0[:3, :3] = R
            T0[:3, 3] = q - R @ centroid
            r = icp(T0)
            # Rank by the fraction of points matched, then their RMS distance.
            results.append((-r.fitness, r.inlier_rmse, r.transformation))
        results.sort(key=lambda t: (t[0], t[1]))
        candidates = [t[2] for t in results[: defaults.BASELINE_RESCORED]]
    # Score the best few with meshrec's measure on the mesh itself.
    placed = np.array([apply_transform(np.asarray(T), touch.points) for T in candidates])
    errors = mean_distances(model, placed)
    k = int(np.argmin(errors))
    return BaselineResult(
        model=model.name,
        method=method,
        error=float(errors[k]),
        T_model_touch=np.array(candidates[k]),
        seconds=time.perf_counter() - t0,
    )
