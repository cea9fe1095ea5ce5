"""Generate the realistic test libraries: mechanical parts and coarse primitives (issue 13).

Two model libraries are written as binary STL files, as a user would bring them:

``models/parts/``
    Twelve mechanical parts in millimetres (brackets, a flange, pipes, a bolt, a nut, a
    knob, a washer, a plate, a shaft, a pulley, a gusset), with fillets, chamfers and
    holes, built by constructive solid geometry with manifold3d and exported at a typical
    CAD resolution: circles cut into segments of at most ``CAD_ANGLE_DEG`` degrees and at
    least ``CAD_EDGE_MM`` long (the exporter's angle and chord settings), flat faces as
    the long thin triangles a CAD tool writes.
``models/primitives/``
    Six trimesh primitives at trimesh's default resolution, unit-sized: a cylinder of 32
    sections, a capsule, an icosphere, a cone, a box and a torus.

The same builders, called with ``fine=True``, give the shapes the coarse files stand for
(circles of 2-degree or 0.5 mm segments, primitives of 360 sections): the "real" objects that
``tools/families.py`` touches. The table of the files (faces, vertices, edge lengths,
watertightness) is printed and written into ``models/README.md`` after the marker line
``<!-- make_parts.py -->`` (everything after it is replaced; ``tools/make_models.py``
keeps it).

The script is deterministic: running it twice writes byte-identical files.

Usage::

    .venv/bin/python tools/make_parts.py [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import manifold3d as mf
import numpy as np
import trimesh

_REPO = Path(__file__).resolve().parent.parent
_DEFAULT_OUT = _REPO / "models"
MARKER = "<!-- make_parts.py -->"

CAD_ANGLE_DEG = 10.0  # the coarse export: at most this angle per circle segment
CAD_EDGE_MM = 1.0  # ... unless that makes segments shorter than this
FINE_ANGLE_DEG = 2.0  # the "real" shapes: circles of 2-degree segments ...
FINE_EDGE_MM = 0.5  # ... or 0.5 mm ones (flat faces need no subdivision to be exact)
FINE_SECTIONS = 360  # the real primitives' sections


# --------------------------------------------------------------------------- CSG helpers
@dataclass(frozen=True)
class _Quality:
    """Circle resolution of one build: segment angle (deg) and shortest segment (mm)."""

    angle: float
    edge: float

    def segments(self, radius: float, degrees: float = 360.0) -> int:
        """Segments of an arc of ``radius`` over ``degrees`` (a multiple of 4 for a circle)."""
        n_angle = degrees / self.angle
        n_edge = math.radians(degrees) * radius / self.edge
        n = max(3, math.ceil(min(n_angle, n_edge)))
        return max(8, 4 * math.ceil(n / 4)) if degrees >= 360.0 else n


def _rounded(cs: mf.CrossSection, convex: float, q: _Quality, concave: float | None = None):
    """A cross-section with its convex corners rounded to ``convex`` and its concave
    corners filleted to ``concave`` (default the same), by offsetting in and out."""
    concave = convex if concave is None else concave
    out = cs.offset(-convex, mf.JoinType.Miter, 2.0).offset(
        convex, mf.JoinType.Round, 2.0, q.segments(convex)
    )
    return out.offset(concave, mf.JoinType.Round, 2.0, q.segments(concave)).offset(
        -concave, mf.JoinType.Round, 2.0, q.segments(concave)
    )


def _poly(points) -> mf.CrossSection:
    """A cross-section from one counter-clockwise outline ``[(x, y), ...]``."""
    return mf.CrossSection([np.asarray(points, dtype=np.float64)])


def _revolve(profile, q: _Quality, fillet: float = 0.0) -> mf.Manifold:
    """A solid of revolution about z from an (r, z) outline, its corners filleted."""
    cs = _poly(profile)
    if fillet > 0:
        cs = _rounded(cs, fillet, q)
    r_max = float(np.max(np.asarray(profile)[:, 0]))
    return mf.Manifold.revolve(cs, q.segments(r_max))


def _cylinder(radius, height, q: _Quality, center=True) -> mf.Manifold:
    """A cylinder along z (centred on the origin by default)."""
    return mf.Manifold.cylinder(height, radius, -1.0, q.segments(radius), center)


def _rot(m: mf.Manifold, x=0.0, y=0.0, z=0.0) -> mf.Manifold:
    """``m`` rotated by Euler angles in degrees."""
    return m.rotate((x, y, z))


# --------------------------------------------------------------------------- the parts
def l_bracket(q):
    """L bracket 60 x 40 x 30 mm, 6 mm thick, filleted bend, two holes per leg."""
    t, a, b, w = 6.0, 60.0, 40.0, 30.0
    outline = _poly([(0, 0), (a, 0), (a, t), (t, t), (t, b), (0, b)])
    body = mf.Manifold.extrude(_rounded(outline, 1.5, q, 4.0), w).translate((0, 0, -w / 2))
    hole = _cylinder(3.2, 3 * t, q)
    for z in (-8.0, 8.0):
        body = body - _rot(hole, x=90).translate((40.0, t / 2, z))
        body = body - _rot(hole, y=90).translate((t / 2, 26.0, z))
    return body


def flange(q):
    """Flange: disc 80 mm across, 10 mm thick, hub 36 mm across, bore 20 mm, 6 bolt holes."""
    profile = [(10, 0), (40, 0), (40, 10), (18, 10), (18, 28), (10, 28)]
    body = _revolve(profile, q, fillet=2.0)
    hole = _cylinder(3.5, 30.0, q)
    for k in range(6):
        ang = 2 * math.pi * k / 6
        body = body - hole.translate((29 * math.cos(ang), 29 * math.sin(ang), 5.0))
    return body


def pipe(q):
    """Straight pipe: 30 mm outside, 24 mm inside, 100 mm long, rounded ends."""
    return _revolve([(12, 0), (15, 0), (15, 100), (12, 100)], q, fillet=1.0)


def pipe_elbow(q):
    """90-degree pipe elbow: 30 mm outside, 22 mm inside, bend radius 40 mm, 20 mm stubs."""
    ring = mf.CrossSection.circle(15.0, q.segments(15.0)) - mf.CrossSection.circle(
        11.0, q.segments(11.0)
    )
    ring = ring.translate((40.0, 0.0))
    bend = mf.Manifold.revolve(ring, q.segments(55.0), 90.0)
    stub = mf.Manifold.extrude(ring.translate((-40.0, 0.0)), 20.0)
    # The bend runs from the xz half-plane (y = 0) to the yz half-plane (x = 0); the stubs
    # continue it along -y and -x.
    a = _rot(stub, x=90).translate((40.0, 0.0, 0.0))
    b = _rot(stub, y=-90).translate((0.0, 40.0, 0.0))
    return bend + a + b


def bolt(q):
    """M10 bolt: hex head 17 mm across flats, 7 mm high, chamfered; shank 40 mm, fillet."""
    flats = 17.0
    r_hex = flats / math.sqrt(3)
    head = mf.Manifold.cylinder(7.0, r_hex, -1.0, 6).rotate((0, 0, 30))
    r_big = r_hex + 0.5  # a 30-degree chamfer of the head's top rim
    top = 7.0 - (r_big - flats / 2) * math.tan(math.radians(30))
    head = head ^ _revolve([(0, 0), (r_big, 0), (r_big, top), (flats / 2, 7.0), (0, 7.0)], q)
    shank = _revolve([(0, -40), (4.3, -40), (5, -39.3), (5, 0.5), (0, 0.5)], q)
    under = _revolve([(0, -1.5), (5, -1.5), (6.5, 0.1), (0, 0.1)], q)  # fillet-like flare
    return head + shank + under


def hex_nut(q):
    """M10 nut: 17 mm across flats, 8 mm high, 10 mm bore, both rims chamfered."""
    flats = 17.0
    body = mf.Manifold.cylinder(8.0, flats / math.sqrt(3), -1.0, 6, True).rotate((0, 0, 30))
    r = flats / math.sqrt(3)
    cham = _revolve([(0, -4), (r - 1.2, -4), (r + 2.8, 0), (r - 1.2, 4), (0, 4)], q)
    return (body ^ cham) - _cylinder(5.0, 10.0, q)


def knob(q):
    """Control knob: 40 mm across, 18 mm high, domed filleted top, 12 grip flutes, bore."""
    profile = [(0, 0), (20, 0), (20, 14), (14, 18), (0, 18)]
    body = _revolve(profile, q, fillet=3.0)
    flute = _cylinder(2.5, 40.0, q)
    for k in range(12):
        ang = 2 * math.pi * k / 12
        body = body - flute.translate((21.0 * math.cos(ang), 21.0 * math.sin(ang), 0.0))
    return body - _cylinder(3.0, 24.0, q).translate((0, 0, 0))


def washer(q):
    """Washer: 40 mm outside, 17 mm bore, 3 mm thick, edges rounded."""
    return _revolve([(8.5, 0), (20, 0), (20, 3), (8.5, 3)], q, fillet=1.0)


def plate(q):
    """Mounting plate 80 x 50 x 6 mm, rounded corners, four holes and a slot."""
    outline = _rounded(_poly([(-40, -25), (40, -25), (40, 25), (-40, 25)]), 6.0, q)
    slot = _rounded(_poly([(-15, -4), (15, -4), (15, 4), (-15, 4)]), 3.9, q)
    body = mf.Manifold.extrude(outline - slot, 6.0)
    hole = _cylinder(3.2, 20.0, q)
    for x in (-32.0, 32.0):
        for y in (-17.0, 17.0):
            body = body - hole.translate((x, y, 3.0))
    return body


def shaft(q):
    """Stepped shaft: 20, 16 and 12 mm diameters over 90 mm, filleted steps, chamfered ends."""
    profile = [(0, 0), (5, 0), (6, 1), (6, 25), (8, 25), (8, 55), (10, 55), (10, 89),
               (9, 90), (0, 90)]
    return _revolve(profile, q, fillet=0.8)


def pulley(q):
    """V-belt pulley: 70 mm across, 20 mm wide, V groove, hub and 12 mm bore."""
    profile = [(6, 0), (35, 0), (35, 4), (27, 10), (35, 16), (35, 20), (14, 20), (14, 26),
               (6, 26)]
    return _revolve(profile, q, fillet=1.0)


def gusset(q):
    """Corner gusset: two 50 x 40 x 5 mm plates at a right angle with a triangular rib."""
    t = 5.0
    outline = _poly([(0, 0), (50, 0), (50, t), (t, t), (t, 50), (0, 50)])
    body = mf.Manifold.extrude(_rounded(outline, 1.5, q, 3.0), 40.0).translate((0, 0, -20.0))
    rib = mf.Manifold.extrude(
        _rounded(_poly([(t, t), (45, t), (t, 45)]), 1.5, q), 4.0
    ).translate((0, 0, -2.0))
    hole = _cylinder(2.7, 3 * t, q)
    body = body + rib
    for z in (-12.0, 12.0):
        body = body - _rot(hole, x=90).translate((32.0, t / 2, z))
        body = body - _rot(hole, y=90).translate((t / 2, 32.0, z))
    return body


PARTS = {
    "bolt": bolt,
    "flange": flange,
    "gusset": gusset,
    "hex_nut": hex_nut,
    "knob": knob,
    "l_bracket": l_bracket,
    "pipe": pipe,
    "pipe_elbow": pipe_elbow,
    "plate": plate,
    "pulley": pulley,
    "shaft": shaft,
    "washer": washer,
}


def build_part(name: str, fine: bool = False) -> trimesh.Trimesh:
    """One part as a mesh, centred on its bounding box; ``fine`` for the real shape.

    Parameters
    ----------
    name : str
        A key of ``PARTS``.
    fine : bool
        Circles at ``FINE_ANGLE_DEG`` / ``FINE_EDGE_MM`` instead of the CAD export's
        ``CAD_ANGLE_DEG`` / ``CAD_EDGE_MM``.

    Returns
    -------
    trimesh.Trimesh
        Millimetres, watertight.
    """
    q = _Quality(FINE_ANGLE_DEG, FINE_EDGE_MM) if fine else _Quality(CAD_ANGLE_DEG, CAD_EDGE_MM)
    solid = PARTS[name](q)
    m = solid.to_mesh()
    mesh = trimesh.Trimesh(
        np.asarray(m.vert_properties[:, :3], dtype=np.float64),
        np.asarray(m.tri_verts, dtype=np.int64),
        process=True,
    )
    lo, hi = mesh.bounds
    mesh.apply_translation(-(lo + hi) / 2)
    return mesh


# --------------------------------------------------------------------------- primitives
def _primitives(fine: bool) -> dict:
    """The six primitives, unit-sized: trimesh defaults (coarse) or their real shapes."""
    c = trimesh.creation
    if not fine:
        return {
            "cylinder": c.cylinder(radius=0.5, height=1.2, sections=32),
            "capsule": c.capsule(height=1.0, radius=0.35),
            "icosphere": c.icosphere(subdivisions=3, radius=0.6),
            "cone": c.cone(radius=0.5, height=1.0, sections=32),
            "box": c.box(extents=(1.0, 0.7, 0.5)),
            "torus": c.torus(major_radius=0.6, minor_radius=0.2),
        }
    return {
        "cylinder": c.cylinder(radius=0.5, height=1.2, sections=FINE_SECTIONS),
        "capsule": c.capsule(height=1.0, radius=0.35, count=(FINE_SECTIONS, FINE_SECTIONS)),
        "icosphere": c.icosphere(subdivisions=6, radius=0.6),
        "cone": c.cone(radius=0.5, height=1.0, sections=FINE_SECTIONS),
        "box": c.box(extents=(1.0, 0.7, 0.5)),
        "torus": c.torus(
            major_radius=0.6,
            minor_radius=0.2,
            major_sections=FINE_SECTIONS,
            minor_sections=FINE_SECTIONS // 2,
        ),
    }


def build_primitive(name: str, fine: bool = False) -> trimesh.Trimesh:
    """One primitive (``cylinder``, ``capsule``, ``icosphere``, ``cone``, ``box``, ``torus``).

    Parameters
    ----------
    name : str
    fine : bool
        The real shape (``FINE_SECTIONS`` sections, a 6-times subdivided icosphere) instead
        of trimesh's default export.

    Returns
    -------
    trimesh.Trimesh
        Unit-sized, watertight, centred on the origin.
    """
    return _primitives(fine)[name]


PRIMITIVES = ("box", "capsule", "cone", "cylinder", "icosphere", "torus")


# --------------------------------------------------------------------------- writing
def _measure(mesh: trimesh.Trimesh) -> dict:
    """Faces, vertices, edge lengths, size and watertightness of a mesh."""
    edges = mesh.edges_unique_length
    return {
        "faces": len(mesh.faces),
        "vertices": len(mesh.vertices),
        "median_edge": float(np.median(edges)),
        "max_edge": float(edges.max()),
        "size": float(np.linalg.norm(mesh.extents)),
        "watertight": bool(mesh.is_watertight),
    }


def _table(rows) -> str:
    """Markdown table of the measured files."""
    lines = [
        "| file | units | faces | vertices | median edge | longest edge | diagonal | watertight |",
        "|---|---|---:|---:|---:|---:|---:|---|",
    ]
    for rel, units, m in rows:
        lines.append(
            f"| `{rel}` | {units} | {m['faces']:,} | {m['vertices']:,} | "
            f"{m['median_edge']:.3g} | {m['max_edge']:.3g} | {m['size']:.3g} | "
            f"{'yes' if m['watertight'] else 'no'} |"
        )
    return "\n".join(lines) + "\n"


def _readme_section(table: str) -> str:
    """The section of ``models/README.md`` that this script writes."""
    parts = "\n".join(f"- `{k}.stl`: {PARTS[k].__doc__.splitlines()[0]}" for k in PARTS)
    return f"""{MARKER}

