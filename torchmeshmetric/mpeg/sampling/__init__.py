"""Meshes to point clouds as ``mm sample`` makes them: grid, face, edge, map, prnd, subdivision, vertex.

Each sampler is one module; ``sample_count_search`` is ``--nbSamplesMin/Max``'s search, ``model_cloud``
loads a model as ``mm compare`` reads it, ``texture`` the texel lookup they share. Imports only
``mpeg.core``.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
