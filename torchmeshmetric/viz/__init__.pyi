"""The names of ``torchmeshmetric.viz``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import colors as colors
from . import error_mesh as error_mesh
from . import html_report as html_report
from . import mesh_logging as mesh_logging
from . import plots as plots
from . import rd_curves as rd_curves
from . import sweep as sweep
from . import validation as validation
from .colors import error_colors, write_error_ply
from .error_mesh import ErrorMesh, glb_bytes, ply_bytes
from .html_report import html_page, write_html
from .mesh_logging import log_error_mesh, surface_errors
from .plots import plot_frame_curves, plot_histograms, plot_mpeg_curves
from .rd_curves import plot_rd_curves
from .sweep import plot_weight_sweep
from .validation import plot_validation

__all__ = [
    "ErrorMesh",
    "error_colors",
    "glb_bytes",
    "html_page",
    "log_error_mesh",
    "ply_bytes",
    "surface_errors",
    "write_html",
    "plot_frame_curves",
    "plot_histograms",
    "plot_mpeg_curves",
    "plot_rd_curves",
    "plot_validation",
    "plot_weight_sweep",
    "write_error_ply",
]
