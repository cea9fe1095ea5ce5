"""A touch with its normal given stays on that side of a thin wall
(meshrec.registration.poses.pose_hypotheses)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import meshrec


def _tube(r_in: float) -> trimesh.Trimesh:
    """A tube with a 1 mm wall, inner radius ``r_in``, 40 long, in mm."""
    return trimesh.creation.annulus(r_min=r_in, r_max=r_in + 1.0, height=40.0, sections=256)


@pytest.fixture(scope="module")
def tube(tmp_path_factory):
    folder = tmp_path_factory.mktemp("models")
    _tube(14.0).export(folder / "tube.stl")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path_factory.mktemp("cache"))
    return library["tube"]


def _inside(mesh, r_in: float, seed: int):
    """A touch of the tube's inner wall with its outward normal (into the bore)."""
    sim = meshrec.simulate_touch(
        mesh, contact=(r_in, 0.0, 0.0), rng=seed, n_points=41, noise=0.01, length=10.0
    )
    return sim.touch.with_hints(normal=sim.T_touch_model[:3, :3] @ sim.normal)


def _placed_normals_agree(reg, touch) -> list[float]:
    """Per pose, the model's normal at its contact against the touch's normal placed."""
    return [float(p.normal @ (p.T_model_touch[:3, :3] @ touch.normal)) for p in reg.poses]


def test_the_inside_of_a_wider_tube_is_not_placed_on_the_outside_of_a_thin_one(tube):
    # A black-box probe (stop 34): the inside of a tube of radius 16 (not in the folder),
    # its normal given, against a tube of radii 14 and 15: the refinement carried the
    # data through the 1 mm wall onto the outer surface (radius 15 fits a concave radius
    # 16 better than the inner 14 does), where the data's normal points into the
    # material. No such pose is kept.
    touch = _inside(_tube(16.0), 16.0, 1048)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = meshrec.register(touch, tube)
    assert reg.rejected or min(_placed_normals_agree(reg, touch)) > 0.0
    if reg.rejected:
        assert "through the surface" in reg.reason


def test_the_inside_of_the_tube_itself_is_placed_on_its_inner_wall(tube):
    touch = _inside(_tube(14.0), 14.0, 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = meshrec.register(touch, tube)
    assert not reg.rejected
    assert min(_placed_normals_agree(reg, touch)) > 0.0
    assert np.hypot(*reg.contact[:2]) == pytest.approx(14.0, abs=0.05)
    assert reg.rms < 0.02


def test_keeps_side_tells_the_inner_wall_from_the_outer_one(tube):
    # The same touch at its true pose (on the inner wall) and moved 1 mm outwards onto the
    # outer wall, where its given normal (into the bore) points into the material.
    from meshrec.registration.poses import keeps_side

    touch = _inside(_tube(14.0), 14.0, 5)
    sim = meshrec.simulate_touch(
        _tube(14.0), contact=(14.0, 0.0, 0.0), rng=5, n_points=41, noise=0.01, length=10.0
    )
    T_true = np.linalg.inv(sim.T_touch_model)
    out = np.eye(4)
    out[0, 3] = 1.0
    geometry = meshrec.estimate_local_geometry(touch.curves)
    assert keeps_side(tube, touch, geometry, T_true)
    assert not keeps_side(tube, touch, geometry, out @ T_true)
    # without the normal the side is not known: both are placements
    bare = sim.touch
    assert keeps_side(tube, bare, geometry, out @ T_true)


def test_several_touches_inside_a_wider_tube_are_not_placed_through_the_wall(tube):
    # Three touches of a radius-16 bore, normals given, against the 14/15 tube: the joint
    # refinements are held to the same test as one touch's poses.
    wide = _tube(16.0)
    touches = []
    for k, angle in enumerate((0.0, 0.5, -0.4)):
        c = (16.0 * np.cos(angle), 16.0 * np.sin(angle), 5.0 * k - 5.0)
        sim = meshrec.simulate_touch(
            wide, contact=c, rng=k, n_points=41, noise=0.01, length=10.0, transform=False
        )
        touches.append(sim.touch.with_hints(normal=sim.normal))
    library = meshrec.ModelLibrary(None, (tube,))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = meshrec.recognize(touches, library)
    best = rec.ranking[0]
    for p in best.poses:
        for t in touches:
            g = meshrec.estimate_local_geometry(t.curves)
            placed = p.T_model_touch[:3, :3] @ g.point + p.T_model_touch[:3, 3]
            _, closest, face = tube.surface.closest_points(placed[None])
            n = tube.surface.interpolated_normals(closest, face)[0]
            assert n @ (p.T_model_touch[:3, :3] @ t.normal) > -0.5
