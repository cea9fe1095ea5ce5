"""Benchmark protocols (the paper's Tables 2 to 4) and the Open3D baselines.

The protocols are importable from here (``meshrec.bench.run_trials``); the baselines, which
need open3d, from :mod:`meshrec.bench.baseline`.
"""

from meshrec.bench.blobs import Blob, blob_set, make_blob, write_blobs
from meshrec.bench.protocols import (
    OBJECT_SIDES,
    Trial,
    object_localisation_error,
    paper_touch,
    run_trials,
)
from meshrec.bench.shapes import (
    EXTRA_FAMILIES,
    SHAPE_FAMILIES,
    Shape,
    make_shape,
    shape_set,
    write_shapes,
)

__all__ = [
    "EXTRA_FAMILIES",
    "OBJECT_SIDES",
    "SHAPE_FAMILIES",
    "Blob",
    "Shape",
    "Trial",
    "blob_set",
    "make_blob",
    "make_shape",
    "object_localisation_error",
    "paper_touch",
    "run_trials",
    "shape_set",
    "write_blobs",
    "write_shapes",
]
