"""Tests for meshrec.sim.paper: symmetry groups and implicit distances of the paper's surfaces."""

import numpy as np
import pytest

from meshrec.sim.paper import (
    PAPER_SURFACES,
    implicit_distance,
    localisation_error,
    symmetry_rotations,
)


def _surface_points(name, rng, n=200):
    u, v = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    if name == "ellipsoid":
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        return d * [1.0, 0.8, 0.5]
    if name == "elliptic_paraboloid":
        return np.stack([1.5 * u, 1.1 * v, u**2 + v**2], 1)
    if name == "monkey_saddle":
        return np.stack([u, v, u**3 - 3 * u * v**2], 1)
    return np.stack([u, v, u**2 * v**2], 1)


@pytest.mark.parametrize("name", PAPER_SURFACES)
def test_symmetries_map_the_surface_onto_itself(name):
    rng = np.random.default_rng(0)
    pts = _surface_points(name, rng)
    assert np.all(implicit_distance(name, pts) < 1e-12)
    group = symmetry_rotations(name)
    assert np.allclose(group[0], np.eye(3))
    for R in group:
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert np.all(implicit_distance(name, pts @ R.T) < 1e-9)


def test_group_sizes():
    assert [len(symmetry_rotations(n)) for n in PAPER_SURFACES] == [4, 2, 6, 4]


def test_implicit_distance_first_order():
    # A point 0.01 above the paraboloid's apex is 0.01 away.
    d = implicit_distance("elliptic_paraboloid", np.array([[0.0, 0.0, 0.01]]))
    assert d[0] == pytest.approx(0.01)


def test_localisation_error_modulo_symmetry():
    p = np.array([0.3, 0.4, 0.2])
    flipped = np.array([-0.3, -0.4, 0.2])  # 180 degrees about z
    assert localisation_error("elliptic_paraboloid", p, flipped) == pytest.approx(0.0)
    assert localisation_error("monkey_saddle", p, flipped) > 0.1


@pytest.mark.parametrize(
    "call",
    [
        lambda: symmetry_rotations("torus"),
        lambda: implicit_distance("torus", np.zeros((1, 3))),
        lambda: localisation_error("torus", np.zeros(3), np.zeros(3)),
    ],
)
def test_unknown_surface(call):
    with pytest.raises(ValueError, match="name must be one of"):
        call()


def test_implicit_distance_shape_error():
    with pytest.raises(ValueError, match=r"points must be \(n, 3\), got \(3,\)"):
        implicit_distance("ellipsoid", np.zeros(3))


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: symmetry_rotations(3), TypeError, "name must be one of .* got int"),
        (lambda: implicit_distance("ellipsoid", "xyz"), TypeError, "points must be an array"),
        (
            lambda: implicit_distance("ellipsoid", np.zeros((2, 3), dtype=complex)),
            TypeError,
            "points must hold real numbers",
        ),
        (
            lambda: implicit_distance("ellipsoid", [[0.0, np.nan, 0.0]]),
            ValueError,
            "points has a non-finite point at row 0",
        ),
        (
            lambda: localisation_error("ellipsoid", [0, 0], np.zeros(3)),
            ValueError,
            r"true_contact must be \(3,\), got \(2,\)",
        ),
        (
            lambda: localisation_error("ellipsoid", np.zeros(3), None),
            TypeError,
            "found_contact must be an array of real numbers",
        ),
    ],
)
def test_argument_checks(call, error, match):
    with pytest.raises(error, match=match):
        call()
