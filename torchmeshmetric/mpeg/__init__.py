"""MPEG's mesh metrics, equal to mmetric's figures: D1/D2 PSNR and Hausdorff, colour (Y, Cb, Cr) PSNR.

Meshes become point clouds as mmetric makes them (:func:`grid_sample`: the V-DMC CTC grid; :func:`vertex_sample`:
what ``mm compare --mode pcc`` does to a mesh), and :func:`mpeg_compare` measures them as mpeg-pcc-dmetric does.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
