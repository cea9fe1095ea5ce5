"""Joint pose seeds from pairs of touches (meshrec.recognition.pairs) and their use.

The known answer: touches simulated on a bumped sphere (asymmetric) placed at a known
pose; short noisy curves (0.2 long, noise 0.004), where each touch alone fits the shape at
many places.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import meshrec
from meshrec import bench, defaults
from meshrec.recognition.joint import register_touches, search_pairs
from meshrec.recognition.pairs import pair_seeds
from meshrec.recognition.scoring import decide, fit_p_value
from meshrec.registration.refine import refine_rigid
from meshrec.registration.register import touch_geometry


@pytest.fixture(scope="module")
def bumped(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pairs")
    bench.write_shapes(bench.shape_set(1, seed=3, families=["bumped_sphere"]), folder)
    cache = tmp_path_factory.mktemp("pairs_cache")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    return library[library.names[0]]


def _touches(model, seed: int, count: int = 3):
    rng = np.random.default_rng(seed)
    T_world_model = np.eye(4)
    T_world_model[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T_world_model[:3, 3] = rng.uniform(-1, 1, 3)
    touches = [
        meshrec.simulate_touch(
            model, length=0.2, noise=0.004, rng=rng, transform=False
        ).touch.transformed(T_world_model)
        for _ in range(count)
    ]
    return touches, np.linalg.inv(T_world_model)


def _displacement(T, T_true, touches) -> float:
    """Largest distance between the touches' points mapped by ``T`` and by the truth."""
    points = np.vstack([t.points for t in touches])
    a = points @ T[:3, :3].T + T[:3, 3]
    b = points @ T_true[:3, :3].T + T_true[:3, 3]
    return float(np.linalg.norm(a - b, axis=1).max())


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "count"), [(0, 3), (2, 3), (5, 2)])
def test_pair_seeds_hold_the_true_pose_and_search_pairs_reaches_it(bumped, seed, count):
    touches, T_true = _touches(bumped, seed, count)
    geometries = [touch_geometry(t) for t in touches]
    seeds = pair_seeds(touches, bumped, geometries)
    assert 1 <= len(seeds) <= defaults.PAIR_KEEP
    for T in seeds:
        assert T.shape == (4, 4)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
        assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    # A seed near the truth (about the spread's spacing, much less than the shape's size)
    assert min(_displacement(T, T_true, touches) for T in seeds) < 0.5
    first = register_touches(touches, bumped, geometries, upto=1)
    fit = search_pairs(touches, bumped, geometries, first)
    # ... and the joint search from them fits as well as the true pose refined does (short
    # noisy touches may fit another pose as well: that is for the scores to say)
    points = np.vstack([t.points for t in touches])
    truth = refine_rigid(bumped, points, T_true)
    # (two short noisy touches on a nearly round shape pin the pose loosely: the refined
    # truth slides up to about 0.11 of the unit-size shape, measured on seed 5)
    assert _displacement(truth.T_model_touch, T_true, touches) < 0.15
    assert fit.registration.rms <= truth.rms * 1.001
    assert fit.registration.rms <= first.registration.rms
    assert fit.registration.rms < 1.2 * 0.004 / np.sqrt(3)  # uniform noise's RMS, +20%
    assert fit.single == first.single


def test_pair_seeds_keep_at_most_keep(bumped):
    touches, _ = _touches(bumped, 5, count=2)
    geometries = [touch_geometry(t) for t in touches]
    seeds = pair_seeds(touches, bumped, geometries, keep=5)
    assert 1 <= len(seeds) <= 5


def test_pair_seeds_and_search_pairs_refuse_bad_input(bumped):
    touches, _ = _touches(bumped, 0, count=2)
    geometries = [touch_geometry(t) for t in touches]
    with pytest.raises(ValueError, match="at least two touches, got 1"):
        pair_seeds(touches[:1], bumped, geometries[:1])
    with pytest.raises(ValueError, match=r"one LocalGeometry per touch \(2\), got 1"):
        pair_seeds(touches, bumped, geometries[:1])
    for keep in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="keep must be a positive integer"):
            pair_seeds(touches, bumped, geometries, keep=keep)
    first = register_touches(touches, bumped, geometries, upto=1)
    with pytest.raises(ValueError, match="at least two touches, got 1"):
        search_pairs(touches[:1], bumped, geometries[:1], first)


def _rms_at_p(p: float, n: int, noise: float) -> float:
    """The RMS residual whose chi-square tail is ``p`` (bisection on fit_p_value)."""
    lo, hi = noise * 0.5, noise * 10
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fit_p_value(mid, n, noise) > p else (lo, mid)
    return 0.5 * (lo + hi)


