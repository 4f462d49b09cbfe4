"""The names of ``torchmeshmetric.temporal``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import); ``sted`` is the function (its module
# is torchmeshmetric.temporal.sted, as mpeg.mpeg_metrics).
from . import figures as figures
from . import kg as kg
from . import registered as registered
from . import report as report
from . import sequences as sequences
from . import topology as topology
from .figures import FIGURE_NAMES, TemporalFigures, same_connectivity, temporal_figures
from .kg import kg_error, kso_error
from .registered import (
    RegisteredPair,
    TrackedSequence,
    carry_onto,
    registered_pair,
    track_original,
    weld_short_edges,
)
from .report import temporal_markdown, temporal_report
from .sequences import check_sequence_pair
from .sted import DEFAULT_C, DEFAULT_DT, DEFAULT_WINDOW, StedResult, largest_vertex_distance, sted
from .topology import Neighbourhoods, mesh_edges, neighbourhoods

__all__ = [
    "DEFAULT_C",
    "FIGURE_NAMES",
    "RegisteredPair",
    "TemporalFigures",
    "TrackedSequence",
    "carry_onto",
    "registered_pair",
    "same_connectivity",
    "temporal_figures",
    "temporal_markdown",
    "temporal_report",
    "track_original",
    "weld_short_edges",
    "DEFAULT_DT",
    "DEFAULT_WINDOW",
    "Neighbourhoods",
    "StedResult",
    "check_sequence_pair",
    "kg_error",
    "kso_error",
    "largest_vertex_distance",
    "mesh_edges",
    "neighbourhoods",
    "sted",
]
