"""Data: mesh / sequence I/O, the built-in demo sequence with ground-truth motion, capture-defect fixtures."""

from torchmeshmetric.data.defects import add_capture_defects
from torchmeshmetric.data.demo import BONE_NAMES, DemoSequence, demo_sequence
from torchmeshmetric.data.io import MeshFileError, list_frames, load_mesh, load_sequence, natural_key, save_mesh

__all__ = [
    "BONE_NAMES",
    "DemoSequence",
    "MeshFileError",
    "add_capture_defects",
    "demo_sequence",
    "list_frames",
    "load_mesh",
    "load_sequence",
    "natural_key",
    "save_mesh",
]
