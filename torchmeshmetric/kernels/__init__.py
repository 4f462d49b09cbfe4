"""Exact, chunked, differentiable distance kernels (pure functions)."""

from torchmeshmetric.kernels.nearest import NearestVertexDistance, nearest_vertex_distance, register_nearest_backend
from torchmeshmetric.kernels.point_triangle import (
    ClosestPointOnTriangle,
    PointMeshDistance,
    closest_point_on_triangle,
    point_mesh_distance,
    register_face_backend,
)
from torchmeshmetric.kernels.sampling import SurfaceSamples, sample_surface, vertex_set

# Registers the accelerated backends ("bvh", "pruned") used by backend="auto"; must follow the kernels above.
from torchmeshmetric.kernels import accel  # noqa: E402, I001

__all__ = [
    "ClosestPointOnTriangle",
    "NearestVertexDistance",
    "PointMeshDistance",
    "SurfaceSamples",
    "closest_point_on_triangle",
    "nearest_vertex_distance",
    "point_mesh_distance",
    "register_face_backend",
    "register_nearest_backend",
    "sample_surface",
    "vertex_set",
]
