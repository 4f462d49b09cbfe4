"""The temporal metrics of dynamic-mesh compression (KG, KSO, STED) and their registered forms (docs/temporal.md)."""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
