"""torchmeshmetric: exact, differentiable metrics for dynamic (volumetric-video) mesh simplification."""

from torchmeshmetric._checks import (
    DeviceError,
    DTypeError,
    EmptyInputError,
    IndexRangeError,
    NonFiniteError,
    ShapeError,
)
from torchmeshmetric.kernels import (
    ClosestPointOnTriangle,
    NearestVertexDistance,
    PointMeshDistance,
    SurfaceSamples,
    closest_point_on_triangle,
    nearest_vertex_distance,
    point_mesh_distance,
    sample_surface,
    vertex_set,
)
from torchmeshmetric.metrics import (
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistanceLoss,
    mesh_surface_distance_loss,
    nearest_vertex_distance_loss,
)
from torchmeshmetric.stats import DistanceAccumulator, DistanceStatistics, distance_statistics
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__version__ = "0.1.0"

# The metric ``NearestVertexDistance`` lives in ``torchmeshmetric.metrics``: the top-level name is the kernel's result.
__all__ = [
    "ClosestPointOnTriangle",
    "DistanceAccumulator",
    "DistanceStatistics",
    "DistanceStatisticsMetric",
    "MeshSurfaceDistance",
    "MeshSurfaceDistanceLoss",
    "NearestVertexDistanceLoss",
    "distance_statistics",
    "mesh_surface_distance_loss",
    "nearest_vertex_distance_loss",
    "DTypeError",
    "DeviceError",
    "EmptyInputError",
    "IndexRangeError",
    "Mesh",
    "MeshLike",
    "NearestVertexDistance",
    "NonFiniteError",
    "PointMeshDistance",
    "ShapeError",
    "SurfaceSamples",
    "__version__",
    "as_mesh",
    "closest_point_on_triangle",
    "nearest_vertex_distance",
    "pack_meshes",
    "pack_points",
    "point_mesh_distance",
    "sample_surface",
    "vertex_set",
]