## `parts/`: mechanical parts at CAD export resolution, millimetres

Written by `tools/make_parts.py` (manifold3d constructive solid geometry, deterministic).
Circles are cut into segments of {CAD_ANGLE_DEG:g} degrees (but none shorter than
{CAD_EDGE_MM:g} mm), as a CAD tool's STL export does at its usual settings; flat faces are
long thin triangles. Each part is centred on its bounding box.

{parts}

## `primitives/`: trimesh primitives at trimesh's default resolution, unit-sized

`trimesh.creation` with its default sections: `cylinder` (radius 0.5, height 1.2, 32
sections: every vertex on the two rims), `capsule` (radius 0.35, height 1.0), `icosphere`
(radius 0.6, 3 subdivisions), `cone` (radius 0.5, height 1.0, 32 sections), `box`
(1.0 x 0.7 x 0.5), `torus` (radii 0.6 and 0.2). The coarse files are the point: they are
what a user brings. `tools/families.py` touches the real shapes (the same builders at
{FINE_ANGLE_DEG:g}-degree circles) and recognises against these files.

{table}"""


def main(argv=None) -> int:
    """Write ``models/parts/`` and ``models/primitives/`` and their README section.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status, 0 on success.
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=_DEFAULT_OUT, help="output folder")
    args = parser.parse_args(argv)
    out = args.out
    rows = []
    for library, names, build, units in (
        ("parts", list(PARTS), build_part, "mm"),
        ("primitives", list(PRIMITIVES), build_primitive, "unit"),
    ):
        folder = out / library
        folder.mkdir(parents=True, exist_ok=True)
        if units == "mm":
            (folder / "meshrec.json").write_text(json.dumps({"units": "mm"}), encoding="utf-8")
        for name in names:
            mesh = build(name)
            if not mesh.is_watertight:
                raise RuntimeError(f"{library}/{name} is not watertight")
            path = folder / f"{name}.stl"
            mesh.export(path, file_type="stl")
            back = trimesh.load(path, file_type="stl", force="mesh")
            rows.append((f"{library}/{name}.stl", units, _measure(back)))
            print(f"wrote {path}", flush=True)
    table = _table(rows)
    print(table, end="")
    readme = out / "README.md"
    text = readme.read_text(encoding="utf-8") if readme.exists() else "# Bundled models\n"
    head = text.split(MARKER)[0].rstrip("\n")
    readme.write_text(head + "\n\n" + _readme_section(table), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
