"""A surface backend for tests: the registration's SurfaceQuery and nothing more.

Not a test module (no ``test_`` prefix): the tests import it. It answers by delegating to
another backend (the default AabbSurface) and counts the closest-point queries; it has no
ray casting, so code that casts rays must fall back.
"""

from __future__ import annotations


class DelegatingSurface:
    """Satisfies SurfaceQuery without inheriting from anything; counts
    ``closest_points`` calls in ``calls``."""

    def __init__(self, inner):
        self.inner = inner
        self.calls = 0

    def closest_points(self, points):
        self.calls += 1
        return self.inner.closest_points(points)

    def interpolated_normals(self, closest, face):
        return self.inner.interpolated_normals(closest, face)

    def smooth_offsets(self, closest, face):
        return self.inner.smooth_offsets(closest, face)

    def smooth_offsets_and_gradients(self, closest, face):
        return self.inner.smooth_offsets_and_gradients(closest, face)
