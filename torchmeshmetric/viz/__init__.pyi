"""The names of ``torchmeshmetric.viz``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import colors as colors
from . import plots as plots
from . import rd_curves as rd_curves
from . import sweep as sweep
from . import validation as validation
from .colors import error_colors, write_error_ply
from .plots import plot_frame_curves, plot_histograms, plot_mpeg_curves
from .rd_curves import plot_rd_curves
from .sweep import plot_weight_sweep
from .validation import plot_validation

__all__ = [
    "error_colors",
    "plot_frame_curves",
    "plot_histograms",
    "plot_mpeg_curves",
    "plot_rd_curves",
    "plot_validation",
    "plot_weight_sweep",
    "write_error_ply",
]
