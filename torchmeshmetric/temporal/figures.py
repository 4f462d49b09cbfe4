"""The five temporal figures of a sequence pair, exact when the connectivity allows, registered otherwise.

The entry point of the tools (``torchmeshmetric temporal``, the evaluation reports): KG, KSO, STED_s, STED_t and
STED as plain numbers, and whether they came from the registered form (docs/temporal.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, ShapeError
from torchmeshmetric.evaluation.pipeline import RegisterFn, RegistrationOptions
from torchmeshmetric.registration.cache import CachedRegistration, RegistrationCache
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh
from torchmeshmetric.temporal.kg import kg_error, kso_error
from torchmeshmetric.temporal.registered import registered_pair
from torchmeshmetric.temporal.sted import DEFAULT_C, DEFAULT_DT, DEFAULT_WINDOW, check_sted_parameters, sted
from torchmeshmetric.temporal.topology import referenced_vertices

__all__ = ["FIGURE_NAMES", "TemporalFigures", "same_connectivity", "temporal_figures"]

#: The figures, in the order the tools print them.
FIGURE_NAMES = ("kg", "kso", "sted_s", "sted_t", "sted")


class TemporalFigures(NamedTuple):
    """KG, KSO, STED_s, STED_t and STED of a sequence pair (see :func:`temporal_figures`).

    Attributes:
        kg: KG error (percent).
        kso: KSO's E_RMS.
        sted_s: STED's spatial part.
        sted_t: STED's temporal part.
        sted: STED.
        registered: ``True`` when measured with the registered form (the frames' connectivity differs).
        num_frames: frames compared.
        num_verts: vertices followed: those some face of the original's frame 0 references (vertices no face uses
            take no part), or the tracked frame 0's.
        unconverged: frames ``k`` of the original whose registration of ``k-1`` onto ``k`` (the registered forms'
            tracking) says ``converged=False``; empty for the exact forms.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> frames = [trimesh.Trimesh(sphere.vertices * (1 + 0.1 * k), sphere.faces) for k in range(3)]
        >>> f = temporal_figures(frames, frames)
        >>> f.num_frames, f.num_verts, f.registered, f.kg, f.unconverged
        (3, 162, False, 0.0, ())
    """

    kg: float
    kso: float
    sted_s: float
    sted_t: float
    sted: float
    registered: bool
    num_frames: int
    num_verts: int
    unconverged: tuple[int, ...] = ()

    def as_dict(self) -> dict[str, float | bool | int | list[int]]:
        """The figures as a plain dict (for JSON reports)."""
        return {**self._asdict(), "unconverged": list(self.unconverged)}


def same_connectivity(original: Sequence[Mesh], distorted: Sequence[Mesh]) -> bool:
    """Whether the exact forms apply to two sequences of meshes.

    They do when every frame of both has the original frame 0's vertex count and its triangles: the same vertex
    triples, in any face order and any order within a face. The exact forms compare vertex ``i`` of both, so the
    distorted frames' faces are the evidence that their vertex ``i`` is the original's: the same surfaces with their
    vertices numbered otherwise have the same counts and other triples (measured by the registered forms instead).

    Args:
        original: the original frames (frame 0's vertex count and triangles are the reference).
        distorted: the distorted frames.

    Returns:
        Whether every frame of both has frame 0's vertex count and triangles.

    Example:
        >>> import trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> flipped = Mesh(sphere.verts, sphere.faces.flip(0).roll(1, dims=1))  # other order, same triangles
        >>> renumbered = Mesh(sphere.verts.flip(0), sphere.num_verts - 1 - sphere.faces)
        >>> same_connectivity([sphere, sphere], [flipped, sphere]), same_connectivity([sphere], [renumbered])
        (True, False)
    """
    first = original[0]
    if any(m.num_verts != first.num_verts for m in (*original, *distorted)):
        return False
    faces, triangles = first.faces.cpu(), None
    for m in (*original[1:], *distorted):
        if m.faces.shape != faces.shape:
            return False
        if torch.equal(m.faces.cpu(), faces):  # the same faces: no sort (~60 ms a 40k-face frame)
            continue
        triangles = _triangles(faces) if triangles is None else triangles
        if not torch.equal(_triangles(m.faces), triangles):
            return False
    return True


def _triangles(faces: Tensor) -> Tensor:
    """``faces`` as a set: each face's indices sorted, then the faces sorted (duplicates kept once)."""
    return torch.unique(faces.detach().cpu().sort(dim=1).values, dim=0)


def temporal_figures(
    original: Sequence[MeshLike],
    distorted: Sequence[MeshLike],
    *,
    registered: bool | None = None,
    registrations: Sequence[CachedRegistration] | None = None,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    registration_cache: RegistrationCache | None = None,
    device: torch.device | str | None = None,
    backend: str = "auto",
    dt: float = DEFAULT_DT,
    window: int = DEFAULT_WINDOW,
    c: float = DEFAULT_C,
) -> TemporalFigures:
    """KG, KSO, STED_s, STED_t and STED of ``distorted`` against ``original``, in float64.

    Vertices that no face of the original's frame 0 uses are not part of the surface and take no part, in either form
    (the registered form tracks frame 0 without them).

    Args:
        original: the ``F >= 2`` original frames.
        distorted: the ``F`` distorted frames.
        registered: ``None`` (default): the exact forms when :func:`same_connectivity`, the registered forms
            otherwise; ``True``: the registered forms; ``False``: the exact forms (an error if they do not apply).
        registrations: the ``F - 1`` registrations of the registered forms when already computed.
        registration_fn: registration function (default: the library's non-rigid registration).
        registration_options: options of the default registration (part of the cache key).
        registration_cache: a :class:`~torchmeshmetric.registration.RegistrationCache` (``None``: no cache).
        device: where the registration, the tracking and the metrics run.
        backend: kernel backend of the registration and of the closest-point queries.
        dt: STED's temporal step (see :func:`~torchmeshmetric.temporal.sted`).
        window: STED's temporal window (half-width in frames).
        c: STED's weight of the temporal part.

    Returns:
        :class:`TemporalFigures`.

    Raises:
        ShapeError: frame counts that differ, fewer than 2 frames, or ``registered=False`` on frames whose
            connectivity differs.
        EmptyInputError: a frame without vertices or faces (named).
        TypeError, ValueError: ``registered`` not ``None`` or a bool; ``dt``, ``window``, ``c`` as :func:`sted`
            checks them (before any registration).

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> frames = [trimesh.Trimesh(sphere.vertices * (1 + 0.1 * k), sphere.faces) for k in range(3)]
        >>> f = temporal_figures(frames, frames)
        >>> f.registered, f.kg, f.sted
        (False, 0.0, 0.0)
    """
    if isinstance(original, (str, bytes)) or not isinstance(original, Sequence):
        raise TypeError(f"original: expected a sequence of meshes, found {type(original).__name__}")
    if isinstance(distorted, (str, bytes)) or not isinstance(distorted, Sequence):
        raise TypeError(f"distorted: expected a sequence of meshes, found {type(distorted).__name__}")
    originals = [as_mesh(m, name=f"original[{k}]") for k, m in enumerate(original)]
    distorteds = [as_mesh(m, name=f"distorted[{k}]") for k, m in enumerate(distorted)]
    if len(originals) != len(distorteds):
        raise ShapeError(f"distorted: expected {len(originals)} frame(s) (those of original), found {len(distorteds)}")
    if len(originals) < 2:
        raise ShapeError(f"original: expected at least 2 frames, found {len(originals)}")
    if registered is not None and not isinstance(registered, bool):  # 0 or "no" would pick a form silently
        raise TypeError(f"registered: expected None, True or False, found {registered!r}")
    for name, meshes in (("original", originals), ("distorted", distorteds)):
        for k, m in enumerate(meshes):
            if m.num_verts == 0 or m.num_faces == 0:
                raise EmptyInputError(
                    f"{name}[{k}]: expected a mesh, found {m.num_verts} vertices and {m.num_faces} faces"
                )
    check_sted_parameters(dt, window, c)  # now, not after the registered forms' registrations
    exact = same_connectivity(originals, distorteds)
    if registered is False and not exact:
        raise ShapeError(
            "registered=False: the exact forms need every frame of both sequences to have the original frame 0's "
            "vertex count and triangles (the same vertex triples); these differ (use the registered forms)"
        )
    use_registered = not exact if registered is None else registered
    if use_registered:
        pair = registered_pair(
            originals,
            distorteds,
            registrations=registrations,
            registration_fn=registration_fn,
            registration_options=registration_options,
            registration_cache=registration_cache,
            device=device,
            backend=backend,
        )
        a, b, faces = pair.original.detach(), pair.distorted.detach(), pair.faces
        unconverged = tuple(k for k, r in enumerate(pair.tracking.registrations, 1) if not r.converged)
    else:
        unconverged = ()
        dev = torch.device(device) if device is not None else originals[0].device
        a = torch.stack([m.verts.detach().to(dev, torch.float64) for m in originals])
        b = torch.stack([m.verts.detach().to(dev, torch.float64) for m in distorteds])
        # Only the vertices some face uses, as the registered form's tracked frame 0 (found by review: a stray vertex
        # moved KG by 3.8 % through its denominator, and the two forms disagreed on one unchanged connectivity).
        used, faces = referenced_vertices(originals[0].faces.to(dev), a.shape[1])
        if not bool(used.all()):
            a, b = a[:, used], b[:, used]
    s = sted(a, b, faces, dt=dt, window=window, c=c)
    return TemporalFigures(
        kg=float(kg_error(a, b)),
        kso=float(kso_error(a, b)),
        sted_s=float(s.spatial),
        sted_t=float(s.temporal),
        sted=float(s.sted),
        registered=use_registered,
        num_frames=int(a.shape[0]),
        num_verts=int(a.shape[1]),
        unconverged=unconverged,
    )
