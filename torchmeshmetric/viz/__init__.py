"""Visual outputs: per-vertex error colours (PLY), histograms and per-frame curves (PNG, matplotlib)."""

from torchmeshmetric.viz.colors import error_colors, write_error_ply
from torchmeshmetric.viz.plots import plot_frame_curves, plot_histograms, plot_mpeg_curves
from torchmeshmetric.viz.sweep import plot_weight_sweep
from torchmeshmetric.viz.validation import plot_validation

__all__ = [
    "error_colors",
    "plot_frame_curves",
    "plot_histograms",
    "plot_mpeg_curves",
    "plot_validation",
    "plot_weight_sweep",
    "write_error_ply",
]
