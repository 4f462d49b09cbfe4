"""The evaluation system: registration of original frames, the four distance sets, statistics, reports."""

from torchmeshmetric.evaluation.cache import CachedRegistration, RegistrationCache, registration_key
from torchmeshmetric.evaluation.comparison import (
    DEFAULT_COMPARISON_STATISTICS,
    compare_methods,
    comparison_markdown,
    paired_t_interval,
)
from torchmeshmetric.evaluation.flicker import FLICKER, FlickerDistances, flicker_distances
from torchmeshmetric.evaluation.pipeline import (
    check_methods,
    default_register,
    evaluate_pair,
    evaluate_sequence,
    register_pairs,
    registration_settings,
)
from torchmeshmetric.evaluation.reports import (
    paper_tables,
    report_dict,
    write_csv,
    write_json,
    write_markdown,
)
from torchmeshmetric.evaluation.results import (
    BEST_PAIR_RULE,
    FLOOR_SET_NAMES,
    SET_NAMES,
    PairEvaluation,
    SequenceEvaluation,
    flatten_statistics,
    mean_statistics,
)
from torchmeshmetric.evaluation.sweep import DEFAULT_SWEEP_WEIGHTS, WeightSweep, registered_qem_sweep
from torchmeshmetric.evaluation.temporal_consistency import TemporalConsistency

__all__ = [
    "BEST_PAIR_RULE",
    "DEFAULT_COMPARISON_STATISTICS",
    "DEFAULT_SWEEP_WEIGHTS",
    "FLICKER",
    "FLOOR_SET_NAMES",
    "SET_NAMES",
    "CachedRegistration",
    "FlickerDistances",
    "PairEvaluation",
    "RegistrationCache",
    "SequenceEvaluation",
    "TemporalConsistency",
    "WeightSweep",
    "compare_methods",
    "comparison_markdown",
    "check_methods",
    "default_register",
    "evaluate_pair",
    "evaluate_sequence",
    "flatten_statistics",
    "flicker_distances",
    "mean_statistics",
    "paired_t_interval",
    "paper_tables",
    "register_pairs",
    "registered_qem_sweep",
    "registration_key",
    "registration_settings",
    "report_dict",
    "write_csv",
    "write_json",
    "write_markdown",
]
