"""torchmeshmetric: exact, differentiable metrics for dynamic (volumetric-video) mesh simplification."""

from torchmeshmetric._checks import (
    DeviceError,
    DTypeError,
    EmptyInputError,
    IndexRangeError,
    NonFiniteError,
    ShapeError,
)
from torchmeshmetric.data import (
    DemoSequence,
    MeshFileError,
    add_capture_defects,
    demo_sequence,
    list_frames,
    load_mesh,
    load_sequence,
    save_mesh,
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
from torchmeshmetric.simplification import simplify_qem, simplify_registered_qem
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__version__ = "0.1.0"

__all__ = [
    "ClosestPointOnTriangle",
    "DTypeError",
    "DemoSequence",
    "DeviceError",
    "EmptyInputError",
    "IndexRangeError",
    "Mesh",
    "MeshFileError",
    "MeshLike",
    "NearestVertexDistance",
    "NonFiniteError",
    "PointMeshDistance",
    "ShapeError",
    "SurfaceSamples",
    "__version__",
    "add_capture_defects",
    "as_mesh",
    "closest_point_on_triangle",
    "demo_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "nearest_vertex_distance",
    "pack_meshes",
    "pack_points",
    "point_mesh_distance",
    "sample_surface",
    "save_mesh",
    "simplify_qem",
    "simplify_registered_qem",
    "vertex_set",
]