def test_one_model_fitting_worse_than_the_noise_is_not_recognised():
    n, noise = 300, 0.002
    names, probs = ["a", "b", "c"], [0.999, 0.0009, 0.0001]
    # Between the unknown and the recognise thresholds: the fit is poor but not hopeless
    p = np.sqrt(defaults.UNKNOWN_P_VALUE * defaults.RECOGNISE_P_VALUE)
    poor = _rms_at_p(p, n, noise)
    assert poor / noise <= defaults.UNKNOWN_FIT_RATIO or p >= defaults.UNKNOWN_P_VALUE
    v = decide(names, probs, poor, n, noise)
    assert v.verdict == "ambiguous"
    assert v.plausible == ("a", "b")
    assert "worse than the noise allows" in v.reason
    # The same probabilities with a fit to the noise: recognised
    good = _rms_at_p(0.5, n, noise)
    assert decide(names, probs, good, n, noise).verdict == "recognised"
    # A library of one model: nothing else could have been missed
    assert decide(["a"], [1.0], poor, n, noise).verdict == "recognised"


def test_pair_screen_tree_gives_the_exact_nearest_sites(bumped, monkeypatch):
    # The screen's KD tree is built for speed (without compact nodes). Its capped
    # distances are the brute-force nearest sites' (points near the surface and far off),
    # and the seeds are those of scipy's default tree: the same poses, in the same order.
    import meshrec.recognition.pairs as pairs_module

    sites = np.vstack([bumped.mesh.vertices, bumped.curvature.points])
    rng = np.random.default_rng(4)
    x = sites[rng.integers(len(sites), size=600)] + rng.normal(scale=0.05, size=(600, 3))
    cap = 0.08
    got = pairs_module.cKDTree(sites, compact_nodes=False).query(x, distance_upper_bound=cap)[0]
    d = x[:, None, :] - sites[None, :, :]
    brute = np.sqrt((d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) + d[..., 2] * d[..., 2])
    brute = brute.min(axis=1)
    assert np.isinf(got).any()  # capped ...
    assert np.isfinite(got).any()  # ... and not
    np.testing.assert_array_equal(got, np.where(brute < cap, brute, np.inf))

    touches, _ = _touches(bumped, 2, count=3)
    geometries = [touch_geometry(t) for t in touches]
    fast = pair_seeds(touches, bumped, geometries, keep=8)
    original = pairs_module.cKDTree
    monkeypatch.setattr(pairs_module, "cKDTree", lambda points, *args, **kwargs: original(points))
    default = pair_seeds(touches, bumped, geometries, keep=8)
    assert len(fast) == len(default) >= 1
    for a, b in zip(fast, default, strict=True):
        np.testing.assert_array_equal(a, b)


def test_pair_seeds_are_rigid_where_a_model_pairs_frame_is_undefined(tmp_path):
    # Two touches of a box (40 x 30 x 20) at a seeded pose (a black-box probe's case,
    # stop 32): some model point pairs lie on two faces at right angles with the baseline
    # along their bisector, where the pair's frame is undefined. Their "rotations" were
    # singular, squashed the touches onto a line that fits any surface to 1e-15, and were
    # all 32 seeds kept; the box was then left out of `plausible`. Every seed must be a
    # rotation, and the recognition names the box at a pose that fits to the noise.
    import trimesh

    (tmp_path / "models").mkdir()
    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    box.export(tmp_path / "models" / "box.stl")
    trimesh.creation.box(extents=(60.0, 45.0, 6.0)).export(tmp_path / "models" / "plate.stl")
    library = meshrec.ModelLibrary.from_folder(tmp_path / "models", cache_dir=tmp_path / "cache")
    rng = np.random.default_rng(4001)
    q = rng.normal(size=4)
    T_world_model = trimesh.transformations.quaternion_matrix(q / np.linalg.norm(q))
    T_world_model[:3, 3] = rng.uniform(-200, 200, 3)
    touches = [
        meshrec.simulate_touch(
            box, rng=200 + k, noise=0.02, n_points=61, transform=False
        ).touch.transformed(T_world_model)
        for k in range(2)
    ]
    geometries = [touch_geometry(t) for t in touches]
    seeds = pair_seeds(touches, library["box"], geometries)
    assert len(seeds) >= 1
    for T in seeds:
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
        assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    rec = meshrec.recognize(touches, library)
    assert rec.best.model == "box"
    assert "box" in rec.plausible
    R = rec.best.T_model_touch[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert rec.best.rms < 2.0 * 0.02 / np.sqrt(3)  # uniform noise's RMS, twice
