"""``torchmetrics`` metrics and ``nn.Module`` losses on the paper's two distances (thin wrappers on the kernels).

Names, per distance: ``*_distance_sets`` (the forward and reverse distance sets of a batch, a
``DirectedDistances``), ``*_distance_loss`` and ``*DistanceLoss`` (a differentiable reduction of them), and the
``torchmetrics.Metric`` ``MeshSurfaceDistance`` / ``NearestVertexDistance`` (their statistics, accumulated). The
kernels they call (``torchmeshmetric.point_mesh_distance``, ``torchmeshmetric.nearest_vertex_distance``)
measure one query set against one reference and return indices too.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
