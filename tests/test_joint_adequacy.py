"""Several touches: a leading model whose joint fit is worse than the noise is searched again.

The known answers: touches of a sphere of radius 1.1 against a unit sphere (each touch
alone fits it to the noise, no one pose fits all three: not in the library), and three
touches of a scanned can (YCB) across its rims, which fit the can at the true pose to the
noise (the simulation's own pose).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation
from seeded_touches import touches_at, world_pose

import meshrec
from meshrec.recognition import passes as passes_module

YCB = Path(__file__).resolve().parents[2] / "shared" / "data" / "ycb"


def test_a_leader_fitting_worse_than_the_noise_is_searched_again_from_pairs(tmp_path, monkeypatch):
    (tmp_path / "models").mkdir()
    trimesh.creation.icosphere(subdivisions=4, radius=1.0).export(
        tmp_path / "models" / "sphere.stl"
    )
    library = meshrec.ModelLibrary.from_folder(tmp_path / "models", cache_dir=tmp_path / "cache")
    big = trimesh.creation.icosphere(subdivisions=4, radius=1.1)
    rng = np.random.default_rng(4)
    touches, _ = touches_at(big, world_pose(rng), rng)
    searched = []
    original = passes_module.search_pairs

    def spy(touches, model, *args, **kwargs):
        searched.append(model.name)
        return original(touches, model, *args, **kwargs)

    monkeypatch.setattr(passes_module, "search_pairs", spy)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touches, library)
    # the only model leads, and fits worse than the noise: its pose is looked for again
    # from pairs of touches (before: only models well below a leader were)
    assert "sphere" in searched
    # ... and still nothing fits: a sphere 10% larger is not in the library
    assert rec.verdict == "unknown"
    assert "no one rigid pose fits them all" in rec.reason
    # touches each fitting alone, not together: the frames may disagree too (a probe,
    # stop 34: a calibration error that differs per touch)
    assert "hand-eye calibration" in rec.reason


@pytest.mark.slow
@pytest.mark.skipif(not (YCB / "master_chef_can.obj").is_file(), reason="no YCB scans")
def test_three_touches_across_a_scanned_cans_rims_are_recognised(tmp_path):
    """Measured before the change: ``unknown`` (joint RMS 3.1 times the noise, the joint
    search in a wrong basin while the can led); the true pose fits to the noise."""
    names = ("master_chef_can", "tomato_soup_can")
    library = [meshrec.ModelIndex.from_file(YCB / f"{n}.obj", cache_dir=tmp_path) for n in names]
    rng = np.random.default_rng(0)
    sims = [
        meshrec.simulate_touch(
            YCB / "master_chef_can.obj", rng=rng, noise=1e-4, n_points=61, transform=False
        )
        for _ in range(3)
    ]
    size = float(np.linalg.norm(np.ptp(sims[0].touch.points, axis=0)))
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-10 * size, 10 * size, 3)
    touches = [s.touch.transformed(T) for s in sims]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touches, library)
    assert rec.best.model == "master_chef_can"
    assert rec.verdict == "recognised"
    # uniform noise of half-width 1e-4 has an RMS of 5.77e-5
    assert rec.best.rms < 1.2 * 1e-4 / np.sqrt(3)
