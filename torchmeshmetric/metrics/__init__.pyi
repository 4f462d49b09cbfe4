"""The names of ``torchmeshmetric.metrics``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import directed_distances as directed_distances
from . import distance_states as distance_states
from . import distance_statistics_metric as distance_statistics_metric
from . import mesh_surface_distance as mesh_surface_distance
from . import nearest_vertex_distance as nearest_vertex_distance
from . import selected_statistic as selected_statistic
from . import surface_distance_sets as surface_distance_sets
from . import vertex_distance_sets as vertex_distance_sets
from .directed_distances import DirectedDistances
from .distance_statistics_metric import DistanceStatisticsBase, DistanceStatisticsMetric
from .mesh_surface_distance import MeshSurfaceDistance
from .mesh_surface_distance_loss import MeshSurfaceDistanceLoss, mesh_surface_distance_loss
from .nearest_vertex_distance import NearestVertexDistance
from .nearest_vertex_distance_loss import NearestVertexDistanceLoss, nearest_vertex_distance_loss
from .selected_statistic import SelectedStatistic
from .surface_distance_sets import SurfaceDistanceOptions, mesh_surface_distance_sets
from .temporal_consistency_loss import TemporalConsistencyLoss, TemporalLossCache, temporal_consistency_loss
from .vertex_distance_sets import NearestVertexOptions, nearest_vertex_distance_sets

__all__ = [
    "TemporalConsistencyLoss",
    "TemporalLossCache",
    "temporal_consistency_loss",
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
]
