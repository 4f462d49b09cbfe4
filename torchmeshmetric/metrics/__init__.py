"""``torchmetrics`` metrics and ``nn.Module`` losses on the paper's two distances (thin wrappers on the kernels)."""

from torchmeshmetric.metrics.directed_distances import DirectedDistances
from torchmeshmetric.metrics.distance_statistics_metric import DistanceStatisticsBase, DistanceStatisticsMetric
from torchmeshmetric.metrics.mesh_surface_distance import MeshSurfaceDistance, mesh_surface_distances
from torchmeshmetric.metrics.mesh_surface_distance_loss import MeshSurfaceDistanceLoss, mesh_surface_distance_loss
from torchmeshmetric.metrics.nearest_vertex_distance import NearestVertexDistance, nearest_vertex_distances
from torchmeshmetric.metrics.nearest_vertex_distance_loss import (
    NearestVertexDistanceLoss,
    nearest_vertex_distance_loss,
)
from torchmeshmetric.metrics.selected_statistic import SelectedStatistic

__all__ = [
    "DirectedDistances",
    "DistanceStatisticsBase",
    "DistanceStatisticsMetric",
    "MeshSurfaceDistance",
    "MeshSurfaceDistanceLoss",
    "NearestVertexDistance",
    "NearestVertexDistanceLoss",
    "SelectedStatistic",
    "mesh_surface_distance_loss",
    "mesh_surface_distances",
    "nearest_vertex_distance_loss",
    "nearest_vertex_distances",
]
