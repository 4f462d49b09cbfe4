"""Point clouds and meshes compared as ``mm compare`` does: pcc (D1/D2, colour), PCQM, IBSM, equality.

``pcc`` is mpeg-pcc-dmetric's comparison (with ``neighbours``, ``psnr``, ``colour``); ``mpeg_metrics``,
``sequence``, ``metric`` and ``losses`` put sampling and comparison together; ``pcqm``, ``ibsm``,
``equality``, ``topology`` and ``tfan_comparison`` are mmetric's other modes; ``csv_rows`` its CSV.
Imports ``mpeg.core`` and ``mpeg.sampling``.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
