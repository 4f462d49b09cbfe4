"""The names of ``torchmeshmetric.data``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import defects as defects
from . import demo as demo
from . import frames as frames
from . import io as io
from . import mesh_file as mesh_file
from . import obj as obj
from . import off as off
from . import ply as ply
from . import sequence as sequence
from . import trimesh_formats as trimesh_formats
from .defects import add_capture_defects
from .demo import BONE_NAMES, DemoSequence, demo_sequence
from .frames import list_frames, natural_key
from .io import load_mesh, read_mesh_arrays, save_mesh
from .mesh_file import MeshFileError
from .sequence import Prefetcher, iter_sequence, load_sequence, prefetch_frames

__all__ = [
    "BONE_NAMES",
    "DemoSequence",
    "MeshFileError",
    "Prefetcher",
    "add_capture_defects",
    "demo_sequence",
    "iter_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "natural_key",
    "prefetch_frames",
    "read_mesh_arrays",
    "save_mesh",
]
