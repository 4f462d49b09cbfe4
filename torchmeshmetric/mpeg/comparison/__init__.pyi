"""The names of ``torchmeshmetric.mpeg.comparison``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import colour as colour
from . import csv_rows as csv_rows
from . import equality as equality
from . import losses as losses
from . import metric as metric
from . import neighbours as neighbours
from . import pcc as pcc
from . import pcqm as pcqm
from . import point_order as point_order
from . import psnr as psnr
from . import sequence as sequence
from . import tfan_comparison as tfan_comparison
from . import topology as topology
from .colour import rgb_to_ycbcr
from .equality import EqualityModel, MeshEquality, load_equality_model, mesh_equality
from .ibsm import IbsmNoOverlapWarning, IbsmResult, ibsm
from .losses import (
    MpegGeometryLoss,
    differentiable_grid_sample,
    mpeg_geometry_loss,
    mpeg_psnr_from_mse,
    point_to_plane_mse,
    point_to_point_mse,
)
from .metric import MpegPSNR
from .mpeg_metrics import MpegClouds, Sampling, mpeg_metrics, mpeg_point_cloud, mpeg_point_clouds
from .neighbours import NeighbourTies, k_nearest, mpeg_sq_dists, nearest_with_ties
from .pcc import MpegDirection, MpegPointErrors, MpegResult, PointErrors, bbox_diagonal, mpeg_compare, mpeg_point_errors
from .pcqm import PcqmResult, mpeg_pcqm
from .pcqm_lightness import pcqm_lightness
from .psnr import mpeg_psnr
from .sequence import MpegSequence, mean_psnr, mpeg_sequence
from .tfan_comparison import TfanEquality, TfanUndefinedError, tfan_equality
from .topology import TopologyComparison, TopologyMapError, read_topology_map, topology_equivalence

__all__ = [
    "rgb_to_ycbcr",
    "MpegDirection",
    "MpegPointErrors",
    "MpegResult",
    "PointErrors",
    "bbox_diagonal",
    "mpeg_compare",
    "mpeg_point_errors",
    "EqualityModel",
    "MeshEquality",
    "load_equality_model",
    "mesh_equality",
    "IbsmNoOverlapWarning",
    "IbsmResult",
    "ibsm",
    "MpegGeometryLoss",
    "differentiable_grid_sample",
    "mpeg_geometry_loss",
    "mpeg_psnr_from_mse",
    "point_to_plane_mse",
    "point_to_point_mse",
    "MpegPSNR",
    "MpegClouds",
    "Sampling",
    "mpeg_metrics",
    "mpeg_point_cloud",
    "mpeg_point_clouds",
    "NeighbourTies",
    "k_nearest",
    "mpeg_sq_dists",
    "nearest_with_ties",
    "PcqmResult",
    "mpeg_pcqm",
    "pcqm_lightness",
    "mpeg_psnr",
    "MpegSequence",
    "mean_psnr",
    "mpeg_sequence",
    "TfanEquality",
    "TfanUndefinedError",
    "tfan_equality",
    "TopologyComparison",
    "TopologyMapError",
    "read_topology_map",
    "topology_equivalence",
]
