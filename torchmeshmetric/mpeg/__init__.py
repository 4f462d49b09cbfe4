"""MPEG's mesh metrics, equal to mmetric's figures: D1/D2 PSNR and Hausdorff, colour (Y, Cb, Cr) PSNR.

Meshes become point clouds as mmetric makes them (:func:`grid_sample`: the V-DMC CTC grid; :func:`vertex_sample`:
what ``mm compare --mode pcc`` does to a mesh), and :func:`mpeg_compare` measures them as mpeg-pcc-dmetric does.

Four rooms, each importing only itself and the rooms before it: ``core`` (textured meshes, point clouds, mmetric's
float32 and fixed-point arithmetic, its output files), ``sampling`` (``mm sample``'s samplers), ``comparison``
(``mm compare``'s modes: pcc, PCQM, IBSM, equality, topology, TFAN; the metrics and losses built on them) and
``ctc`` (the V-DMC CTC chain, BD-rate, the CTC sheet, campaigns). Every name is served here too.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
