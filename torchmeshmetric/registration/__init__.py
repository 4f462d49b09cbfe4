"""Registration of frame k-1 onto frame k: rigid ICP, then an Adam-optimised embedded deformation graph."""

from torchmeshmetric.registration.deformation_graph import (
    DeformationGraph,
    embedded_deformation,
    farthest_point_nodes,
    skinning_weights,
)
from torchmeshmetric.registration.energies import (
    Correspondences,
    embedded_deformation_regularizer,
    find_correspondences,
    geman_mcclure,
    surface_term,
)
from torchmeshmetric.registration.nonrigid import NonRigidRegistration, RegistrationWarning, register_nonrigid
from torchmeshmetric.registration.options import DEFAULT_SCHEDULE, NonRigidOptions, Stage
from torchmeshmetric.registration.rigid import (
    RigidRegistration,
    SimilarityTransform,
    kabsch_umeyama,
    register_rigid,
    transform_matrix,
)
from torchmeshmetric.registration.warp import RegistrationWarp, SurfaceWarp, Warp

__all__ = [
    "DEFAULT_SCHEDULE",
    "Correspondences",
    "DeformationGraph",
    "NonRigidOptions",
    "NonRigidRegistration",
    "RegistrationWarning",
    "RegistrationWarp",
    "RigidRegistration",
    "SimilarityTransform",
    "Stage",
    "SurfaceWarp",
    "Warp",
    "embedded_deformation",
    "embedded_deformation_regularizer",
    "farthest_point_nodes",
    "find_correspondences",
    "geman_mcclure",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    "skinning_weights",
    "surface_term",
    "transform_matrix",
]
