"""Visual outputs: per-vertex error colours (PLY), histograms and per-frame curves (PNG, matplotlib)."""

from torchmeshmetric.viz.colors import error_colors, write_error_ply
from torchmeshmetric.viz.plots import plot_frame_curves, plot_histograms, plot_mpeg_curves

__all__ = ["error_colors", "plot_frame_curves", "plot_histograms", "plot_mpeg_curves", "write_error_ply"]
