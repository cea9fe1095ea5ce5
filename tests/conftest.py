"""Fixtures shared by several tests: the bundled libraries (indexed once per session), the
picture tests (test_viz.py, test_plots.py) and the several-touch tests (test_joint.py,
test_bestfirst.py)."""

import dataclasses
import types
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshrec

MODELS = Path(__file__).resolve().parents[1] / "models"

#: The seed of the touch on the small ellipsoid below.
TOUCH_SEED = 8


def _equivalent_truth(sim, found):
    """The truth as the equivalent pose nearest ``found``: the axis-aligned ellipsoid is
    mapped onto itself by the turns by pi about its axes, so each of its four placements
    is the truth; the search may end at any (the pictures compare against the one found).
    """
    turns = [np.diag(d) for d in ([1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1])]
    S = min(turns, key=lambda R: float(np.linalg.norm(R @ sim.contact - found)))
    S4 = np.eye(4)
    S4[:3, :3] = S
    T_model_touch = S4 @ sim.T_model_touch
    return dataclasses.replace(
        sim,
        contact=S @ sim.contact,
        normal=S @ sim.normal,
        T_model_touch=T_model_touch,
        T_touch_model=np.linalg.inv(T_model_touch),
        clean_curves=tuple(c @ S.T for c in sim.clean_curves),
    )


@pytest.fixture(scope="session")
def surfaces(tmp_path_factory):
    """The paper's four surfaces (``models/surfaces``), indexed once into a fresh cache."""
    cache = tmp_path_factory.mktemp("cache")
    return meshrec.ModelLibrary.from_folder(MODELS / "surfaces", cache_dir=cache)


@pytest.fixture(scope="session")
def objects(tmp_path_factory):
    """The four bundled objects (``models/objects``), indexed once into a fresh cache."""
    cache = tmp_path_factory.mktemp("cache")
    return meshrec.ModelLibrary.from_folder(MODELS / "objects", cache_dir=cache)


@pytest.fixture(scope="session")
def touched_ellipsoid(tmp_path_factory):
    """A small ellipsoid (5120 faces) and a box, a seeded touch on the ellipsoid, its files
    and its recognition."""
    folder = tmp_path_factory.mktemp("models")
    mesh = trimesh.creation.icosphere(subdivisions=4)
    mesh.apply_scale([1.0, 0.8, 0.5])
    mesh.export(folder / "ellipsoid.stl")
    trimesh.creation.box(extents=[2.0, 2.0, 2.0]).export(folder / "box.stl")
    cache = tmp_path_factory.mktemp("cache")
    library = meshrec.ModelLibrary.from_folder(folder, cache_dir=cache)
    model = library["ellipsoid"]
    sim = meshrec.simulate_touch(model, rng=TOUCH_SEED)
    rec = meshrec.recognize(sim.touch, library)
    sim = _equivalent_truth(sim, rec.best.contact)
    files = tmp_path_factory.mktemp("touch")
    sim.write(files / "touch.csv", files / "truth.json")
    return types.SimpleNamespace(
        folder=folder,
        cache=cache,
        library=library,
        model=model,
        sim=sim,
        rec=rec,
        files=files,
        seed=TOUCH_SEED,
    )


@pytest.fixture(scope="session")
def ellipsoid_capsule_torus(tmp_path_factory):
    """A small ellipsoid (axes 1, 0.8, 0.5), a capsule and a torus, about 5k faces each,
    indexed once for the several-touch tests."""
    folder = tmp_path_factory.mktemp("models")
    ellipsoid = trimesh.creation.icosphere(subdivisions=4)
    ellipsoid.apply_scale([1.0, 0.8, 0.5])
    ellipsoid.export(folder / "ellipsoid.stl")
    trimesh.creation.capsule(height=1.0, radius=0.5, count=[48, 48]).export(folder / "capsule.stl")
    trimesh.creation.torus(0.8, 0.3, major_sections=96, minor_sections=48).export(
        folder / "torus.stl"
    )
    return meshrec.ModelLibrary.from_folder(folder, cache_dir=tmp_path_factory.mktemp("cache"))
