"""The names of ``torchmeshmetric.simplification``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import qem as qem
from . import registered_qem as registered_qem
from . import sequence as sequence
from .qem import simplify_qem
from .registered_qem import DEFAULT_WEIGHT, simplify_registered_qem
from .sequence import simplify_sequence

__all__ = [
    "DEFAULT_WEIGHT",
    "simplify_qem",
    "simplify_registered_qem",
    "simplify_sequence",
]
