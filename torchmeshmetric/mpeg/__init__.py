"""MPEG's mesh metrics, equal to mmetric's figures: D1/D2 PSNR and Hausdorff, colour (Y, Cb, Cr) PSNR.

Meshes become point clouds as mmetric makes them (:func:`grid_sample`: the V-DMC CTC grid; :func:`vertex_sample`:
what ``mm compare --mode pcc`` does to a mesh), and :func:`mpeg_compare` measures them as mpeg-pcc-dmetric does.
"""

from torchmeshmetric.mpeg.bd_rate import bd_rate
from torchmeshmetric.mpeg.colour import rgb_to_ycbcr
from torchmeshmetric.mpeg.comparison import MpegDirection, MpegResult, bbox_diagonal, mpeg_compare
from torchmeshmetric.mpeg.ctc import CTC_COLUMNS, CtcFrame, CtcSequence, ctc_frame, ctc_mean, ctc_sequence
from torchmeshmetric.mpeg.dequantize import dequantize_positions, dequantize_uvs
from torchmeshmetric.mpeg.grid_sampling import (
    BoxError,
    GridHits,
    GridTooLargeError,
    check_box,
    grid_hits,
    grid_sample,
    mesh_box,
    unique_vertex_rows,
)
from torchmeshmetric.mpeg.ibsm import IbsmResult, ibsm
from torchmeshmetric.mpeg.losses import (
    MpegGeometryLoss,
    differentiable_grid_sample,
    mpeg_geometry_loss,
    mpeg_psnr_from_mse,
    point_to_plane_mse,
    point_to_point_mse,
)
from torchmeshmetric.mpeg.metric import MpegPSNR
from torchmeshmetric.mpeg.mpeg_metrics import Sampling, mpeg_metrics, mpeg_point_cloud
from torchmeshmetric.mpeg.neighbours import NeighbourTies, k_nearest, mpeg_sq_dists, nearest_with_ties
from torchmeshmetric.mpeg.point_cloud import PointCloud, merge_duplicate_points
from torchmeshmetric.mpeg.psnr import mpeg_psnr
from torchmeshmetric.mpeg.sequence import MpegSequence, mean_psnr, mpeg_sequence
from torchmeshmetric.mpeg.texture import sample_texture
from torchmeshmetric.mpeg.textured_mesh import TexturedMesh, load_textured_mesh
from torchmeshmetric.mpeg.vertex_sampling import vertex_sample

__all__ = [
    "CTC_COLUMNS",
    "BoxError",
    "CtcFrame",
    "CtcSequence",
    "GridHits",
    "GridTooLargeError",
    "IbsmResult",
    "MpegGeometryLoss",
    "MpegPSNR",
    "MpegDirection",
    "MpegResult",
    "MpegSequence",
    "NeighbourTies",
    "PointCloud",
    "Sampling",
    "TexturedMesh",
    "bbox_diagonal",
    "bd_rate",
    "ctc_frame",
    "ctc_mean",
    "ctc_sequence",
    "dequantize_positions",
    "dequantize_uvs",
    "check_box",
    "differentiable_grid_sample",
    "grid_hits",
    "grid_sample",
    "ibsm",
    "load_textured_mesh",
    "merge_duplicate_points",
    "mean_psnr",
    "mesh_box",
    "mpeg_compare",
    "mpeg_geometry_loss",
    "mpeg_metrics",
    "mpeg_point_cloud",
    "mpeg_psnr",
    "mpeg_sequence",
    "mpeg_sq_dists",
    "k_nearest",
    "nearest_with_ties",
    "point_to_plane_mse",
    "point_to_point_mse",
    "mpeg_psnr_from_mse",
    "rgb_to_ycbcr",
    "sample_texture",
    "unique_vertex_rows",
    "vertex_sample",
]
