"""``torchmetrics`` metrics and ``nn.Module`` losses on the paper's two distances (thin wrappers on the kernels).

Names, per distance: ``*_distance_sets`` (the forward and reverse distance sets of a batch, a
``DirectedDistances``), ``*_distance_loss`` and ``*DistanceLoss`` (a differentiable reduction of them), and the
``torchmetrics.Metric`` ``MeshSurfaceDistance`` / ``NearestVertexDistance`` (their statistics, accumulated). The
kernels they call (``torchmeshmetric.point_mesh_distance``, ``torchmeshmetric.nearest_vertex_distance``)
measure one query set against one reference and return indices too.
"""

from torchmeshmetric._deprecation import deprecated_names
from torchmeshmetric.metrics.directed_distances import DirectedDistances
from torchmeshmetric.metrics.distance_statistics_metric import DistanceStatisticsBase, DistanceStatisticsMetric
from torchmeshmetric.metrics.mesh_surface_distance import (
    MeshSurfaceDistance,
    SurfaceDistanceOptions,
    mesh_surface_distance_sets,
)
from torchmeshmetric.metrics.mesh_surface_distance_loss import MeshSurfaceDistanceLoss, mesh_surface_distance_loss
from torchmeshmetric.metrics.nearest_vertex_distance import (
    NearestVertexDistance,
    NearestVertexOptions,
    nearest_vertex_distance_sets,
)
from torchmeshmetric.metrics.nearest_vertex_distance_loss import (
    NearestVertexDistanceLoss,
    nearest_vertex_distance_loss,
)
from torchmeshmetric.metrics.selected_statistic import SelectedStatistic
from torchmeshmetric.metrics.temporal_consistency_loss import (
    TemporalConsistencyLoss,
    TemporalLossCache,
    temporal_consistency_loss,
)

__all__ = [
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
    "TemporalConsistencyLoss",
    "TemporalLossCache",
    "mesh_surface_distance_loss",
    "mesh_surface_distance_sets",
    "nearest_vertex_distance_loss",
    "nearest_vertex_distance_sets",
    "temporal_consistency_loss",
]

__getattr__ = deprecated_names(
    __name__,
    {
        "mesh_surface_distances": ("torchmeshmetric.metrics.mesh_surface_distance_sets", mesh_surface_distance_sets),
        "nearest_vertex_distances": (
            "torchmeshmetric.metrics.nearest_vertex_distance_sets",
            nearest_vertex_distance_sets,
        ),
    },
)
