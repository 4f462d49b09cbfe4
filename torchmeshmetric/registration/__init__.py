"""Registration of frame k-1 onto frame k: rigid ICP, then an Adam-optimised embedded deformation graph."""

from torchmeshmetric.registration.rigid import (
    RigidRegistration,
    SimilarityTransform,
    kabsch_umeyama,
    register_rigid,
    transform_matrix,
)

__all__ = [
    "RigidRegistration",
    "SimilarityTransform",
    "kabsch_umeyama",
    "register_rigid",
    "transform_matrix",
]
