"""The names of ``torchmeshmetric.kernels``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import accel as accel
from . import contract as contract
from . import danskin as danskin
from . import index_cache as index_cache
from . import mesh_index as mesh_index
from . import nearest as nearest
from . import point_triangle as point_triangle
from . import sampling as sampling
from . import select as select
from . import triangle as triangle
from .danskin import surface_distances
from .index_cache import IndexCache
from .mesh_index import MeshIndex, PointMeshResult
from .nearest import NearestVertexResult, nearest_vertex_distance
from .point_triangle import point_mesh_distance
from .sampling import SurfaceSamples, sample_surface, vertex_set
from .triangle import ClosestPointOnTriangle, closest_point_on_triangle

__all__ = [
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
    "surface_distances",
    "vertex_set",
]
