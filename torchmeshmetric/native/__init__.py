"""The package's C++ extensions: every ``.cpp`` and ``.h`` source lives here, built by the one loader (``loader``).

``torchmeshmetric build`` (or ``python -m torchmeshmetric.native``) builds them all ahead of first use.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
