"""The names of ``torchmeshmetric.mpeg.sampling``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import edge_sampling as edge_sampling
from . import face_sampling as face_sampling
from . import grid_sampling as grid_sampling
from . import map_sampling as map_sampling
from . import model_cloud as model_cloud
from . import prnd_sampling as prnd_sampling
from . import sample_count_search as sample_count_search
from . import subdivision_rows as subdivision_rows
from . import subdivision_sampling as subdivision_sampling
from . import texture as texture
from . import vertex_sampling as vertex_sampling
from .edge_sampling import edge_sample
from .face_sampling import face_sample
from .grid_sampling import (
    BoxError,
    GridHits,
    GridSamples,
    GridTooLargeError,
    grid_hits,
    grid_sample,
    grid_sample_faces,
    mesh_box,
)
from .map_sampling import map_sample
from .model_cloud import load_model_cloud
from .prnd_sampling import prnd_sample
from .subdivision_sampling import subdivision_sample
from .texture import sample_texture
from .vertex_sampling import vertex_sample

__all__ = [
    "edge_sample",
    "face_sample",
    "BoxError",
    "GridHits",
    "GridSamples",
    "GridTooLargeError",
    "grid_hits",
    "grid_sample",
    "grid_sample_faces",
    "mesh_box",
    "map_sample",
    "load_model_cloud",
    "prnd_sample",
    "subdivision_sample",
    "sample_texture",
    "vertex_sample",
]
