"""The V-DMC common test conditions: the per-frame CTC chain, BD-rate, the CTC sheet and whole campaigns.

``chain`` is the CTC step of one decoded frame or sequence (``dequantize``, reindex, grid sampling, pcc,
IBSM), ``face_errors`` its per-face export, ``bd_rate`` the sheet's ``bdRateExtend``, ``sheet`` the
summary, ``manifest`` and ``campaign`` a whole campaign, ``frame_pattern`` the frame file names.
Imports ``mpeg.core``, ``mpeg.sampling`` and ``mpeg.comparison``.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
