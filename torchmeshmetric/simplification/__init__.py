"""Simplifiers: plain QEM (fast-simplification) and Registered QEM (ours), Garland & Heckbert 1997."""

from torchmeshmetric.simplification.qem import simplify_qem
from torchmeshmetric.simplification.registered_qem import DEFAULT_WEIGHT, simplify_registered_qem
from torchmeshmetric.simplification.sequence import simplify_sequence

__all__ = ["DEFAULT_WEIGHT", "simplify_qem", "simplify_registered_qem", "simplify_sequence"]
