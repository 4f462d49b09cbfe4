"""Exact, chunked, differentiable distance kernels (pure functions)."""

from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.nearest import NearestVertexResult, nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import (
    ClosestPointOnTriangle,
    PointMeshResult,
    closest_point_on_triangle,
    point_mesh_distance,
)
from torchmeshmetric.kernels.sampling import SurfaceSamples, sample_surface, vertex_set

__all__ = [
    "ClosestPointOnTriangle",
    "IndexCache",
    "MeshIndex",
    "NearestVertexResult",
    "PointMeshResult",
    "SurfaceSamples",
    "closest_point_on_triangle",
    "nearest_vertex_distance",
    "point_mesh_distance",
    "sample_surface",
    "vertex_set",
]
