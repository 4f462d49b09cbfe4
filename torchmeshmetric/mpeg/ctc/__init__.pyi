"""The names of ``torchmeshmetric.mpeg.ctc``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import campaign as campaign
from . import chain as chain
from . import dequantize as dequantize
from . import face_errors as face_errors
from . import frame_pattern as frame_pattern
from . import manifest as manifest
from . import settings as settings
from . import sheet as sheet
from .bd_rate import bd_rate
from .campaign import CampaignResult, run_ctc_campaign
from .chain import CTC_COLUMNS, CtcFrame, CtcSequence, ctc_frame, ctc_mean, ctc_sequence
from .dequantize import dequantize_positions, dequantize_uvs
from .face_errors import FaceErrors, ctc_face_errors
from .manifest import CtcCampaign, CtcManifestError, load_ctc_campaign
from .settings import CtcSettings
from .sheet import RatePoint, ctc_summary, read_test_model_csv

__all__ = [
    "bd_rate",
    "CTC_COLUMNS",
    "CtcFrame",
    "CtcSequence",
    "ctc_frame",
    "ctc_mean",
    "ctc_sequence",
    "CtcSettings",
    "CampaignResult",
    "run_ctc_campaign",
    "CtcCampaign",
    "CtcManifestError",
    "load_ctc_campaign",
    "RatePoint",
    "ctc_summary",
    "read_test_model_csv",
    "dequantize_positions",
    "dequantize_uvs",
    "FaceErrors",
    "ctc_face_errors",
]
