"""torchmeshmetric: exact, differentiable metrics for dynamic (volumetric-video) mesh simplification."""

# The data, kernel and metric packages are public as a whole: their __all__ is the root's, not restated here.
from torchmeshmetric import data, kernels, metrics
from torchmeshmetric._checks import (
    DeviceError,
    DTypeError,
    EmptyInputError,
    IndexRangeError,
    NonFiniteError,
    ShapeError,
    StaleIndexError,
)
from torchmeshmetric._version import __version__
from torchmeshmetric.data import *  # noqa: F403
from torchmeshmetric.evaluation import (
    PairEvaluation,
    SequenceEvaluation,
    TemporalConsistency,
    evaluate_pair,
    evaluate_sequence,
    register_pairs,
)
from torchmeshmetric.kernels import *  # noqa: F403
from torchmeshmetric.metrics import *  # noqa: F403
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
    NonRigidOptions,
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
    "StaleIndexError",
    "__version__",
    "as_mesh",
    "pack_meshes",
    "pack_points",
    # kernels
    *kernels.__all__,
    # statistics, metrics, losses
    "DistanceAccumulator",
    "DistanceStatistics",
    "distance_statistics",
    *metrics.__all__,
    # registration
    "DeformationGraph",
    "NonRigidOptions",
    "NonRigidRegistration",
    "RegistrationWarning",
    "RigidRegistration",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    # data and simplification
    *data.__all__,
    "simplify_qem",
    "simplify_registered_qem",
    # the evaluation system (paper Fig. 2)
    "PairEvaluation",
    "SequenceEvaluation",
    "TemporalConsistency",
    "evaluate_pair",
    "evaluate_sequence",
    "register_pairs",
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
