r"""A registration as a map of arbitrary points: frame ``k-1`` space → frame ``k`` space.

A registration of original frame ``k-1`` onto frame ``k`` moves that frame's vertices; the evaluation's ``flicker``
set also needs to move *other* points of frame ``k-1`` (the vertices of the simplified frame ``k-1``). Two maps:

* :class:`RegistrationWarp` — the deformation that :func:`~torchmeshmetric.registration.register_nonrigid` found,
  defined in all of space: the rigid (similarity) transform, the normalisation to the target's bounding-box centre
  and unit diagonal, then the embedded deformation graph (Sumner, Schmid & Pauly 2007), each point skinned to its
  ``K`` nearest nodes exactly as the registered vertices were:

  .. math::

      x \mapsto d\, G\!\left(\frac{s R x + t - c}{d}\right) + c.

  On the source vertices it reproduces the registered vertices (to rounding).
* :class:`SurfaceWarp` — for a registration known only by its registered vertices (a mesh, a user's function, a
  cached entry without the deformation): the piecewise-linear map of the source surface, extended off the surface
  by the closest point. A point ``x`` with closest point ``p = \sum_j b_j v_j`` on face ``(v_0, v_1, v_2)`` of the
  source moves by the barycentric blend of its vertices' displacements: ``x + \sum_j b_j (v'_j - v_j)``. It is a
  translation locally, so an offset from the surface keeps its direction while the surface rotates (an error of
  about the offset times the rotation angle between the frames).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, NamedTuple, Protocol

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError, check_finite, check_float, check_int, check_shape, check_tensor
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.registration._common import normalisation
from torchmeshmetric.registration.deformation_graph import embedded_deformation, skinning_weights
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, is_mesh_like

if TYPE_CHECKING:
    from torchmeshmetric.registration.nonrigid import NonRigidRegistration

__all__ = ["RegistrationWarp", "SurfaceWarp", "Warp", "as_warp", "deformation_of"]


class Warp(Protocol):
    """A map of ``(P, 3)`` points of frame ``k-1`` to their ``(P, 3)`` positions in frame ``k`` (any callable).

    Example:
        >>> import torch
        >>> shift: Warp = lambda points: points + torch.tensor([0.5, 0.0, 0.0])  # any callable (P, 3) -> (P, 3)
        >>> shift(torch.zeros(2, 3)).tolist()
        [[0.5, 0.0, 0.0], [0.5, 0.0, 0.0]]
        >>> as_warp(shift, None, None, name="registration") is shift  # taken as it is wherever a registration goes
        True
    """

    def __call__(self, points: Tensor, /) -> Tensor:
        """Positions in frame ``k`` of ``points``."""
        ...


def _check_points(points: Tensor) -> None:
    check_shape(points, ("P", 3), "points")
    check_float(points, "points")
    check_finite(points, "points")


def check_warped(moved: object, points: Tensor, name: str) -> Tensor:
    """Check a warp's output ``moved`` for its input ``points``: the evaluation's and the temporal loss's one check.

    A warp is the caller's code (a voxel-grid lookup that forgets ``.float()``, a half-precision model): its output
    is refused rather than cast, since a cast gave a silently wrong loss and, from integers, no gradient (found by
    review). Finiteness is the caller's to check (the loss checks a whole batch with one device read).

    Args:
        moved: the warp's output.
        points: ``(V, 3)`` the points it was given.
        name: the output's name in errors (e.g. ``"warp(simplified_k_minus_1.verts)"``).

    Returns:
        ``moved``, a ``(V, 3)`` float32 or float64 tensor.

    Raises:
        TypeError: ``moved`` is not a tensor.
        ShapeError: it is not ``(V, 3)``, one row per point.
        DTypeError: it is not float32 or float64 (integer, boolean, complex, half precision).

    Example:
        >>> p = torch.zeros(4, 3)
        >>> check_warped(p + 1.0, p, "warp(points)").shape
        torch.Size([4, 3])
    """
    check_tensor(moved, name, "a (V, 3) torch.Tensor")
    assert isinstance(moved, Tensor)  # for mypy: check_tensor raised otherwise
    check_shape(moved, (points.shape[0], 3), name)
    check_float(moved, name)
    return moved


#: The tensor fields of a :class:`RegistrationWarp` (all but ``num_neighbors``).
_WARP_TENSORS = ("rigid", "center", "diagonal", "nodes", "rotations", "translations")


class RegistrationWarp(NamedTuple):
    """The deformation of a non-rigid registration, applicable to any points (see the module docstring).

    Attributes:
        rigid: ``(4, 4)`` similarity transform ``[[s R, t], [0, 1]]`` applied first (identity without one).
        center: ``(3,)`` centre of the normalised frame (target's bounding-box centre).
        diagonal: 0-dim scale of the normalised frame (target's bounding-box diagonal).
        nodes: ``(N, 3)`` graph nodes, in the normalised frame.
        rotations: ``(N, 3, 3)`` node rotation matrices.
        translations: ``(N, 3)`` node translations, in the normalised frame.
        num_neighbors: nodes per point ``K`` of the skinning.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric.registration import register_nonrigid
        >>> src = trimesh.creation.icosphere(subdivisions=1)
        >>> tgt = trimesh.creation.icosphere(subdivisions=2)
        >>> tgt.vertices *= [1.1, 1.0, 0.9]
        >>> r = register_nonrigid(src, tgt)  # 42 -> 162 vertices: ~0.2 s
        >>> r.converged
        True
        >>> warp = RegistrationWarp.from_registration(r, tgt)
        >>> bool(torch.allclose(warp(torch.tensor(src.vertices)), r.verts, atol=1e-12))
        True
    """

    rigid: Tensor
    center: Tensor
    diagonal: Tensor
    nodes: Tensor
    rotations: Tensor
    translations: Tensor
    num_neighbors: int

    @classmethod
    def from_registration(cls, result: NonRigidRegistration, target: MeshLike) -> RegistrationWarp:
        """The warp of a :class:`~torchmeshmetric.registration.NonRigidRegistration` of a source onto ``target``.

        Args:
            result: the registration's result (its ``graph`` and ``rigid``).
            target: the mesh it was registered onto (defines the normalised frame).
        """
        graph = result.graph
        dtype, dev = graph.nodes.dtype, graph.nodes.device
        center, diagonal = normalisation(as_mesh(target, name="target").to(dev, dtype))
        with torch.no_grad():
            return cls(
                rigid=result.rigid.transform.detach().to(dev, dtype),
                center=center.detach(),
                diagonal=diagonal.detach(),
                nodes=graph.nodes.detach(),
                rotations=graph.rotation_matrices().detach(),
                translations=graph.translations.detach(),
                num_neighbors=int(graph.vert_nodes.shape[1]),
            )

    def __call__(self, points: Tensor) -> Tensor:
        """``(P, 3)`` positions in frame ``k`` of ``points (P, 3)`` given in frame ``k-1`` (dtype/device kept)."""
        _check_points(points)
        w = self.to(points.device, torch.promote_types(points.dtype, self.nodes.dtype))
        x = points.to(w.nodes.dtype)
        x = x @ w.rigid[:3, :3].T + w.rigid[:3, 3]
        x = (x - w.center) / w.diagonal
        idx, weights = skinning_weights(x, w.nodes, w.num_neighbors)
        x = embedded_deformation(x, w.nodes, w.rotations, w.translations, idx, weights)
        return (x * w.diagonal + w.center).to(points.dtype)

    def to(self, device: torch.device | str, dtype: torch.dtype | None = None) -> RegistrationWarp:
        """The warp with every tensor on ``device`` (and in ``dtype`` when given; tensors already there are kept)."""
        return self._replace(
            **{
                name: getattr(self, name).to(device=device, dtype=dtype or getattr(self, name).dtype)
                for name in _WARP_TENSORS
            }
        )

    def clone(self) -> RegistrationWarp:
        """A copy whose tensors share no memory with this warp's (an in-place edit of one leaves the other)."""
        return self._replace(**{name: getattr(self, name).clone() for name in _WARP_TENSORS})

    def state(self) -> dict[str, object]:
        """Plain dict of tensors and ints (for ``torch.save(weights_only=True)``); :meth:`from_state` reverses it."""
        return {name: getattr(self, name) for name in self._fields}

    @classmethod
    def from_state(cls, state: Mapping[str, object], *, name: str = "warp") -> RegistrationWarp:
        """Rebuild a warp from :meth:`state`, checked: a state read back from a file may be anything.

        Args:
            state: what :meth:`state` returned.
            name: the state's name in errors (each field is named ``{name}.{field}``).

        Raises:
            ValueError: a missing field, a diagonal that is not positive, a graph without nodes.
            ShapeError, DTypeError, NonFiniteError: a tensor of the wrong shape or dtype, or holding NaN/Inf (a warp
                that would move every point to NaN, or divide by a zero diagonal).
            TypeError: a field that is not a tensor, a ``num_neighbors`` that is not an int >= 1.

        Example:
            >>> import torch
            >>> eye = torch.eye(3, dtype=torch.float64)
            >>> warp = RegistrationWarp(torch.eye(4, dtype=torch.float64), torch.zeros(3, dtype=torch.float64),
            ...                         torch.tensor(1.0, dtype=torch.float64), eye, eye.expand(3, 3, 3), 0 * eye, 2)
            >>> RegistrationWarp.from_state({**warp.state(), "diagonal": torch.tensor(0.0)})
            Traceback (most recent call last):
                ...
            ValueError: warp.diagonal: expected a positive scale (the target's diagonal), found 0.0
        """
        missing = [field for field in cls._fields if field not in state]
        if missing:
            raise ValueError(f"{name}: expected the fields {list(cls._fields)}, found none for {missing}")
        shapes: dict[str, tuple[str | int, ...]] = {
            "rigid": (4, 4), "center": (3,), "diagonal": (), "nodes": ("N", 3), "rotations": ("N", 3, 3),
            "translations": ("N", 3),
        }  # fmt: skip
        tensors: dict[str, Tensor] = {}
        for field, pattern in shapes.items():
            t = state[field]
            check_shape(t, pattern, f"{name}.{field}")  # type: ignore[arg-type]
            assert isinstance(t, Tensor)  # check_shape refuses anything else
            check_float(t, f"{name}.{field}")
            check_finite(t, f"{name}.{field}")
            tensors[field] = t
        nodes = tensors["nodes"].shape[0]
        if nodes == 0:
            raise ValueError(f"{name}.nodes: expected at least one node, found none")
        for field in ("rotations", "translations"):
            if tensors[field].shape[0] != nodes:
                raise ShapeError(
                    f"{name}.{field}: expected one row per node ({nodes}), found {tensors[field].shape[0]}"
                )
        diagonal = float(tensors["diagonal"])
        if not diagonal > 0:
            raise ValueError(f"{name}.diagonal: expected a positive scale (the target's diagonal), found {diagonal}")
        num_neighbors = check_int(state["num_neighbors"], f"{name}.num_neighbors", 1)
        return cls(**tensors, num_neighbors=num_neighbors)


class SurfaceWarp(NamedTuple):
    """The piecewise-linear map of a registration known by its registered vertices (see the module docstring).

    Attributes:
        source: the source mesh (original frame ``k-1``).
        registered_verts: ``(V, 3)`` its registered vertices (same order), in frame ``k``.

    Example:
        >>> import torch, trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> warp = SurfaceWarp(sphere, sphere.verts + torch.tensor([0.5, 0.0, 0.0]))
        >>> warp(torch.tensor([[0.0, 0.0, 2.0]], dtype=sphere.dtype)).tolist()  # a translation moves every point
        [[0.5, 0.0, 2.0]]
    """

    source: Mesh
    registered_verts: Tensor

    def __call__(self, points: Tensor) -> Tensor:
        """``(P, 3)`` positions in frame ``k`` of ``points (P, 3)`` given in frame ``k-1`` (dtype/device kept)."""
        _check_points(points)
        if tuple(self.registered_verts.shape) != tuple(self.source.verts.shape):
            raise ShapeError(
                f"registered_verts: expected the shape of the source's vertices {tuple(self.source.verts.shape)}, "
                f"found {tuple(self.registered_verts.shape)}"
            )
        dtype = torch.promote_types(points.dtype, self.source.dtype)
        src = self.source.to(points.device, dtype)
        disp = self.registered_verts.to(points.device, dtype) - src.verts
        with torch.no_grad():
            hit = point_mesh_distance(points.to(dtype), src)
        moved = points.to(dtype) + (hit.bary[..., None] * disp[src.faces[hit.face_idx]]).sum(1)
        return moved.to(points.dtype)


def deformation_of(registration: object, original_k: MeshLike) -> Warp | None:
    """The deformation a caller's registration carries: its ``warp``, or a ``NonRigidRegistration``'s; else ``None``.

    One of the two conversions of a registration (the evaluation's and the temporal loss's); :func:`as_warp` is the
    other, for registrations known only by their registered vertices.

    Args:
        registration: a caller's registration: anything with a ``warp`` attribute (the evaluation's
            ``CachedRegistration``), a ``NonRigidRegistration``, or anything else (then ``None``).
        original_k: the target frame (a ``NonRigidRegistration``'s warp needs it).

    Returns:
        The registration's :data:`Warp` (a callable mapping ``(P, 3)`` points of frame ``k-1`` to frame ``k``), or
        ``None`` when it carries no deformation.

    Example:
        >>> from types import SimpleNamespace
        >>> shift = lambda points: points + 1.0
        >>> deformation_of(SimpleNamespace(warp=shift), None) is shift, deformation_of(object(), None) is None
        (True, True)
    """
    warp = getattr(registration, "warp", None)  # a CachedRegistration (evaluation), or anything holding a warp
    if warp is not None:
        return warp
    if getattr(registration, "graph", None) is not None and hasattr(registration, "rigid"):  # NonRigidRegistration
        return RegistrationWarp.from_registration(registration, original_k)  # type: ignore[arg-type]
    return None


def as_warp(registration: object, original_k: MeshLike, original_k_minus_1: Mesh, *, name: str) -> Warp:
    """A caller's registration of ``original_k_minus_1`` onto ``original_k`` as a map of points (frame k-1 → k).

    Args:
        registration: a warp (any callable ``(P, 3) -> (P, 3)``), a ``NonRigidRegistration``, an object with a
            ``warp`` (the evaluation's ``CachedRegistration``) or only ``verts``, or the registered mesh (frame
            ``k-1``'s topology): the last two as their :class:`SurfaceWarp`.
        original_k: the target frame.
        original_k_minus_1: the source frame.
        name: the argument's name in errors.

    Returns:
        A :data:`Warp`: the registration's own deformation (:func:`deformation_of`), the callable itself, or a
        :class:`SurfaceWarp` of the registered vertices (in ``original_k_minus_1``'s dtype and device).

    Raises:
        ShapeError: registered vertices that are not those of ``original_k_minus_1``.
        TypeError: anything else.

    Example:
        >>> import torch, trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> warp = as_warp((sphere.verts + 1.0, sphere.faces), sphere, sphere, name="registration")
        >>> type(warp).__name__, (warp(sphere.verts[:2]) - sphere.verts[:2]).round(decimals=9).tolist()
        ('SurfaceWarp', [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    """
    warp = deformation_of(registration, original_k)
    if warp is not None:
        return warp
    verts = getattr(registration, "verts", None)
    if verts is None and is_mesh_like(registration):
        verts = as_mesh(registration, name=name).verts  # type: ignore[arg-type]
    if verts is not None:  # known only by its registered vertices: their piecewise-linear map
        verts = torch.as_tensor(verts).detach()
        if tuple(verts.shape) != tuple(original_k_minus_1.verts.shape):
            raise ShapeError(
                f"{name}: expected registered vertices of shape {tuple(original_k_minus_1.verts.shape)} "
                f"(the vertices of original_k_minus_1), found {tuple(verts.shape)}"
            )
        return SurfaceWarp(original_k_minus_1.detach(), verts.to(original_k_minus_1.verts))
    if callable(registration):
        return registration
    raise TypeError(
        f"{name}: expected None, a warp (callable), a NonRigidRegistration, a registration with 'warp' or 'verts', "
        f"or the registered mesh, found {type(registration).__name__}"
    )
