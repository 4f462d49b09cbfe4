"""The names of ``torchmeshmetric``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import data as data
from . import evaluation as evaluation
from . import kernels as kernels
from . import metrics as metrics
from . import mpeg as mpeg
from . import registration as registration
from . import simplification as simplification
from . import stats as stats
from . import structures as structures
from . import viz as viz
from ._checks import DeviceError, DTypeError, EmptyInputError, IndexRangeError, NonFiniteError, ShapeError
from ._version import __version__
from .data import (
    BONE_NAMES,
    DemoSequence,
    MeshFileError,
    add_capture_defects,
    demo_sequence,
    list_frames,
    load_mesh,
    load_sequence,
    natural_key,
    save_mesh,
)
from .evaluation import (
    PairEvaluation,
    SequenceEvaluation,
    TemporalConsistency,
    evaluate_pair,
    evaluate_sequence,
    register_pairs,
)
from .kernels import (
    ClosestPointOnTriangle,
    IndexCache,
    MeshIndex,
    NearestVertexResult,
    PointMeshResult,
    SurfaceSamples,
    closest_point_on_triangle,
    nearest_vertex_distance,
    point_mesh_distance,
    sample_surface,
    vertex_set,
)
from .metrics import (
    DirectedDistances,
    DistanceStatisticsBase,
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistance,
    NearestVertexDistanceLoss,
    NearestVertexOptions,
    SelectedStatistic,
    SurfaceDistanceOptions,
    mesh_surface_distance_loss,
    mesh_surface_distance_sets,
    nearest_vertex_distance_loss,
    nearest_vertex_distance_sets,
)
from .mpeg import (
    MpegGeometryLoss,
    MpegPSNR,
    MpegResult,
    PointCloud,
    TexturedMesh,
    differentiable_grid_sample,
    grid_sample,
    load_textured_mesh,
    mpeg_compare,
    mpeg_geometry_loss,
    mpeg_metrics,
    mpeg_sequence,
    vertex_sample,
)
from .registration import (
    DeformationGraph,
    NonRigidOptions,
    NonRigidRegistration,
    RegistrationWarning,
    RigidRegistration,
    kabsch_umeyama,
    register_nonrigid,
    register_rigid,
)
from .simplification import simplify_qem, simplify_registered_qem
from .stats import DistanceAccumulator, DistanceStatistics, distance_statistics
from .structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__all__ = [
    "DTypeError",
    "DeviceError",
    "EmptyInputError",
    "IndexRangeError",
    "Mesh",
    "MeshLike",
    "NonFiniteError",
    "ShapeError",
    "__version__",
    "as_mesh",
    "pack_meshes",
    "pack_points",
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
    "DistanceAccumulator",
    "DistanceStatistics",
    "distance_statistics",
    "DirectedDistances",
    "DistanceStatisticsBase",
    "DistanceStatisticsMetric",
    "MeshSurfaceDistance",
    "MeshSurfaceDistanceLoss",
    "NearestVertexDistance",
    "NearestVertexDistanceLoss",
    "NearestVertexOptions",
    "SelectedStatistic",
    "SurfaceDistanceOptions",
    "mesh_surface_distance_loss",
    "mesh_surface_distance_sets",
    "nearest_vertex_distance_loss",
    "nearest_vertex_distance_sets",
    "DeformationGraph",
    "NonRigidOptions",
    "NonRigidRegistration",
    "RegistrationWarning",
    "RigidRegistration",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    "BONE_NAMES",
    "DemoSequence",
    "MeshFileError",
    "add_capture_defects",
    "demo_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "natural_key",
    "save_mesh",
    "simplify_qem",
    "simplify_registered_qem",
    "PairEvaluation",
    "SequenceEvaluation",
    "TemporalConsistency",
    "evaluate_pair",
    "evaluate_sequence",
    "register_pairs",
    "MpegGeometryLoss",
    "MpegPSNR",
    "MpegResult",
    "PointCloud",
    "TexturedMesh",
    "differentiable_grid_sample",
    "grid_sample",
    "load_textured_mesh",
    "mpeg_compare",
    "mpeg_geometry_loss",
    "mpeg_metrics",
    "mpeg_sequence",
    "vertex_sample",
]
