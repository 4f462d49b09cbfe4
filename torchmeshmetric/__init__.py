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
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__version__ = "0.1.0"

__all__ = [
    "ClosestPointOnTriangle",
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
