"""Simplifiers: plain QEM (fast-simplification) and Registered QEM (ours), Garland & Heckbert 1997."""

from torchmeshmetric.simplification.qem import simplify_qem
from torchmeshmetric.simplification.registered_qem import simplify_registered_qem

__all__ = ["simplify_qem", "simplify_registered_qem"]
