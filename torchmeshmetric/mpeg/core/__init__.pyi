"""The names of ``torchmeshmetric.mpeg.core``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import fixed_point as fixed_point
from . import model_files as model_files
from . import point_cloud as point_cloud
from . import reindex as reindex
from . import textured_mesh as textured_mesh
from .point_cloud import PointCloud, merge_duplicate_points
from .textured_mesh import TexturedMesh, load_textured_mesh, read_texture

__all__ = [
    "PointCloud",
    "merge_duplicate_points",
    "TexturedMesh",
    "load_textured_mesh",
    "read_texture",
]
