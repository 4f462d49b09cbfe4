"""Mesh container and ragged-batch packing helpers.

A :class:`Mesh` is an immutable pair ``verts (V, 3)`` float / ``faces (F, 3)`` int64. Every function of the library
that takes a mesh also takes a ``(verts, faces)`` tuple of tensors or numpy arrays and a ``trimesh.Trimesh``
(see :func:`as_mesh`). Ragged batches are packed tensors with per-item ``lengths``, as in PyTorch3D: the
items are concatenated along the first dimension and ``lengths[b]`` rows belong to item ``b``; packed faces
hold indices *local to their item's vertices*.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple, Union

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import (
    DTypeError,
    EmptyInputError,
    IndexRangeError,
    ShapeError,
    check_device,
    check_faces,
    check_finite,
    check_flag,
    check_float,
    check_float_dtype,
    check_lengths,
    check_same_device,
    check_shape,
    check_tensor,
)

if TYPE_CHECKING:
    import trimesh

# The packing and scaling helpers (batch_index, lengths_to_offsets, looks_like_pair, power_of_two_above,
# power_of_two_scale_down, vertex_set_mask) are the library's internals: importable by name, not public (they check
# nothing; a review found them in __all__, undocumented, taking out-of-range indices).
__all__ = [
    "Mesh",
    "MeshLike",
    "PackedMeshes",
    "PackedPoints",
    "as_mesh",
    "as_points",
    "bbox_diagonal",
    "is_mesh_like",
    "pack_meshes",
    "pack_points",
    "require_faces",
]


def power_of_two_above(largest: Tensor) -> Tensor:
    """Elementwise, the power of two ``2**e`` with ``largest / 2**e`` in ``[0.5, 1)`` (1 where ``largest`` is 0).

    Dividing coordinates by it is exact (only exponents change): the one way the library keeps squared lengths and
    areas of float32 coordinates from overflowing (beyond ~1e19, ~1e9 for areas) or underflowing, bit for bit the
    same figures wherever nothing overflowed. ``largest`` is detached by the caller (a constant of the inputs).

    Example:
        >>> power_of_two_above(torch.tensor([5.0, 0.3, 0.0])).tolist()
        [8.0, 0.5, 1.0]
    """
    _, exponent = torch.frexp(largest)
    return torch.ldexp(torch.ones_like(largest), exponent)


def power_of_two_scale_down(largest: Tensor) -> Tensor:
    """Elementwise ``1 / power_of_two_above(largest)``, formed directly: ``largest`` times it is in ``[0.5, 1)``.

    For float64 sums near the top of the range (statistics of values near 1.7e308, the areas of a batch's items):
    ``2**e`` itself overflows for ``largest >= 2**1023``, its reciprocal does not. Multiplying by it is exact. It is
    capped at ``2**1021`` for a subnormal ``largest`` (whose reciprocal power of two overflows), and is 1 where
    ``largest`` is 0 or not finite.

    Example:
        >>> power_of_two_scale_down(torch.tensor([5.0, 1.7e308, 0.0], dtype=torch.float64)).tolist()
        [0.125, 5.562684646268003e-309, 1.0]
    """
    _, exponent = torch.frexp(largest)
    return torch.ldexp(torch.ones_like(largest), -exponent.clamp_min(-1021))


def bbox_diagonal(points: Tensor) -> Tensor:
    """Length of the diagonal of the axis-aligned bounding box of ``(P, 3)`` points (0-dim, their dtype; 0 if none).

    The norm is taken in float64 (its squares overflow float32 beyond ~1e19 units) of the extent scaled by an exact
    power of two: unscaled, the squares overflowed float64 beyond ~1e154 and underflowed below ~1e-154, a diagonal
    of ``inf`` or 0 that every metric then refused as its PSNR peak (found by review). The same bits wherever nothing
    over- or underflowed: a power of two scales the squares, their sum and the root exactly.

    Args:
        points: ``(P, 3)`` float points (trusted: not checked).

    Returns:
        The 0-dim diagonal length, in ``points``' dtype.

    Example:
        >>> bbox_diagonal(torch.tensor([[0.0, 0.0, 0.0], [3e-200, 4e-200, 0.0]], dtype=torch.float64)).item()
        5e-200
    """
    if points.shape[0] == 0:
        return points.new_zeros(())
    extent = (points.amax(0) - points.amin(0)).to(torch.float64)
    scale = power_of_two_scale_down(extent.detach().amax())
    return (extent * scale).norm().div(scale).to(points.dtype)


def require_faces(mesh: Mesh, name: str) -> Mesh:
    """``mesh``, refused unless it has a face, under the caller's ``name`` for it (``simplified_k``, ``original_k``).

    For entry points that measure to a surface or from a vertex set: the kernels would name their own argument
    (``faces: mesh 0 has no faces but 162 query points``, the same words for four different frames; found by review).

    Args:
        mesh: the mesh.
        name: the caller's name for it, in the error.

    Returns:
        ``mesh`` itself.

    Raises:
        EmptyInputError: ``mesh`` has no face.

    Example:
        >>> require_faces(Mesh(torch.zeros(3, 3), torch.tensor([[0, 1, 2]])), "simplified_k").num_faces
        1
    """
    if mesh.num_faces == 0:
        raise EmptyInputError(f"{name}: expected a mesh with at least one face, found none")
    return mesh


def vertex_set_mask(faces: Tensor, num_verts: int) -> Tensor:
    """``(V,)`` bool: the vertices some face references, the paper's vertex set (Eq. 3).

    Args:
        faces: ``(F, 3)`` int64 vertex indices (possibly of a packed batch).
        num_verts: ``V``, the number of vertices the indices refer to.

    Example:
        >>> import torch
        >>> vertex_set_mask(torch.tensor([[0, 1, 2]]), 4).tolist()
        [True, True, True, False]
    """
    used = torch.zeros(num_verts, dtype=torch.bool, device=faces.device)
    used[faces.reshape(-1)] = True
    return used


@dataclass(frozen=True, eq=False)
class Mesh:
    """An immutable triangle mesh.

    Args:
        verts: ``(V, 3)`` floating-point vertex positions.
        faces: ``(F, 3)`` integer vertex indices (converted to ``int64``).
        validate: check shapes, dtypes, finiteness and index range (default ``True``).

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError: on malformed input.

    Derived per-face and per-vertex quantities (:meth:`face_areas`, :meth:`face_normals`, :meth:`vertex_normals`,
    :meth:`surface_face_mask`, :meth:`surface_vertex_mask`, :meth:`referenced_vertex_mask`) are computed from one pass
    of face cross products and cached on the mesh, like trimesh's ``face_normals``, under one rule: a value is reused
    only while ``verts`` does not require grad and neither ``verts``, ``faces`` nor the returned tensor was modified in
    place (torch's version counters tell). When ``verts`` requires grad every call computes afresh, so each loss gets
    its own autograd graph and no graph is kept alive by the mesh. Treat the returned tensors as read-only.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> m = Mesh(torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> m.num_verts, m.num_faces
        (3, 1)
        >>> m.face_normals(), m.face_areas()
        (tensor([[0., 0., 1.]]), tensor([0.5000]))
    """

    verts: Tensor
    faces: Tensor
    _derived: dict[str, tuple[tuple[int, ...], Tensor]] = field(init=False, repr=False, compare=False)

    def __init__(self, verts: Tensor, faces: Tensor, *, validate: bool = True) -> None:
        validate = check_flag(validate, "validate")
        if validate:
            check_shape(verts, ("V", 3), "verts")
            check_float(verts, "verts")
            check_finite(verts, "verts")
            check_faces(faces, verts.shape[0], "faces")
            check_same_device({"verts": verts, "faces": faces})
        object.__setattr__(self, "verts", verts)
        object.__setattr__(self, "faces", faces.long())
        object.__setattr__(self, "_derived", {})

    def __getstate__(self) -> dict[str, Tensor]:
        return {"verts": self.verts, "faces": self.faces}  # derived values are recomputed, not shipped

    def __setstate__(self, state: dict[str, Tensor]) -> None:
        object.__setattr__(self, "verts", state["verts"])
        object.__setattr__(self, "faces", state["faces"])
        object.__setattr__(self, "_derived", {})

    @property
    def num_verts(self) -> int:
        """Number of vertices ``V``."""
        return int(self.verts.shape[0])

    @property
    def num_faces(self) -> int:
        """Number of faces ``F``."""
        return int(self.faces.shape[0])

    @property
    def device(self) -> torch.device:
        """Device of the vertex tensor."""
        return self.verts.device

    @property
    def dtype(self) -> torch.dtype:
        """Floating-point dtype of the vertices."""
        return self.verts.dtype

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None) -> Mesh:
        """Return a copy on another device and/or with another vertex dtype (torch.float32 or torch.float64).

        Raises:
            DTypeError: ``dtype`` is another dtype (a half-precision or integer mesh is refused by every check).
            DeviceError: ``device`` is no device, is unavailable, or is ``meta`` (no values).
        """
        if dtype is not None:
            check_float_dtype(dtype)
        if device is not None:
            device = check_device(device)
        return Mesh(self.verts.to(device=device, dtype=dtype), self.faces.to(device=device), validate=False)

    def detach(self) -> Mesh:
        """Return the mesh with vertices detached from the autograd graph (the mesh itself when there is no graph).

        Vertices that do not require grad are kept, the very tensor: a detached alias would be a new tensor object at
        every call, which an :class:`~torchmeshmetric.IndexCache` cannot recognise without hashing the mesh again
        (the losses detach their references at every step).
        """
        return Mesh(self.verts.detach(), self.faces, validate=False) if self.verts.requires_grad else self

    def bbox_diagonal(self) -> Tensor:
        """Length of the diagonal of the axis-aligned bounding box of the referenced vertices (0-dim tensor)."""
        return bbox_diagonal(self.verts[self.referenced_vertex_mask()] if self.num_faces else self.verts)

    def _cached(self, name: str, compute: Callable[[], Tensor]) -> Tensor:
        """``compute()``, reused while the mesh's tensors and the value are unchanged (see the class docstring)."""
        verts, faces = self.verts, self.faces
        if verts.requires_grad or verts.is_inference() or faces.is_inference():
            return compute()  # a fresh autograd graph per call; inference tensors have no version counter
        stamp = (verts._version, faces._version)
        hit = self._derived.get(name)
        if hit is not None and hit[0] == (*stamp, hit[1]._version):
            return hit[1]
        value = compute()
        self._derived[name] = ((*stamp, value._version), value)
        return value

    def _face_cross(self) -> Tensor:
        """``(F, 3)`` cross products of two edges of each face: twice the area times the unit normal."""

        def compute() -> Tensor:
            tri = self.verts[self.faces]
            return torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)

        return self._cached("face_cross", compute)

    def _face_cross_norm(self) -> Tensor:
        """``(F, 1)`` norms of :meth:`_face_cross` (twice the areas)."""
        return self._cached("face_cross_norm", lambda: self._face_cross().norm(dim=-1, keepdim=True))

    def face_areas(self) -> Tensor:
        """``(F,)`` triangle areas (cached, see the class docstring)."""
        return self._cached("face_areas", lambda: 0.5 * self._face_cross_norm()[:, 0])

    def _normal_cross(self) -> Tensor:
        """``(F, 3)`` :meth:`_face_cross` of the edges divided by a power of two near the longest edge component.

        The directions the normals need, without overflow: float32 squared areas overflowed for coordinates beyond
        ~1e9 (and underflowed below ~1e-9), so every normal came out 0 (found by review: ``carry_onto`` then fell back
        to closest points). The division is exact, so the normals are the same bits wherever nothing overflowed.
        """

        def compute() -> Tensor:
            tri = self.verts[self.faces]
            e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
            largest = torch.maximum(e1.detach().abs().amax(), e2.detach().abs().amax()) if len(tri) else tri.sum()
            unit = power_of_two_above(largest)
            return torch.linalg.cross(e1 / unit, e2 / unit, dim=-1)

        return self._cached("normal_cross", compute)

    def face_normals(self) -> Tensor:
        """``(F, 3)`` unit face normals (right-hand rule); exactly zero for zero-area faces, which have none."""

        def compute() -> Tensor:
            n = self._normal_cross()
            return _unit(n, n.norm(dim=-1, keepdim=True))

        return self._cached("face_normals", compute)

    def vertex_normals(self) -> Tensor:
        """``(V, 3)`` area-weighted unit vertex normals; exactly zero where no face of positive area touches."""

        def compute() -> Tensor:
            n, f = self._normal_cross(), self.faces
            acc = torch.zeros_like(self.verts).index_add(0, f[:, 0], n).index_add(0, f[:, 1], n)
            acc = acc.index_add(0, f[:, 2], n)
            return _unit(acc, acc.norm(dim=-1, keepdim=True))

        return self._cached("vertex_normals", compute)

    def surface_face_mask(self) -> Tensor:
        """``(F,)`` bool: the faces whose normal is set by their vertices, not by rounding.

        A face counts when twice its area exceeds 64 times the rounding error of computing it from its coordinates
        (``eps * max|coordinate| * longest edge``): captured frames hold zero-area faces (collinear corners, a
        zero-length edge) whose computed area is 0 or rounding noise depending on the last bits of the input, and
        whose normal then points anywhere. Their vertices must not enter or leave a selection under a change of one
        ulp (measured: a midpoint vertex moving in and out of the registration's data points moved the registered
        vertices of a captured-like pair by 1.6e-4 of the diagonal under one ulp).
        """

        def compute() -> Tensor:
            a, b, c = (self.verts.index_select(0, self.faces[:, i]) for i in range(3))
            longest2 = torch.stack([(b - a).square().sum(1), (c - b).square().sum(1), (a - c).square().sum(1)])
            scale = torch.stack([a.abs().amax(1), b.abs().amax(1), c.abs().amax(1)]).amax(0)
            noise = 64.0 * torch.finfo(self.verts.dtype).eps * scale * longest2.amax(0).sqrt()
            return self._face_cross_norm()[:, 0] > noise

        return self._cached("surface_face_mask", compute)

    def surface_vertex_mask(self) -> Tensor:
        """``(V,)`` bool: the vertices of at least one face with a normal (:meth:`surface_face_mask`).

        Captured frames hold unreferenced vertices and zero-area faces; these are the vertices that lie on the surface
        proper (the registration samples them, :meth:`referenced_vertex_mask` keeps any face's vertices).
        """

        def compute() -> Tensor:
            used = torch.zeros(self.num_verts, dtype=torch.bool, device=self.device)
            used[self.faces[self.surface_face_mask()].reshape(-1)] = True
            return used

        return self._cached("surface_vertex_mask", compute)

    def referenced_vertex_mask(self) -> Tensor:
        """``(V,)`` bool: the vertices referenced by at least one face (the paper's vertex set, Eq. 3)."""
        return self._cached("referenced_vertex_mask", lambda: vertex_set_mask(self.faces, self.num_verts))

    def to_trimesh(self) -> trimesh.Trimesh:
        """Convert to a ``trimesh.Trimesh`` (``process=False`` keeps vertex order)."""
        import trimesh  # here, not with the package: importing trimesh alone takes ~0.15 s

        return trimesh.Trimesh(self.verts.detach().cpu().double().numpy(), self.faces.cpu().numpy(), process=False)

    def __repr__(self) -> str:
        return f"Mesh(num_verts={self.num_verts}, num_faces={self.num_faces}, dtype={self.dtype}, device={self.device})"


def _unit(x: Tensor, norm: Tensor) -> Tensor:
    """Rows of ``x`` divided by their ``norm`` ``(N, 1)``; exactly zero where the norm is zero."""
    return torch.where(norm > 0, x / torch.where(norm > 0, norm, torch.ones_like(norm)), torch.zeros_like(x))


MeshLike = Union[Mesh, tuple[Any, Any], "trimesh.Trimesh"]
"""A :class:`Mesh`, a ``(verts, faces)`` tuple of tensors or arrays, or a ``trimesh.Trimesh``."""


def _to_tensor(x: Any, name: str, *, device: torch.device | str | None, dtype: torch.dtype | None) -> Tensor:
    if isinstance(x, Tensor):
        t = x
    elif isinstance(x, np.ndarray):
        t = torch.from_numpy(np.ascontiguousarray(x))
    else:
        try:
            t = torch.as_tensor(np.asarray(x))
        except Exception as err:
            raise TypeError(f"{name}: expected a tensor or array, found {type(x).__name__}") from err
    if dtype is not None or device is not None:
        t = t.to(device=device, dtype=dtype)
    return t


def as_mesh(
    mesh: MeshLike,
    *,
    name: str = "mesh",
    device: torch.device | str | None = None,
    dtype: torch.dtype | None = None,
) -> Mesh:
    """Convert any accepted mesh form into a validated :class:`Mesh`.

    Args:
        mesh: a :class:`Mesh`, a ``(verts, faces)`` tuple of tensors/arrays, or a ``trimesh.Trimesh``.
        name: argument name used in error messages.
        device: optional target device.
        dtype: optional vertex dtype, torch.float32 or torch.float64. numpy ``float64`` arrays stay ``float64``
            unless given.

    Returns:
        The validated mesh (the same object when no conversion is needed).

    Raises:
        TypeError: ``mesh`` has none of the accepted forms.
        DTypeError: ``dtype`` is neither torch.float32 nor torch.float64; a 2-tuple whose second tensor is not
            integer faces (floating point: the message says that the tuple was read as ``(verts, faces)`` and that a
            batch of point sets is a list).

    Example:
        >>> import trimesh
        >>> as_mesh(trimesh.creation.box()).num_faces
        12
    """
    if device is not None:
        device = check_device(device)
    if dtype is not None:
        check_float_dtype(dtype)
    if isinstance(mesh, Mesh):
        if device is None and dtype is None:
            return mesh
        return mesh.to(device=device, dtype=dtype)
    if isinstance(mesh, tuple) and len(mesh) == 2:
        verts = _to_tensor(mesh[0], f"{name}.verts", device=device, dtype=dtype)
        faces = _to_tensor(mesh[1], f"{name}.faces", device=device if device is not None else verts.device, dtype=None)
        try:
            return _named_mesh(verts, faces, name)
        except DTypeError as err:
            if not faces.is_floating_point():
                raise
            # Floating-point "faces" are often a second point set: the collate tuple(zip(*batch)) makes (a, b) of a
            # batch of two. Not taken as one (it may be faces loaded as floats): the message says how it was read.
            raise DTypeError(
                f"{err}; {name} is a 2-tuple, read as one (verts, faces) mesh: give a batch of point sets as a "
                f"list, {name}=[a, b] (list() of a collated tuple)"
            ) from None
    if type(mesh).__name__ == "Trimesh" and hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        verts = torch.from_numpy(np.asarray(mesh.vertices, dtype=np.float64).copy()).to(device=device, dtype=dtype)
        faces = torch.from_numpy(np.asarray(mesh.faces, dtype=np.int64).copy()).to(device=verts.device)
        return _named_mesh(verts, faces, name)
    raise TypeError(
        f"{name}: expected a Mesh, a (verts, faces) tuple or a trimesh.Trimesh, found {type(mesh).__name__}"
    )


def _named_mesh(verts: Tensor, faces: Tensor, name: str) -> Mesh:
    check_shape(verts, ("V", 3), f"{name}.verts")
    check_float(verts, f"{name}.verts")
    check_finite(verts, f"{name}.verts")
    check_faces(faces, verts.shape[0], f"{name}.faces")
    return Mesh(verts, faces, validate=False)


def as_points(points: Any, name: str = "points") -> Tensor:
    """Validate a ``(P, 3)`` floating-point, finite point tensor (numpy arrays are converted).

    Args:
        points: ``(P, 3)`` float32 or float64 points, a tensor or a numpy array.
        name: the argument's name in error messages.

    Returns:
        The points as a tensor (the same tensor when one was given).

    Raises:
        ShapeError, DTypeError, NonFiniteError: not ``(P, 3)``, not float32/float64, or not finite.

    Example:
        >>> import numpy as np
        >>> as_points(np.zeros((2, 3))).dtype
        torch.float64
    """
    t = _to_tensor(points, name, device=None, dtype=None)
    check_shape(t, ("P", 3), name)
    check_float(t, name)
    check_finite(t, name)
    return t


class PackedPoints(NamedTuple):
    """Ragged batch of point sets: ``points (sum P_b, 3)`` and ``lengths (B,)``."""

    points: Tensor
    lengths: Tensor


class PackedMeshes(NamedTuple):
    """Ragged batch of meshes: packed ``verts``/``faces`` (faces local to their item) and per-item lengths."""

    verts: Tensor
    faces: Tensor
    verts_lengths: Tensor
    faces_lengths: Tensor


def lengths_to_offsets(lengths: Tensor) -> Tensor:
    """``(B,)`` lengths → ``(B + 1,)`` offsets ``[0, l0, l0 + l1, ...]``."""
    return torch.cat([lengths.new_zeros(1), lengths.cumsum(0)])


def batch_index(lengths: Tensor, total: int | None = None) -> Tensor:
    """``(B,)`` lengths → ``(sum lengths,)`` item index of every packed row.

    ``total`` (``sum lengths``, when the caller knows it from a shape) spares a device-to-host read of the sum on
    CUDA (``repeat_interleave``'s ``output_size``).
    """
    return torch.repeat_interleave(torch.arange(lengths.numel(), device=lengths.device), lengths, output_size=total)


def pack_points(points: Sequence[Any] | Tensor, lengths: Tensor | None = None, name: str = "points") -> PackedPoints:
    """Pack a list of ``(P_b, 3)`` point sets (or validate an already packed tensor with ``lengths``).

    A single ``(P, 3)`` tensor without ``lengths`` is a batch of one.

    Args:
        points: a ``(P, 3)`` float tensor (packed, with ``lengths``), or a list of ``(P_b, 3)`` tensors or
            mesh-likes (a mesh stands for its vertex set).
        lengths: ``(B,)`` integer points per item of a packed ``points`` (summing to ``P``).
        name: the argument's name in error messages.

    Returns:
        :class:`PackedPoints` ``(points (sum P_b, 3), lengths (B,))``.

    Raises:
        ShapeError, DTypeError, NonFiniteError: a point set is not ``(P, 3)`` finite floats; ``lengths`` does not
            sum to ``P``.
        TypeError: ``points`` is neither a tensor nor a list (a numpy array: convert it), or ``lengths`` is no
            tensor.

    Example:
        >>> p = pack_points([torch.zeros(2, 3), torch.ones(3, 3)])
        >>> p.points.shape, p.lengths.tolist()
        (torch.Size([5, 3]), [2, 3])
    """
    if isinstance(points, Tensor):
        pts = as_points(points, name)
        if lengths is None:  # a batch of one: its lengths are right by construction
            return PackedPoints(pts, torch.tensor([pts.shape[0]], device=pts.device))
        # checked before the cast: a list failed in .to(), float lengths were truncated (found by review)
        check_lengths(lengths, pts.shape[0], f"{name}_lengths")
        return PackedPoints(pts, lengths.to(device=pts.device, dtype=torch.long))
    if not isinstance(points, Sequence):
        # A numpy array was iterated as a list of point sets, one per row ("points[0]: expected shape (P, 3)").
        check_tensor(points, name, "a (P, 3) torch.Tensor or a list of them")
    if lengths is not None:
        raise TypeError(
            f"{name}_lengths: only valid with a packed tensor, found a {type(points).__name__} of point sets"
        )
    items = [as_points(p, f"{name}[{i}]") for i, p in enumerate(points)]
    if not items:
        raise ValueError(f"{name}: expected at least one point set, found an empty list")
    check_same_device({f"{name}[{i}]": p for i, p in enumerate(items)})
    dtype = items[0].dtype
    for p in items[1:]:
        dtype = torch.promote_types(dtype, p.dtype)
    lengths_t = torch.tensor([p.shape[0] for p in items], device=items[0].device)
    return PackedPoints(torch.cat([p.to(dtype) for p in items]), lengths_t)


def pack_meshes(
    meshes: Sequence[MeshLike] | MeshLike | Tensor,
    faces: Tensor | None = None,
    verts_lengths: Tensor | None = None,
    faces_lengths: Tensor | None = None,
    name: str = "mesh",
) -> PackedMeshes:
    """Pack meshes into one ragged batch.

    Accepts a single mesh-like, a list of mesh-likes, or already packed ``verts``/``faces`` tensors with
    ``verts_lengths``/``faces_lengths`` (both omitted means a batch of one).

    Args:
        meshes: a mesh-like (:class:`Mesh`, ``(verts, faces)`` tuple, ``trimesh.Trimesh``), a list of them, or
            packed ``(sum V_b, 3)`` vertices with ``faces``.
        faces: packed ``(sum F_b, 3)`` integer faces, local to their item, when ``meshes`` is a tensor.
        verts_lengths: ``(B,)`` vertices per item of packed tensors (with ``faces_lengths``).
        faces_lengths: ``(B,)`` faces per item of packed tensors.
        name: the argument's name in error messages.

    Returns:
        :class:`PackedMeshes` ``(verts (sum V_b, 3), faces (sum F_b, 3) int64, verts_lengths (B,),
        faces_lengths (B,))``; faces stay local to their item.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError: a bad mesh, lengths that do not sum to the rows,
            or a face indexing outside its item.
        TypeError: packed vertices without faces, or only one of the two lengths.

    Example:
        >>> import trimesh
        >>> b = pack_meshes([trimesh.creation.icosphere(subdivisions=0), trimesh.creation.box()])
        >>> b.verts.shape, b.verts_lengths.tolist(), b.faces_lengths.tolist()
        (torch.Size([20, 3]), [12, 8], [20, 12])
    """
    if isinstance(meshes, Tensor):
        if faces is None:
            raise TypeError(f"{name}: verts given as a tensor, so faces must be given too")
        verts = meshes
        check_shape(verts, ("V", 3), "verts")
        check_float(verts, "verts")
        check_finite(verts, "verts")
        check_shape(faces, ("F", 3), "faces")
        check_same_device({"verts": verts, "faces": faces})
        if (verts_lengths is None) != (faces_lengths is None):
            raise TypeError("verts_lengths and faces_lengths must be given together")
        if verts_lengths is None or faces_lengths is None:
            check_faces(faces, verts.shape[0], "faces")
            dev = verts.device
            return PackedMeshes(
                verts,
                faces.long(),
                torch.tensor([verts.shape[0]], device=dev),
                torch.tensor([faces.shape[0]], device=dev),
            )
        check_lengths(verts_lengths, verts.shape[0], "verts_lengths")  # before the cast, as in pack_points
        check_lengths(faces_lengths, faces.shape[0], "faces_lengths")
        vl = verts_lengths.to(device=verts.device, dtype=torch.long)
        fl = faces_lengths.to(device=verts.device, dtype=torch.long)
        if vl.numel() != fl.numel():
            raise ShapeError(
                f"verts_lengths/faces_lengths: expected the same batch size, found {vl.numel()} and {fl.numel()}"
            )
        faces = faces.long()
        if faces.numel():
            per_face_nv = vl[batch_index(fl)]
            bad = (faces < 0).any(1) | (faces >= per_face_nv[:, None]).any(1)
            if bool(bad.any()):
                first = int(bad.nonzero()[0, 0])
                raise IndexRangeError(
                    f"faces: expected indices local to each item's vertices, in [0, {int(per_face_nv[first]) - 1}] "
                    f"for packed face {first}, found {faces[first].tolist()}"
                )
        return PackedMeshes(verts, faces, vl, fl)
    if faces is not None:
        # verts and faces are two arguments only as tensors (numpy verts said "faces: only valid when verts is ...").
        check_tensor(meshes, "verts", "a (V, 3) torch.Tensor when faces is given")
        raise TypeError("faces: only valid when verts is a tensor")
    if isinstance(meshes, (list, tuple)) and not (isinstance(meshes, tuple) and looks_like_pair(meshes)):
        items = [as_mesh(m, name=f"{name}[{i}]") for i, m in enumerate(meshes)]
        if not items:
            raise ValueError(f"{name}: expected at least one mesh, found an empty list")
    else:
        items = [as_mesh(meshes, name=name)]  # type: ignore[arg-type]
    check_same_device({f"{name}[{i}]": m.verts for i, m in enumerate(items)})
    dtype = items[0].dtype
    for m in items[1:]:
        dtype = torch.promote_types(dtype, m.dtype)
    dev = items[0].device
    return PackedMeshes(
        torch.cat([m.verts.to(dtype) for m in items]),
        torch.cat([m.faces for m in items]),
        torch.tensor([m.num_verts for m in items], device=dev),
        torch.tensor([m.num_faces for m in items], device=dev),
    )


def looks_like_pair(t: tuple[Any, ...]) -> bool:
    """A 2-tuple whose items are arrays/tensors is a ``(verts, faces)`` mesh, not a list of two meshes."""
    return len(t) == 2 and all(isinstance(x, (Tensor, np.ndarray)) for x in t)


def is_mesh_like(x: Any) -> bool:
    """Whether ``x`` is one mesh: a :class:`Mesh`, a ``(verts, faces)`` pair of arrays/tensors, a ``trimesh.Trimesh``.

    Args:
        x: anything.

    Returns:
        ``True`` for one mesh; ``False`` for a list of meshes, a point set or anything else.

    Example:
        >>> import torch
        >>> is_mesh_like((torch.zeros(3, 3), torch.tensor([[0, 1, 2]]))), is_mesh_like([torch.zeros(3, 3)])
        (True, False)
    """
    if isinstance(x, Mesh):
        return True
    if isinstance(x, tuple) and looks_like_pair(x):
        return True
    return type(x).__name__ == "Trimesh"
