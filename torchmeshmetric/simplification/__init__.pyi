"""The names of ``torchmeshmetric.simplification``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import anchored_qem as anchored_qem
from . import qem as qem
from . import registered_qem as registered_qem
from . import sequence as sequence
from . import temporal_slide as temporal_slide
from . import tracking as tracking
from .anchored_qem import DEFAULT_ANCHOR_WEIGHT, simplify_anchored_qem
from .qem import simplify_qem
from .registered_qem import DEFAULT_WEIGHT, simplify_registered_qem
from .sequence import simplify_sequence
from .temporal_slide import TemporalSlide
from .tracking import anchored_sequence, simplify_tracking, slide_sequence

__all__ = [
    "DEFAULT_ANCHOR_WEIGHT",
    "DEFAULT_WEIGHT",
    "TemporalSlide",
    "anchored_sequence",
    "simplify_anchored_qem",
    "simplify_qem",
    "simplify_registered_qem",
    "simplify_sequence",
    "simplify_tracking",
    "slide_sequence",
]
