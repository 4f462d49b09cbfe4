"""The names of ``torchmeshmetric.evaluation``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import campaign as campaign
from . import comparison as comparison
from . import determinacy as determinacy
from . import distortions as distortions
from . import distributed as distributed
from . import flicker as flicker
from . import pipeline as pipeline
from . import reports as reports
from . import results as results
from . import sweep as sweep
from . import temporal_consistency as temporal_consistency
from . import validation as validation
from .comparison import DEFAULT_COMPARISON_STATISTICS, compare_methods, comparison_markdown, paired_t_interval
from .determinacy import Determinacy, measure_determinacy, nudge_frames
from .flicker import FLICKER, FlickerDistances, flicker_distances
from .pipeline import (
    check_methods,
    default_register,
    evaluate_pair,
    evaluate_sequence,
    register_pairs,
    registration_settings,
)
from .reports import paper_tables, report_dict, write_csv, write_json, write_markdown
from .results import (
    BEST_PAIR_RULE,
    FLOOR_SET_NAMES,
    SET_NAMES,
    PairEvaluation,
    SequenceEvaluation,
    flatten_statistics,
    mean_statistics,
)
from .sweep import DEFAULT_SWEEP_WEIGHTS, WeightSweep, registered_qem_sweep
from .temporal_consistency import TemporalConsistency

__all__ = [
    "check_methods",
    "BEST_PAIR_RULE",
    "DEFAULT_COMPARISON_STATISTICS",
    "DEFAULT_SWEEP_WEIGHTS",
    "FLICKER",
    "FLOOR_SET_NAMES",
    "SET_NAMES",
    "Determinacy",
    "FlickerDistances",
    "PairEvaluation",
    "SequenceEvaluation",
    "TemporalConsistency",
    "WeightSweep",
    "compare_methods",
    "comparison_markdown",
    "default_register",
    "evaluate_pair",
    "evaluate_sequence",
    "flatten_statistics",
    "flicker_distances",
    "mean_statistics",
    "measure_determinacy",
    "nudge_frames",
    "paired_t_interval",
    "paper_tables",
    "register_pairs",
    "registered_qem_sweep",
    "registration_settings",
    "report_dict",
    "write_csv",
    "write_json",
    "write_markdown",
]
