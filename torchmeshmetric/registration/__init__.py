"""Registration of frame k-1 onto frame k: rigid ICP, then an Adam-optimised embedded deformation graph."""

from torchmeshmetric.registration.deformation_graph import (
    DeformationGraph,
    embedded_deformation,
    farthest_point_nodes,
    skinning_weights,
)
from torchmeshmetric.registration.energies import (
    Correspondences,
    acceptance_weights,
    data_term,
    embedded_deformation_regularizer,
    find_correspondences,
    geman_mcclure,
    interpolated_normals,
    reverse_term,
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
    "acceptance_weights",
    "data_term",
    "embedded_deformation",
    "embedded_deformation_regularizer",
    "farthest_point_nodes",
    "find_correspondences",
    "geman_mcclure",
    "interpolated_normals",
    "kabsch_umeyama",
    "register_nonrigid",
    "register_rigid",
    "reverse_term",
    "skinning_weights",
    "transform_matrix",
]
