"""Exact, chunked, differentiable distance kernels (pure functions)."""

# Importing accel registers the accelerated backends ("bvh", "pruned") that backend="auto" uses.
from torchmeshmetric.kernels import accel  # noqa: F401
from torchmeshmetric.kernels.nearest import NearestVertexResult, nearest_vertex_distance, register_nearest_backend
from torchmeshmetric.kernels.point_triangle import (
    ClosestPointOnTriangle,
    PointMeshResult,
    closest_point_on_triangle,
    point_mesh_distance,
    register_face_backend,
)
from torchmeshmetric.kernels.sampling import SurfaceSamples, sample_surface, vertex_set

__all__ = [
    "ClosestPointOnTriangle",
    "NearestVertexResult",
    "PointMeshResult",
    "SurfaceSamples",
    "closest_point_on_triangle",
    "nearest_vertex_distance",
    "point_mesh_distance",
    "register_face_backend",
    "register_nearest_backend",
    "sample_surface",
    "vertex_set",
]
