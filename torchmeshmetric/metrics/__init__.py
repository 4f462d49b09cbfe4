"""``torchmetrics`` metrics and ``nn.Module`` losses on the paper's two distances (thin wrappers on the kernels).

Names, per distance: ``*_distance_sets`` (the forward and reverse distance sets of a batch, a
``DirectedDistances``), ``*_distance_loss`` and ``*DistanceLoss`` (a differentiable reduction of them), and the
``torchmetrics.Metric`` ``MeshSurfaceDistance`` / ``NearestVertexDistance`` (their statistics, accumulated). The
kernels they call (``torchmeshmetric.point_mesh_distance``, ``torchmeshmetric.nearest_vertex_distance``)
measure one query set against one reference and return indices too.
"""

from torchmeshmetric._deprecation import deprecated_names
from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules. The
# renamed names are served, with a warning, by the fallback.
__getattr__, __dir__, __all__ = attach(
    __name__,
    __file__,
    fallback=deprecated_names(
        __name__,
        {
            "mesh_surface_distances": "torchmeshmetric.metrics.mesh_surface_distance_sets",
            "nearest_vertex_distances": "torchmeshmetric.metrics.nearest_vertex_distance_sets",
        },
        stacklevel=3,
    ),
)
