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
from torchmeshmetric.evaluation import (
    PairEvaluation,
    SequenceEvaluation,
    TemporalConsistency,
    evaluate_pair,
    evaluate_sequence,
)
from torchmeshmetric.kernels import (
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
from torchmeshmetric.metrics import (
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistance,
    NearestVertexDistanceLoss,
    SelectedStatistic,
    mesh_surface_distance_loss,
    nearest_vertex_distance_loss,
)
from torchmeshmetric.mpeg import (
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
from torchmeshmetric.registration import (
    DeformationGraph,
    NonRigidRegistration,
    RegistrationWarning,
    RigidRegistration,
    kabsch_umeyama,
    register_nonrigid,
    register_rigid,
)
from torchmeshmetric.simplification import simplify_qem, simplify_registered_qem
from torchmeshmetric.stats import DistanceAccumulator, DistanceStatistics, distance_statistics
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, pack_meshes, pack_points

__version__ = "0.1.0"

__all__ = [
    # structures and errors
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
    # kernels
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
    # statistics, metrics, losses
    "DistanceAccumulator",
    "DistanceStatistics",
    "DistanceStatisticsMetric",
    "MeshSurfaceDistance",
    "MeshSurfaceDistanceLoss",
    "NearestVertexDistance",
    "NearestVertexDistanceLoss",
    "SelectedStatistic",
    "distance_statistics",
    "mesh_surface_distance_loss",
    "nearest_vertex_distance_loss",
    # registration
    "DeformationGraph",
    "NonRigidRegistration",
    "RegistrationWarning",
    "RigidRegistration",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    # data and simplification
    "DemoSequence",
    "MeshFileError",
    "add_capture_defects",
    "demo_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "save_mesh",
    "simplify_qem",
    "simplify_registered_qem",
    # the evaluation system (paper Fig. 2)
    "PairEvaluation",
    "SequenceEvaluation",
    "TemporalConsistency",
    "evaluate_pair",
    "evaluate_sequence",
    # MPEG's metrics (mmetric: D1/D2 and colour PSNR)
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
