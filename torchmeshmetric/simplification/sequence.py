"""Simplify every frame of a sequence with QEM or Registered QEM (frame 0 has no previous frame: QEM there)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from torchmeshmetric.simplification.qem import simplify_qem
from torchmeshmetric.simplification.registered_qem import DEFAULT_WEIGHT, simplify_registered_qem
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["simplify_sequence"]


def simplify_sequence(
    frames: Sequence[MeshLike],
    target: int | float,
    *,
    registrations: Sequence[Any] | None = None,
    weight: float = DEFAULT_WEIGHT,
) -> list[Mesh]:
    """Simplify every frame: plain QEM without ``registrations``, Registered QEM with them.

    Args:
        frames: the ``N`` original frames.
        target: faces to keep per frame (an ``int`` count or a ``float`` ratio in ``(0, 1]``).
        registrations: ``N - 1`` registrations of original frame ``k-1`` onto frame ``k`` (anything with ``verts``
            of frame ``k-1``'s shape, e.g. :class:`~torchmeshmetric.registration.CachedRegistration`); ``None``:
            :func:`simplify_qem` on every frame.
        weight: Registered QEM's weight of the previous frame (see :func:`simplify_registered_qem`).

    Returns:
        The ``N`` simplified frames. Frame 0 has no previous frame and is simplified with :func:`simplify_qem` in
        both modes, so both modes start from the same frame 0.

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 2
        >>> tuple(m.num_faces for m in simplify_sequence(frames, 0.5))
        (160, 160)
    """
    if registrations is not None and len(registrations) != len(frames) - 1:
        raise ValueError(f"registrations: expected {len(frames) - 1} (one per frame pair), found {len(registrations)}")
    out = []
    for k, frame in enumerate(frames):
        if registrations is None or k == 0:
            out.append(simplify_qem(frame, target))
        else:
            prev = as_mesh(frames[k - 1])
            registered = Mesh(registrations[k - 1].verts.to(prev.verts), prev.faces, validate=False)
            out.append(simplify_registered_qem(frame, registered, target, weight=weight))
    return out
