"""Fixtures shared by the picture tests (test_viz.py, test_plots.py)."""

import types

import pytest
import trimesh

import meshrec

#: A touch that the small ellipsoid below registers at its true place (not its twin).
TOUCH_SEED = 8


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
