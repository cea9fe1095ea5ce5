"""A probe whose error lies along the surface normal (most real probes): the noise
estimates must read its whole deviation, or the right model's fit, which sees exactly that
deviation, looks worse than the noise and no touch is ever ``recognised``.

Before the estimates were taken along the normal (stop 29), every one of these touches
was ``ambiguous``, the right model at probability 1 "fitting worse than the noise" at 1.5
to 1.7 times it (the estimates read sigma / sqrt(3) and sigma / sqrt(2)).
"""

from __future__ import annotations

import numpy as np
import pytest

import meshrec

SIGMA = 0.002  # Gaussian, along the normal only: 3.5 times the default noise's deviation


def _normal_noise_touch(mesh, seed: int) -> meshrec.TouchData:
    """A simulated touch whose noise lies along the contact normal only."""
    sim = meshrec.simulate_touch(mesh, rng=seed, noise=0.0)
    normal = np.array(sim.normal, dtype=np.float64)
    normal = normal / np.linalg.norm(normal)
    rng = np.random.default_rng(10_000 + seed)
    T = np.asarray(sim.T_touch_model)
    curves = []
    for clean in sim.clean_curves:
        noisy = clean + rng.normal(0.0, SIGMA, size=(len(clean), 1)) * normal
        curves.append(noisy @ T[:3, :3].T + T[:3, 3])
    return meshrec.TouchData(curves=curves)


@pytest.mark.parametrize("k", range(4))
def test_normal_noise_is_read_whole_and_the_touch_named(surfaces, k):
    name = surfaces.names[k]
    touch = _normal_noise_touch(surfaces[name], 1000 + k)
    g = meshrec.estimate_local_geometry(touch.curves)
    assert g.fit_rms == pytest.approx(SIGMA, rel=0.15)
    assert g.noise_rms == pytest.approx(SIGMA, rel=0.15)
    rec = meshrec.recognize(touch, surfaces)
    assert (rec.verdict, rec.best.model) == ("recognised", name)
    assert rec.best.rms / rec.noise < 1.1
