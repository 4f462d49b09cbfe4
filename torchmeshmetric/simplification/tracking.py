"""Tracking simplification of a sequence: Anchored QEM on every frame, optionally a learned :class:`TemporalSlide`.

Frame 0 is simplified with QEM (:func:`simplify_qem`). Frame ``k`` is simplified with :func:`simplify_anchored_qem`,
anchored at the vertices of the anchored frame ``k-1`` moved by the registration; then, with a ``slide``, each frame's
vertices slide towards the warped *output* frame ``k-1``. The anchors come from the anchored frames (before any
slide), so the collapses do not depend on the model and a training loop computes them once
(:func:`anchored_sequence`), then runs the differentiable :func:`slide_sequence` at every step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.registration.warp import Warp, as_warp
from torchmeshmetric.simplification._target import resolve_target
from torchmeshmetric.simplification.anchored_qem import DEFAULT_ANCHOR_WEIGHT, simplify_anchored_qem
from torchmeshmetric.simplification.qem import simplify_qem
from torchmeshmetric.simplification.temporal_slide import TemporalSlide
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["anchored_sequence", "registration_warp", "simplify_tracking", "slide_sequence"]


def registration_warp(
    registration: Any, original_k_minus_1: MeshLike, original_k: MeshLike, *, name: str = "registration"
) -> Warp:
    """The map of frame ``k-1`` points to frame ``k`` of a registration, as the temporal loss and evaluation make it.

    One conversion for all (:func:`~torchmeshmetric.registration.as_warp`): its ``warp`` when it has one (e.g. a
    ``CachedRegistration`` of :func:`~torchmeshmetric.evaluation.register_pairs`); a
    :class:`~torchmeshmetric.registration.NonRigidRegistration`'s deformation graph
    (:class:`~torchmeshmetric.registration.RegistrationWarp`; its own piecewise-linear map of the registered
    vertices moved simplified vertices 0.0019 on average from where the loss and the evaluation put them, found by
    review); a registration known only by its registered ``verts`` (or the registered mesh) as their
    :class:`~torchmeshmetric.registration.SurfaceWarp`; a callable as is.

    Args:
        registration: the registration of ``original_k_minus_1`` onto ``original_k``.
        original_k_minus_1: the source frame.
        original_k: the target frame (a ``NonRigidRegistration``'s deformation is defined in its frame).
        name: the registration's name in errors.

    Raises:
        TypeError: a registration of none of those kinds.
        ShapeError: registered vertices that are not those of ``original_k_minus_1``.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=1)
        >>> registration_warp(lambda points: points, sphere, sphere)(torch.zeros(1, 3)).tolist()
        [[0.0, 0.0, 0.0]]
    """
    return as_warp(registration, original_k, as_mesh(original_k_minus_1, name="original_k_minus_1"), name=name)


def _check_lengths(frames: Sequence[Any], registrations: Sequence[Any]) -> None:
    if len(frames) == 0:
        raise EmptyInputError("frames: expected at least one frame, found none")
    if len(registrations) != len(frames) - 1:
        raise ValueError(f"registrations: expected {len(frames) - 1} (one per frame pair), found {len(registrations)}")


def anchored_sequence(
    frames: Sequence[MeshLike],
    target: int | float,
    registrations: Sequence[Any],
    *,
    weight: float = DEFAULT_ANCHOR_WEIGHT,
) -> list[Mesh]:
    """QEM on frame 0, then Anchored QEM on frame ``k`` anchored at the warped anchored frame ``k-1``.

    Args:
        frames: the ``N`` original frames.
        target: faces per frame (an ``int`` count or a ``float`` ratio in ``(0, 1]``).
        registrations: ``N - 1`` registrations of original frame ``k-1`` onto frame ``k`` (see
            :func:`registration_warp`).
        weight: the anchor weight of :func:`simplify_anchored_qem`.

    Returns:
        The ``N`` simplified frames (no gradient).

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 3
        >>> same = [lambda points: points] * 2  # frames that do not move
        >>> tuple(m.num_faces for m in anchored_sequence(frames, 0.5, same))
        (160, 160, 160)
    """
    _check_lengths(frames, registrations)
    out = [simplify_qem(frames[0], target)]
    for k in range(1, len(frames)):
        warp = registration_warp(registrations[k - 1], frames[k - 1], frames[k], name=f"registrations[{k - 1}]")
        with torch.no_grad():
            anchors = warp(out[-1].verts.detach())
        out.append(simplify_anchored_qem(frames[k], anchors, target, weight=weight))
    return out


def slide_sequence(
    anchored: Sequence[Mesh], frames: Sequence[MeshLike], registrations: Sequence[Any], slide: TemporalSlide
) -> list[Mesh]:
    """Each anchored frame ``k >= 1`` slid towards the warped *output* frame ``k-1`` (frame 0 is kept).

    Differentiable in ``slide``'s parameters through the whole chain (the output frame ``k-1`` is the target of
    frame ``k``): a training loop calls it at every step on the same ``anchored`` frames.

    Args:
        anchored: the frames of :func:`anchored_sequence`.
        frames: the ``N`` original frames (for registrations known only by their registered vertices).
        registrations: the ``N - 1`` registrations.
        slide: the learned placement.

    Returns:
        ``N`` meshes with the faces of ``anchored``.

    Raises:
        ValueError: ``anchored`` or ``registrations`` of the wrong length.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.simplification import TemporalSlide
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 2
        >>> same = [lambda points: points]  # frames that do not move
        >>> anchored = anchored_sequence(frames, 0.5, same)
        >>> slid = slide_sequence(anchored, frames, same, TemporalSlide())
        >>> [m.num_faces for m in slid], slid[1].verts.requires_grad  # a loss on it trains the slide
        ([160, 160], True)
    """
    _check_lengths(frames, registrations)
    if len(anchored) != len(frames):
        raise ValueError(f"anchored: expected {len(frames)} frames (one per original), found {len(anchored)}")
    dtype = slide.dtype
    out = [anchored[0].to(dtype=dtype)]
    for k in range(1, len(anchored)):
        warp = registration_warp(registrations[k - 1], frames[k - 1], frames[k], name=f"registrations[{k - 1}]")
        previous = Mesh(warp(out[-1].verts), out[-1].faces, validate=False)
        current = anchored[k].to(dtype=dtype)
        out.append(Mesh(slide(current, previous), current.faces, validate=False))
    return out


def simplify_tracking(
    frames: Sequence[MeshLike],
    target: int | float,
    registrations: Sequence[Any],
    *,
    weight: float = DEFAULT_ANCHOR_WEIGHT,
    slide: TemporalSlide | None = None,
) -> list[Mesh]:
    """Simplify a sequence so that each frame follows the previous one's tessellation (see the module docstring).

    Args:
        frames: the ``N`` original frames.
        target: faces per frame (an ``int`` count or a ``float`` ratio in ``(0, 1]``).
        registrations: ``N - 1`` registrations of original frame ``k-1`` onto frame ``k``.
        weight: the anchor weight of :func:`simplify_anchored_qem`.
        slide: a trained :class:`TemporalSlide`, or ``None`` for Anchored QEM alone.

    Returns:
        The ``N`` simplified frames, detached, in the dtype of ``frames[0]``. A target that keeps every face of every
        frame returns detached copies of the frames (as :func:`simplify_qem` does): nothing is simplified, so
        nothing is carried or slid (the slide moved vertices up to 0.5 % of the diagonal off the surface at ``1.0``).

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 2
        >>> tuple(m.num_faces for m in simplify_tracking(frames, 0.5, [lambda points: points]))
        (160, 160)
    """
    meshes = [as_mesh(f, name=f"frames[{k}]") for k, f in enumerate(frames)]
    if meshes and all(resolve_target(target, m.num_faces) == m.num_faces for m in meshes):
        # Copies, as simplify_qem's: the output shared its tensors with the caller's frames.
        return [Mesh(m.verts.detach().to(meshes[0].dtype, copy=True), m.faces.clone(), validate=False) for m in meshes]
    anchored = anchored_sequence(frames, target, registrations, weight=weight)
    if slide is None:
        return anchored
    with torch.no_grad():
        out = slide_sequence(anchored, frames, registrations, slide)
    return [Mesh(m.verts.to(anchored[0].dtype), m.faces, validate=False) for m in out]
