"""The names of ``torchmeshmetric.mpeg``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import colour as colour
from . import comparison as comparison
from . import ctc_campaign as ctc_campaign
from . import ctc_manifest as ctc_manifest
from . import ctc_sheet as ctc_sheet
from . import edge_sampling as edge_sampling
from . import equality as equality
from . import face_errors as face_errors
from . import face_sampling as face_sampling
from . import grid_sampling as grid_sampling
from . import losses as losses
from . import map_sampling as map_sampling
from . import metric as metric
from . import model_cloud as model_cloud
from . import neighbours as neighbours
from . import pcqm as pcqm
from . import point_cloud as point_cloud
from . import prnd_sampling as prnd_sampling
from . import psnr as psnr
from . import sequence as sequence
from . import subdivision_sampling as subdivision_sampling
from . import texture as texture
from . import textured_mesh as textured_mesh
from . import tfan_comparison as tfan_comparison
from . import topology as topology
from . import vertex_sampling as vertex_sampling
from .bd_rate import bd_rate
from .colour import rgb_to_ycbcr
from .comparison import (
    MpegDirection,
    MpegPointErrors,
    MpegResult,
    PointErrors,
    bbox_diagonal,
    mpeg_compare,
    mpeg_point_errors,
)
from .ctc import CTC_COLUMNS, CtcFrame, CtcSequence, ctc_frame, ctc_mean, ctc_sequence
from .ctc_campaign import CampaignResult, run_ctc_campaign
from .ctc_manifest import CtcCampaign, CtcManifestError, load_ctc_campaign
from .ctc_sheet import RatePoint, ctc_summary, read_test_model_csv
from .dequantize import dequantize_positions, dequantize_uvs
from .edge_sampling import edge_sample
from .equality import MeshEquality, mesh_equality
from .face_errors import FaceErrors, ctc_face_errors
from .face_sampling import face_sample
from .grid_sampling import (
    BoxError,
    GridHits,
    GridSamples,
    GridTooLargeError,
    check_box,
    grid_hits,
    grid_sample,
    grid_sample_faces,
    mesh_box,
    unique_vertex_rows,
)
from .ibsm import IbsmNoOverlapWarning, IbsmResult, ibsm
from .losses import (
    MpegGeometryLoss,
    differentiable_grid_sample,
    mpeg_geometry_loss,
    mpeg_psnr_from_mse,
    point_to_plane_mse,
    point_to_point_mse,
)
from .map_sampling import map_sample
from .metric import MpegPSNR
from .model_cloud import load_model_cloud
from .mpeg_metrics import MpegClouds, Sampling, mpeg_metrics, mpeg_point_cloud, mpeg_point_clouds
from .neighbours import NeighbourTies, k_nearest, mpeg_sq_dists, nearest_with_ties
from .pcqm import PcqmResult, mpeg_pcqm
from .pcqm_lightness import pcqm_lightness
from .point_cloud import PointCloud, merge_duplicate_points
from .prnd_sampling import prnd_sample
from .psnr import mpeg_psnr
from .sequence import MpegSequence, mean_psnr, mpeg_sequence
from .subdivision_sampling import subdivision_sample
from .texture import sample_texture
from .textured_mesh import TexturedMesh, load_textured_mesh, read_texture
from .tfan_comparison import TfanMesh, TfanUndefinedError, load_tfan_mesh, tfan_equality
from .topology import TopologyComparison, TopologyMapError, read_topology_map, topology_equivalence
from .vertex_sampling import vertex_sample

__all__ = [
    "CTC_COLUMNS",
    "CtcFrame",
    "CtcSequence",
    "CampaignResult",
    "FaceErrors",
    "ctc_face_errors",
    "CtcCampaign",
    "CtcManifestError",
    "RatePoint",
    "ctc_summary",
    "load_ctc_campaign",
    "read_test_model_csv",
    "run_ctc_campaign",
    "GridTooLargeError",
    "IbsmNoOverlapWarning",
    "IbsmResult",
    "bd_rate",
    "ctc_frame",
    "ctc_mean",
    "ctc_sequence",
    "dequantize_positions",
    "dequantize_uvs",
    "edge_sample",
    "face_sample",
    "ibsm",
    "read_texture",
    "BoxError",
    "GridHits",
    "GridSamples",
    "MpegPointErrors",
    "PointErrors",
    "grid_sample_faces",
    "mpeg_point_errors",
    "MeshEquality",
    "MpegGeometryLoss",
    "MpegPSNR",
    "MpegClouds",
    "MpegDirection",
    "MpegResult",
    "MpegSequence",
    "NeighbourTies",
    "PointCloud",
    "Sampling",
    "TexturedMesh",
    "TfanMesh",
    "TfanUndefinedError",
    "TopologyComparison",
    "TopologyMapError",
    "bbox_diagonal",
    "check_box",
    "differentiable_grid_sample",
    "grid_hits",
    "grid_sample",
    "load_textured_mesh",
    "load_tfan_mesh",
    "map_sample",
    "merge_duplicate_points",
    "mean_psnr",
    "mesh_box",
    "mesh_equality",
    "mpeg_compare",
    "mpeg_geometry_loss",
    "mpeg_metrics",
    "mpeg_point_cloud",
    "mpeg_point_clouds",
    "mpeg_psnr",
    "mpeg_sequence",
    "mpeg_sq_dists",
    "prnd_sample",
    "read_topology_map",
    "k_nearest",
    "nearest_with_ties",
    "point_to_plane_mse",
    "point_to_point_mse",
    "mpeg_psnr_from_mse",
    "rgb_to_ycbcr",
    "sample_texture",
    "subdivision_sample",
    "tfan_equality",
    "topology_equivalence",
    "unique_vertex_rows",
    "vertex_sample",
    "PcqmResult",
    "load_model_cloud",
    "mpeg_pcqm",
    "pcqm_lightness",
]
