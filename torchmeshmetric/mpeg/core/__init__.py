"""The shared pieces of ``torchmeshmetric.mpeg``: meshes and point clouds as mmetric holds them.

Textured meshes (OBJ/PLY with UVs and maps), point clouds with mmetric's duplicate merge, the oriented
reindex, mmetric's float32 arithmetic and fixed-point boxes, and its PLY/OBJ output files. Imports nothing
else of ``mpeg``: the sampling, comparison and CTC rooms build on it.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
