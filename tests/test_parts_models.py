"""Checks of the realistic test libraries ``models/parts/`` and ``models/primitives/``.

The expected sizes, hole counts and volumes are written out here from the parts'
descriptions (``models/README.md``), independently of ``tools/make_parts.py``; the files
are also checked to be what the script writes today.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

REPO = Path(__file__).resolve().parent.parent
MODELS = REPO / "models"



def _fillet_loss(radius: float, at_radii) -> float:
    """Volume a fillet of ``radius`` takes off a corner of a revolved rectangle, summed over
    the corners at the given distances from the axis (Pappus: area times the path of the
    removed piece's centroid, 0.2234 r from the corner)."""
    area = (1 - math.pi / 4) * radius**2
    return sum(2 * math.pi * area * r for r in at_radii)


# name: (bounding-box extents in mm, through holes (genus), analytic volume or None)
PARTS = {
    "bolt": ((17 / math.sqrt(3) * 2, 17.0, 47.0), 0, None),
    "flange": ((80.0, 80.0, 28.0), 7, None),
    "gusset": ((50.0, 50.0, 40.0), 4, None),
    "hex_nut": ((17 / math.sqrt(3) * 2, 17.0, 8.0), 1, None),
    "knob": ((40.0, 40.0, 18.0), 0, None),
    "l_bracket": ((60.0, 40.0, 30.0), 4, None),
    "pipe": (
        (30.0, 30.0, 100.0),
        1,
        math.pi * (15**2 - 12**2) * 100 - _fillet_loss(1.0, [14.78, 14.78, 12.22, 12.22]),
    ),
    "pipe_elbow": ((75.0, 75.0, 30.0), 1, math.pi * (15**2 - 11**2) * (math.pi / 2 * 40 + 40)),
    "plate": ((80.0, 50.0, 6.0), 5, None),
    "pulley": ((70.0, 70.0, 26.0), 1, None),
    "shaft": ((20.0, 20.0, 90.0), 0, None),
    "washer": (
        (40.0, 40.0, 3.0),
        1,
        math.pi * (20**2 - 8.5**2) * 3 - _fillet_loss(1.0, [19.78, 19.78, 8.72, 8.72]),
    ),
}
# name: (faces of trimesh's default export, volume of the real shape)
PRIMITIVES = {
    "box": (12, 1.0 * 0.7 * 0.5),
    "capsule": (None, math.pi * 0.35**2 * 1.0 + 4 / 3 * math.pi * 0.35**3),
    "cone": (64, math.pi * 0.5**2 * 1.0 / 3),
    "cylinder": (128, math.pi * 0.5**2 * 1.2),
    "icosphere": (1280, 4 / 3 * math.pi * 0.6**3),
    "torus": (None, 2 * math.pi**2 * 0.6 * 0.2**2),
}


def _load(rel: str) -> trimesh.Trimesh:
    return trimesh.load(MODELS / rel, file_type="stl", force="mesh")


def test_the_folders_hold_exactly_the_listed_files():
    assert sorted(p.stem for p in (MODELS / "parts").glob("*.stl")) == sorted(PARTS)
    assert sorted(p.stem for p in (MODELS / "primitives").glob("*.stl")) == sorted(PRIMITIVES)
    assert json.loads((MODELS / "parts" / "meshrec.json").read_text()) == {"units": "mm"}
    assert not (MODELS / "primitives" / "meshrec.json").exists()  # unit-sized


@pytest.mark.parametrize("name", sorted(PARTS))
def test_part_is_a_watertight_solid_of_its_size_and_holes(name):
    extents, holes, volume = PARTS[name]
    mesh = _load(f"parts/{name}.stl")
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0.0
    assert mesh.euler_number == 2 - 2 * holes
    np.testing.assert_allclose(np.sort(mesh.extents), np.sort(extents), rtol=0.02)
    np.testing.assert_allclose(mesh.bounds.mean(axis=0), 0.0, atol=1e-3)  # centred
    if volume is not None:  # 10-degree facets and small fillets: within 2%
        assert mesh.volume == pytest.approx(volume, rel=0.02)
    # a CAD export: few triangles, long thin ones on the flat faces
    assert len(mesh.faces) < 10_000
    assert mesh.edges_unique_length.max() > 5 * np.median(mesh.edges_unique_length)


@pytest.mark.parametrize("name", sorted(PRIMITIVES))
def test_primitive_is_trimesh_default_export(name):
    faces, volume = PRIMITIVES[name]
    mesh = _load(f"primitives/{name}.stl")
    assert mesh.is_watertight
    if faces is not None:
        assert len(mesh.faces) == faces
    assert 0.9 * volume < mesh.volume <= volume * (1 + 1e-6)  # inscribed facets


def test_coarse_cylinder_has_every_vertex_on_its_rims():
    mesh = _load("primitives/cylinder.stl")
    np.testing.assert_allclose(np.abs(mesh.vertices[:, 2]), 0.6, atol=1e-6)


@pytest.fixture(scope="module")
def make_parts():
    pytest.importorskip("manifold3d")
    sys.path.insert(0, str(REPO / "tools"))
    try:
        import make_parts

        yield make_parts
    finally:
        sys.path.remove(str(REPO / "tools"))


@pytest.mark.parametrize("name", ["washer", "l_bracket", "bolt"])
def test_files_are_what_the_script_writes(make_parts, name, tmp_path):
    path = tmp_path / f"{name}.stl"
    make_parts.build_part(name).export(path, file_type="stl")
    assert path.read_bytes() == (MODELS / "parts" / f"{name}.stl").read_bytes()


@pytest.mark.parametrize("name", ["washer", "hex_nut", "plate"])
def test_real_part_is_the_same_shape_finer(make_parts, name):
    coarse = _load(f"parts/{name}.stl")
    fine = make_parts.build_part(name, fine=True)
    assert fine.is_watertight
    assert len(fine.faces) > len(coarse.faces)
    assert fine.volume == pytest.approx(coarse.volume, rel=0.02)
    np.testing.assert_allclose(fine.bounds, coarse.bounds, atol=0.3)
