"""The text of models/README.md and its table of measurements."""

from __future__ import annotations

from shapes.params import N_SAMPLES

__all__ = ["TABLE_HEADER", "measurement_table", "readme_text"]


TABLE_HEADER = (
    "| file | units | faces | vertices | mean edge | min angle (°) | max deviation "
    "| RMS deviation | size (KiB) |\n"
    "|---|---|---:|---:|---:|---:|---:|---:|---:|\n"
)


def measurement_table(rows):
    """Markdown table of the measurements.

    Parameters
    ----------
    rows : list of (str, str, dict, int)
        Relative file path, units, measurements, file size in bytes.

    Returns
    -------
    str
    """
    lines = [
        f"| `{path}` | {units} | {m['faces']:,} | {m['vertices']:,} | {m['mean_edge']:#.4g} "
        f"| {m['min_angle']:.1f} | {m['dev_max']:.2e} | {m['dev_rms']:.2e} "
        f"| {size / 1024:,.0f} |"
        for path, units, m, size in rows
    ]
    return TABLE_HEADER + "\n".join(lines) + "\n"


def readme_text(models, table):
    """Text of ``models/README.md``.

    Parameters
    ----------
    models : list of Model
        The bundled models.
    table : str
        Markdown table of the measurements.

    Returns
    -------
    str
    """

    def shapes(library):
        return "\n".join(f"- `{m.name}.stl`: {m.shape}" for m in models if m.library == library)

    return f"""# Bundled models

Binary STL meshes written by `tools/make_models.py` (run it again to regenerate them; it is
deterministic). Do not edit them by hand.

## `surfaces/`: the paper's simulation surfaces (Table 1), unit-sized

{shapes("surfaces")}

The open patches are the graphs of their equations over the paper's parameter domains, with
normals pointing to +z. They are triangulated with evenly sized triangles in 3D (relaxed with
Delaunay edge flips and DistMesh-style edge springs, then subdivided), so the steep corners
of the monkey saddle are not stretched. The ellipsoid is a subdivided icosphere scaled by
its semi-axes: there are no pole slivers, and the triangles are smallest near the ends of
the long axis, where the ellipsoid is most curved.

## `objects/`: the paper's experiment objects (Figure 7), millimetres

{shapes("objects")}

All are closed, watertight solids with outward normals, centred at the origin, cylinder axes
along z. The paper does not give the height of the cylinders; they are 100 mm tall here. The
cylinder sides are rings of points offset by half a step on every other ring (nearly
equilateral triangles); the caps are concentric rings inside the rim.

## Resolution and accuracy

Every vertex lies on the analytic surface (up to float32 rounding in the STL file). The
deviation is that of the flat triangles from the curved surface: the first-order implicit
distance |f| / |grad f| at {N_SAMPLES:,} points sampled uniformly on the faces (fixed
seed), its maximum over those points and its RMS; for the cylinders, the smaller of the
distances to the side and to the cap planes. Lengths are in the units of the file; the
paper's simulated touch noise is ±0.001 on the unit surfaces (Section 3.1). "min angle" is
the smallest angle of any triangle. The numbers below are measured by the script on the
files as written.

{table}"""

