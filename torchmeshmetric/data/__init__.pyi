"""The names of ``torchmeshmetric.data``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import defects as defects
from . import demo as demo
from . import io as io
from .defects import add_capture_defects
from .demo import BONE_NAMES, DemoSequence, demo_sequence
from .io import (
    MeshFileError,
    Prefetcher,
    iter_sequence,
    list_frames,
    load_mesh,
    load_sequence,
    natural_key,
    prefetch_frames,
    read_mesh_arrays,
    save_mesh,
)

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
