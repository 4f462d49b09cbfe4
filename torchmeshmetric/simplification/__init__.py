"""Simplifiers: plain QEM (fast-simplification), and ours: Registered QEM, Anchored QEM and the learned tracking one.

All are quadric error metric edge collapse (Garland & Heckbert 1997).
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
