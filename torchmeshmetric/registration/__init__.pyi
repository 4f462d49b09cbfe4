"""The names of ``torchmeshmetric.registration``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import adam as adam
from . import cache as cache
from . import deformation_graph as deformation_graph
from . import energies as energies
from . import nonrigid as nonrigid
from . import options as options
from . import rigid as rigid
from . import warp as warp
from .cache import (
    CachedRegistration,
    RegistrationCache,
    compute_registration,
    default_registration_settings,
    registration_key,
)
from .deformation_graph import DeformationGraph, embedded_deformation, farthest_point_nodes, skinning_weights
from .energies import (
    Correspondences,
    acceptance_weights,
    data_term,
    embedded_deformation_regularizer,
    find_correspondences,
    geman_mcclure,
    interpolated_normals,
    reverse_term,
)
from .nonrigid import NonRigidRegistration, RegistrationWarning, register_nonrigid
from .options import DEFAULT_SCHEDULE, NonRigidOptions, Stage
from .rigid import RigidRegistration, SimilarityTransform, kabsch_umeyama, register_rigid, transform_matrix
from .warp import RegistrationWarp, SurfaceWarp, Warp, as_warp, deformation_of

__all__ = [
    "DEFAULT_SCHEDULE",
    "CachedRegistration",
    "Correspondences",
    "DeformationGraph",
    "NonRigidOptions",
    "NonRigidRegistration",
    "RegistrationCache",
    "RegistrationWarning",
    "RegistrationWarp",
    "RigidRegistration",
    "SimilarityTransform",
    "Stage",
    "SurfaceWarp",
    "Warp",
    "as_warp",
    "compute_registration",
    "default_registration_settings",
    "deformation_of",
    "embedded_deformation",
    "embedded_deformation_regularizer",
    "farthest_point_nodes",
    "find_correspondences",
    "geman_mcclure",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    "registration_key",
    "skinning_weights",
    "acceptance_weights",
    "data_term",
    "interpolated_normals",
    "reverse_term",
    "transform_matrix",
]
