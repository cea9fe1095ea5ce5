"""The simulated probe's ray: first hit against analytic answers."""

import numpy as np
import pytest
import trimesh

from meshrec.sim.probe import first_hit


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=5, radius=2.0)


def test_a_ray_through_the_centre_hits_the_near_side(sphere):
    hit = first_hit(sphere.vertices, sphere.faces, [10.0, 0.0, 0.0], [-3.0, 0.0, 0.0])
    # the facets lie inside the sphere by at most its chord error (~1e-3 at this size)
    assert hit[0] == pytest.approx(2.0, abs=3e-3)
    assert np.abs(hit[1:]).max() < 1e-9


def test_an_off_centre_ray_hits_where_the_circle_says(sphere):
    hit = first_hit(sphere.vertices, sphere.faces, [5.0, 1.2, 0.0], [-1.0, 0.0, 0.0])
    assert hit[0] == pytest.approx(np.sqrt(4.0 - 1.2**2), abs=5e-3)
    assert hit[1] == pytest.approx(1.2)


def test_a_ray_that_misses_gives_none(sphere):
    assert first_hit(sphere.vertices, sphere.faces, [5.0, 3.0, 0.0], [-1.0, 0.0, 0.0]) is None
    assert first_hit(sphere.vertices, sphere.faces, [5.0, 0.0, 0.0], [1.0, 0.0, 0.0]) is None


@pytest.mark.parametrize(
    ("origin", "direction", "message"),
    [
        ([0.0, 0.0], [1.0, 0.0, 0.0], "origin"),
        ([0.0, 0.0, np.nan], [1.0, 0.0, 0.0], "origin"),
        ([5.0, 0.0, 0.0], [0.0, 0.0, 0.0], "direction"),
    ],
)
def test_bad_rays_are_refused(sphere, origin, direction, message):
    with pytest.raises(ValueError, match=message):
        first_hit(sphere.vertices, sphere.faces, origin, direction)
