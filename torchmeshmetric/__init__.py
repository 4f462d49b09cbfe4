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
from torchmeshmetric.registration import (
    DeformationGraph,
    NonRigidRegistration,
    RegistrationWarning,
    RigidRegistration,
    kabsch_umeyama,
    register_nonrigid,
    register_rigid,
)
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__version__ = "0.1.0"

__all__ = [
    "ClosestPointOnTriangle",
    "DTypeError",
    "DeformationGraph",
    "DeviceError",
    "EmptyInputError",
    "IndexRangeError",
    "Mesh",
    "MeshLike",
    "NearestVertexDistance",
    "NonFiniteError",
    "NonRigidRegistration",
    "PointMeshDistance",
    "RegistrationWarning",
    "RigidRegistration",
    "ShapeError",
    "SurfaceSamples",
    "__version__",
    "as_mesh",
    "closest_point_on_triangle",
    "kabsch_umeyama",
    "nearest_vertex_distance",
    "pack_meshes",
    "pack_points",
    "point_mesh_distance",
    "register_nonrigid",
    "register_rigid",
    "sample_surface",
    "vertex_set",
]
