"""``MeshIndex``: a mesh (or a batch of meshes) prepared once for many exact distance queries.

:func:`~torchmeshmetric.point_mesh_distance` and :func:`~torchmeshmetric.nearest_vertex_distance` build a selection
structure (a BVH on the CPU) for every call. Registration, ``compare`` and training loops query the *same* mesh
many times: an index validates and centres the mesh once, builds each structure on its first query and keeps it;
:meth:`MeshIndex.refit` moves the vertices (same faces) by refitting the bounds instead of rebuilding. Answers and
gradients are those of the functions, bit for bit where no range scaling is involved (the functions are implemented
on this class; at extreme magnitudes the functions also scale for their far query points, see :class:`MeshIndex`).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import (
    DeviceError,
    DTypeError,
    StaleIndexError,
    check_finite,
    check_flag,
    check_float,
    check_index_dtype,
    check_shape,
)
from torchmeshmetric.kernels._common import (
    DEFAULT_MAX_MEMORY,
    centred,
    check_max_memory,
    check_queries,
    check_representable,
    in_own_frame,
    item_rows,
    merge_rows,
    range_scale,
    referenced_rows,
    rows_of,
    safe_sqrt,
)
from torchmeshmetric.kernels.accel.bvh import bvh_closest_points
from torchmeshmetric.kernels.contract import FaceSet
from torchmeshmetric.kernels.nearest import NearestVertexResult, _NearestIndex
from torchmeshmetric.kernels.sampling import vertex_set_mask
from torchmeshmetric.kernels.select import Selector, check_backend
from torchmeshmetric.kernels.triangle import closest_point_on_triangle_unchecked
from torchmeshmetric.structures import (
    Mesh,
    MeshLike,
    PackedMeshes,
    PackedPoints,
    batch_index,
    lengths_to_offsets,
    looks_like_pair,
    pack_meshes,
    pack_points,
)

__all__ = ["MeshIndex", "PointMeshResult", "measure_once"]


class PointMeshResult(NamedTuple):
    """Result of :func:`point_mesh_distance`.

    Attributes:
        dists: ``(P,)`` Euclidean distance (**not squared**) from each point to the mesh surface.
        face_idx: ``(P,)`` int64 index of the closest face, a row of the (packed) ``faces`` tensor.
        bary: ``(P, 3)`` barycentric coordinates of the closest point on that face.
        closest: ``(P, 3)`` the closest point on the surface.

    Example:
        >>> import torch
        >>> from torchmeshmetric import point_mesh_distance
        >>> triangle = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> r = point_mesh_distance(torch.tensor([[0.25, 0.25, 1.0]]), triangle)
        >>> r.dists.tolist(), r.face_idx.tolist(), r.bary.tolist(), r.closest.tolist()
        ([1.0], [0], [[0.5, 0.25, 0.25]], [[0.25, 0.25, 0.0]])
    """

    dists: Tensor
    face_idx: Tensor
    bary: Tensor
    closest: Tensor


class _CentredHit(NamedTuple):
    """A closest-face query in the frame the kernels computed it in (:meth:`MeshIndex.point_mesh_distance_centred`).

    Attributes:
        result: distances, faces, barycentrics and closest points of the centred, scaled points.
        points_c: ``(P, 3)`` the centred, scaled points.
        point_batch: ``(P,)`` item of each point.
        point_center: ``(1 or P, 3)`` the centre subtracted from each point.
        scale: the index's power-of-two scale, ``None`` for 1.
    """

    result: PointMeshResult
    points_c: Tensor
    point_batch: Tensor
    point_center: Tensor
    scale: float | None


_Source = tuple[str, Tensor, int]
"""A tensor an index was built from: the name its errors give it, the tensor, its version counter then."""


def _version(t: Tensor) -> int:
    """``t``'s in-place version counter; -1 for inference tensors (none: they change only in inference mode)."""
    return -1 if t.is_inference() else t._version


def _sources(named: Sequence[tuple[str, Any]]) -> tuple[_Source, ...]:
    """The tensors among ``named`` with their versions now, each tensor once (numpy arrays were copied: no watch)."""
    out: list[_Source] = []
    for name, t in named:
        if isinstance(t, Tensor) and not any(t is s[1] for s in out):
            out.append((name, t, _version(t)))
    return tuple(out)


def _given_tensors(mesh: Any, faces: Tensor | None, prefix: str = "mesh") -> tuple[list[tuple[str, Any]], ...]:
    """The caller's own vertex and face tensors in the mesh arguments of :class:`MeshIndex`, with their names."""
    if isinstance(mesh, Tensor):
        return [("verts", mesh)], [("faces", faces)]
    if isinstance(mesh, Mesh):
        return [(f"{prefix}.verts", mesh.verts)], [(f"{prefix}.faces", mesh.faces)]
    if isinstance(mesh, tuple) and looks_like_pair(mesh):
        return [(f"{prefix}.verts", mesh[0])], [(f"{prefix}.faces", mesh[1])]
    if isinstance(mesh, (list, tuple)):
        verts: list[tuple[str, Any]] = []
        faces_: list[tuple[str, Any]] = []
        for i, m in enumerate(mesh):
            v, f = _given_tensors(m, None, f"{prefix}[{i}]")
            verts += v
            faces_ += f
        return verts, faces_
    return [], []  # a trimesh: converted by copy, nothing of the caller's is kept


def pack_mesh_args(
    mesh: MeshLike | Sequence[MeshLike] | Tensor,
    faces: Tensor | None,
    verts_lengths: Tensor | None,
    faces_lengths: Tensor | None,
) -> PackedMeshes:
    """The mesh arguments of :class:`MeshIndex` and :func:`~torchmeshmetric.point_mesh_distance`, packed and checked.

    Raises:
        TypeError: for lengths given with mesh-likes (they carry their own sizes).
    """
    if isinstance(mesh, Tensor):
        return pack_meshes(mesh, faces, verts_lengths, faces_lengths)
    if verts_lengths is not None or faces_lengths is not None:
        raise TypeError("verts_lengths/faces_lengths: only valid with packed verts/faces tensors")
    return pack_meshes(mesh, faces)


class MeshIndex:
    """A triangle mesh (or a ragged batch of meshes) prepared once for many exact distance queries.

    Validates and centres the mesh once (on the bounding box of the vertices its faces reference: an unreferenced
    vertex changes no answer); the selection structure of each query kind (closest face, nearest vertex)
    is built on its first query and kept (CPU: the C++ BVH; CUDA: the Triton implicit BVH, or the pruned scan
    without Triton; see ``docs/acceleration.md``). :meth:`point_mesh_distance` and :meth:`nearest_vertex_distance`
    return what the functions of the same names return for this mesh, bit for bit, with the same gradients
    (to the points, and to the mesh vertices through the same recomputation on the selected face), except at
    extreme magnitudes: the index scales coordinates by a power of two chosen from its mesh alone; the functions
    measure the points that scale covers in the same frame and only the others (far from a small mesh) in a frame
    scaled for them too (a single nearest-vertex set: unscaled where its squares are in range), so for point sets of
    size ~1e-15 (float32) the last bits may differ, and a point whose squared distance overflows the index's frame
    raises :class:`~torchmeshmetric.NonFiniteError` where the function measures it.
    :meth:`refit` moves the vertices (same faces): bounds are refitted, not rebuilt (a tree worn by large
    deformations is rebuilt: :data:`~torchmeshmetric.kernels.select.REBUILD_AREA_GROWTH`), and answers stay exact.

    The index keeps the tensors it was built from (no copy: gradients reach them, e.g. an ``nn.Parameter``) and
    their in-place version counters. Once one of them changes in place (``verts.add_(...)``, ``optimizer.step()``)
    every query raises :class:`~torchmeshmetric.StaleIndexError` naming it, whatever the form the index was built from,
    until :meth:`refit` (moved vertices; changed faces need a new index). Writes torch does not count (``.data``, a
    shared numpy array, ``fused=True`` optimizers) are not seen: refit after them (``docs/kernels.md``).

    Args:
        mesh: a mesh-like, a list of mesh-likes (a ragged batch), or packed ``(V, 3)`` vertices with ``faces``.
        faces: ``(F, 3)`` faces when ``mesh`` is a vertex tensor.
        verts_lengths: ``(B,)`` vertices per item of packed vertices.
        faces_lengths: ``(B,)`` faces per item of packed faces (local indices).
        backend: ``"auto"``, ``"bvh"``, ``"triton"``, ``"pruned"`` or ``"bruteforce"``.
        max_memory: bound in bytes of one intermediate of the ``"bruteforce"`` / ``"pruned"`` backends.
        referenced_only: the reference of :meth:`nearest_vertex_distance` is the vertex set of the paper (Eq. 3,
            vertices referenced by a face: :func:`~torchmeshmetric.vertex_set`); ``False``: every vertex.
        tree: closest-face hierarchy of the ``"bvh"`` backend: ``"sah"`` (binned surface-area heuristic: queries
            ~25 % faster, build ~10x the Morton build; for many queries) or ``"morton"`` (the functions' cheap build:
            for a few queries). Answers are identical.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError: on a malformed mesh.
        ValueError: on an unknown backend.
        StaleIndexError: (on a query) a tensor the index was built from changed in place since.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import point_mesh_distance
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> index = MeshIndex(sphere)
        >>> p = torch.tensor([[0.0, 0.0, 3.0]], dtype=torch.float64)
        >>> round(index.point_mesh_distance(p).dists.item(), 6)
        2.0
        >>> bool(index.point_mesh_distance(p).dists == point_mesh_distance(p, sphere).dists)
        True
        >>> index.refit(index.verts * 2)  # same faces, moved vertices
        >>> round(index.point_mesh_distance(p).dists.item(), 6)
        1.0
    """

    def __init__(
        self,
        mesh: MeshLike | Sequence[MeshLike] | Tensor,
        faces: Tensor | None = None,
        *,
        verts_lengths: Tensor | None = None,
        faces_lengths: Tensor | None = None,
        backend: str = "auto",
        max_memory: int = DEFAULT_MAX_MEMORY,
        referenced_only: bool = True,
        tree: str = "sah",
    ) -> None:
        referenced_only = check_flag(referenced_only, "referenced_only")
        packed = pack_mesh_args(mesh, faces, verts_lengths, faces_lengths)
        self._init(packed, backend, max_memory, referenced_only, tree)
        given_verts, given_faces = _given_tensors(mesh, faces)
        self._verts_sources = _sources([*given_verts, ("verts", self.verts)])
        self._faces_sources = _sources(
            [*given_faces, ("faces", self.faces), ("verts_lengths", verts_lengths), ("faces_lengths", faces_lengths)]
        )

    @classmethod
    def from_packed(
        cls,
        packed: PackedMeshes,
        backend: str,
        max_memory: int,
        tree: str = "morton",
        *,
        queries: PackedPoints | None = None,
    ) -> MeshIndex:
        """An index over packed meshes that the caller has already validated: no check is repeated.

        The entry of the library's own loops (the registration validates its two meshes once, not at each of its
        searches). Give it only what :class:`MeshIndex` itself would accept: finite vertices, faces in range.

        Args:
            packed: the packed meshes (:func:`~torchmeshmetric.pack_meshes`).
            backend: a backend name (``"bvh"``, ``"pruned"``, ...).
            max_memory: the bytes a chunked backend may use.
            tree: ``"morton"`` or ``"sah"``.
            queries: the packed points of a one-off index's single query (validated, in the index's dtype): the
                exact power-of-two scaling then covers them too, as :func:`~torchmeshmetric.nearest_vertex_distance`
                does, so that points far from a tiny mesh are measured, not refused (their distances are
                representable; with a scale taken from the mesh alone their squares overflow).

        Returns:
            The index; it watches ``packed``'s tensors as :class:`MeshIndex` does.
        """
        index = cls.__new__(cls)
        index._init(packed, backend, max_memory, True, tree, queries)
        return index

    def _init(
        self,
        packed: PackedMeshes,
        backend: str,
        max_memory: int,
        referenced_only: bool,
        tree: str,
        queries: PackedPoints | None = None,
    ) -> None:
        check_backend(backend)
        max_memory = check_max_memory(max_memory)
        if tree not in ("sah", "morton"):
            raise ValueError(f"tree: expected 'sah' or 'morton', found {tree!r}")
        self.backend, self.max_memory, self.referenced_only, self.tree = backend, max_memory, referenced_only, tree
        self.faces = packed.faces
        self.verts_lengths, self.faces_lengths = packed.verts_lengths, packed.faces_lengths
        num_items = int(packed.verts_lengths.numel())
        if num_items == 1:
            self._faces_global = packed.faces
            self._face_batch = torch.zeros(packed.faces.shape[0], dtype=torch.long, device=packed.faces.device)
        else:
            self._face_batch = batch_index(packed.faces_lengths)
            v_off = lengths_to_offsets(packed.verts_lengths)
            self._faces_global = packed.faces + v_off[self._face_batch][:, None]
        self._face_offsets = lengths_to_offsets(packed.faces_lengths)
        self._faces: Selector | None = None
        self._nearest: _NearestIndex | None = None
        self._origin: MeshIndex | None = None  # the index a `with_verts` copy shares its structures with
        self._faces_everywhere: bool | None = None  # every item has faces (read once, at the first query)
        # The rows the centre and scale come from (None: all), once: refits keep the faces, so they keep the rows.
        self._centre_rows = referenced_rows(self._faces_global, int(packed.verts.shape[0]))
        self._set_verts(packed.verts, queries)
        self._verts_sources = _sources([("verts", packed.verts)])
        self._faces_sources = _sources([("faces", packed.faces)])

    def _check_current(self) -> None:
        """Refuse to answer for a mesh that is gone: a tensor the index was built from changed in place since.

        Costs a few version-counter reads per query; no copy of the mesh is kept or compared.

        Raises:
            StaleIndexError: naming the tensor, with what to do (refit for vertices, a new index for faces).
        """
        for sources, remedy in (
            (
                self._verts_sources,
                "refit the index (index.refit(verts)) after changing its vertices, e.g. after "
                "every optimizer.step() on them",
            ),
            (
                self._faces_sources,
                "the faces of an index cannot change (refit moves vertices only): build a new MeshIndex",
            ),
        ):
            for name, t, version in sources:
                if _version(t) != version:
                    raise StaleIndexError(
                        f"{name}: modified in place since the index was built or last refitted (version "
                        f"{version}, now {_version(t)}), so the index would answer for a mesh that is gone; {remedy}"
                    )

    def _set_verts(self, verts: Tensor, queries: PackedPoints | None = None) -> None:
        self.verts = verts
        # Centre and extent of the referenced vertices only: an unreferenced one far away took the centre off the
        # surface (float32 lost every short distance), or forced a scale that underflowed its faces' squared areas.
        rows = self._centre_rows
        self._centers, self._vert_center, _ = centred(verts, self.verts_lengths, rows)
        verts_c = (verts - self._vert_center).detach()
        used_c = verts_c if rows is None else verts_c.index_select(0, rows)
        extent = float(used_c.abs().amax()) if used_c.numel() else 0.0
        self._extent = extent  # the mesh's own, before any query's (measure_once compares the two frames)
        if queries is not None and queries.points.numel() and queries.lengths.numel() == self.num_items:
            # A one-off index scales for its one query too (a malformed one is refused by check_queries).
            _, center = item_rows(queries.lengths, queries.points.shape[0], self._centers)
            extent = max(extent, float((queries.points.detach() - center).abs().amax()))
        # Exact power-of-two scaling where float arithmetic would overflow or underflow (|ab x ac|^2: degree 4).
        self._scale = range_scale(extent, verts.dtype, 4)
        if self._scale is not None:
            verts_c = verts_c * self._scale
        self._faceset = FaceSet(verts_c, self._faces_global, self._face_batch, self._face_offsets)

    @property
    def dtype(self) -> torch.dtype:
        """Floating dtype of the index; queries must use it."""
        return self.verts.dtype

    @property
    def device(self) -> torch.device:
        """Device of the index; queries must use it."""
        return self.verts.device

    @property
    def num_items(self) -> int:
        """Number of meshes ``B`` in the index."""
        return int(self.verts_lengths.numel())

    def _ref_points(self) -> tuple[Tensor, Tensor]:
        if not self.referenced_only:
            return self.verts, self.verts_lengths
        used = vertex_set_mask(self._faces_global, self.verts.shape[0])
        if self.num_items == 1:
            return self.verts[used], used.sum().reshape(1)
        counts = torch.zeros(self.num_items, dtype=torch.long, device=self.device)
        counts.index_add_(0, batch_index(self.verts_lengths), used.long())
        return self.verts[used], counts

    @property
    def ref_points(self) -> PackedPoints:
        """The reference of :meth:`nearest_vertex_distance`: packed vertex sets and their lengths (``idx`` rows)."""
        ref, lengths = self._ref_points()
        return PackedPoints(ref, lengths)

    def _check_points(self, points: Tensor | Sequence[Tensor], points_lengths: Tensor | None) -> PackedPoints:
        """The points packed and in the index's dtype (the dtype rule: narrower points are cast up, exactly)."""
        for i, p in enumerate([points] if isinstance(points, Tensor) else points):
            name = "points" if isinstance(points, Tensor) else f"points[{i}]"
            if isinstance(p, Tensor) and p.device != self.device:
                raise DeviceError(f"{name}: expected a tensor on the index's device {self.device}, found {p.device}")
            if isinstance(p, Tensor) and p.is_floating_point():
                check_index_dtype(self.dtype, p.dtype, name)
        pts = pack_points(points, points_lengths)
        return pts._replace(points=pts.points.to(self.dtype))

    def point_mesh_distance(
        self, points: Tensor | Sequence[Tensor], *, points_lengths: Tensor | None = None
    ) -> PointMeshResult:
        """Exact distance from every point to the surface: :func:`~torchmeshmetric.point_mesh_distance` on this mesh.

        Args:
            points: ``(P, 3)`` points, packed ``(sum P_b, 3)`` with ``points_lengths``, or a list (one per mesh).
            points_lengths: ``(B,)`` points per mesh of a packed batch.

        Returns:
            :class:`~torchmeshmetric.PointMeshResult` ``(dists, face_idx, bary, closest)``.

        Raises:
            DeviceError: when the points are not on the index's device.
            DTypeError: when the points are wider than the index (float64 points, float32 index): they would be
                rounded (narrower points are cast up: the answer is in the index's dtype).
            ShapeError, NonFiniteError, EmptyInputError, ValueError: on bad points.
            StaleIndexError: a tensor the index was built from changed in place since it was built or refitted.
        """
        pts = self._check_points(points, points_lengths)
        return self.point_mesh_distance_unchecked(pts.points, pts.lengths)

    def point_mesh_distance_centred(self, points: Tensor, points_lengths: Tensor) -> _CentredHit:
        """:meth:`point_mesh_distance_unchecked` before its move back: the answer in the centred (scaled) frame.

        Distances and closest points are those the kernels computed, on the points minus their item's centre, times
        the index's power-of-two scale (``None``: 1); :meth:`to_world` divides and moves them back.

        Args:
            points: ``(P, 3)`` packed query points (validated, as for :meth:`point_mesh_distance_unchecked`).
            points_lengths: ``(B,)`` points per indexed mesh.

        Returns:
            A :class:`_CentredHit`.
        """
        self._check_current()
        if getattr(self, "_faces_everywhere", None) is None:
            # Once per index (its faces cannot change): then no query reads the face counts back from the device.
            self._faces_everywhere = bool((self.faces_lengths > 0).all())
        check_queries(
            points,
            points_lengths,
            self.faces_lengths,
            # named `points`: the sets come from a list as often as from points_lengths (found by review)
            count_error="points: expected {items} point sets (one per mesh), found {sets} (a list of point sets, or "
            "a packed tensor split by points_lengths)",
            lacking_error="faces: mesh {item} has no faces but {points} query points",
            prims_everywhere=bool(self._faces_everywhere),
        )
        point_batch, point_center = item_rows(points_lengths, points.shape[0], self._centers)
        points_c = points - point_center
        scale = self._scale
        if scale is not None:
            points_c = points_c * scale
        if self._faces is None:
            self._faces = self._face_selector()
        result: PointMeshResult | None = None
        if not (points_c.requires_grad or self.verts.requires_grad):
            fused = self._faces.select_closest(points_c, point_batch)
            if fused is not None:
                # Without autograd safe_sqrt(sq) is sqrt(sq) bit for bit (sq >= 0, sqrt(0) = 0).
                result = PointMeshResult(torch.sqrt(fused[1]), fused[0], fused[2], fused[3])
        if result is None:
            result = self._recompute(points_c, self._faces.select(points_c, point_batch), scale)
        return _CentredHit(result, points_c, point_batch, point_center, scale)

    def point_mesh_distance_unchecked(self, points: Tensor, points_lengths: Tensor) -> PointMeshResult:
        """:meth:`point_mesh_distance` for points the caller has validated (packed, finite, dtype and device).

        Args:
            points: ``(P, 3)`` packed query points.
            points_lengths: ``(B,)`` points per indexed mesh.

        Returns:
            As :meth:`point_mesh_distance`.
        """
        return self.to_world(self.point_mesh_distance_centred(points, points_lengths))

    @staticmethod
    def to_world(hit: _CentredHit) -> PointMeshResult:
        """The answer of :meth:`point_mesh_distance_centred` in the caller's frame, checked for overflow."""
        result, scale = hit.result, hit.scale
        if scale is not None:
            result = result._replace(dists=result.dists / scale, closest=result.closest / scale)
        check_representable(result.dists, "points")
        return result._replace(closest=result.closest + hit.point_center)

    def centred_verts(self) -> Tensor:
        """``(V, 3)`` the packed vertices as the kernels measure them: each item centred (and range-scaled), detached.

        Rows are those of the packed ``verts`` (``faces`` index them), in the frame of
        :meth:`point_mesh_distance_centred`'s points and closest points.
        """
        return self._faceset.verts

    def _recompute(self, points_c: Tensor, face_idx: Tensor, scale: float | None) -> PointMeshResult:
        """Distances, barycentrics and closest points (centred frame) on the selected faces, with autograd."""
        if self.verts.requires_grad:
            verts_c = self.verts - self._vert_center
            verts_c = verts_c if scale is None else verts_c * scale
        else:
            verts_c = self._faceset.verts
        if not (points_c.requires_grad or verts_c.requires_grad):
            out = bvh_closest_points(points_c, verts_c, self._faces_global, face_idx)
            if out is not None:
                return PointMeshResult(torch.sqrt(out[0]), face_idx, out[1], out[2])
        tri = verts_c[self._faces_global[face_idx]]
        res = closest_point_on_triangle_unchecked(points_c, tri[:, 0], tri[:, 1], tri[:, 2])
        return PointMeshResult(safe_sqrt(res.sq_dists), face_idx, res.bary, res.closest)

    def nearest_vertex_distance(
        self, points: Tensor | Sequence[Tensor], *, points_lengths: Tensor | None = None
    ) -> NearestVertexResult:
        """Exact distance to the nearest vertex: :func:`~torchmeshmetric.nearest_vertex_distance` to :attr:`ref_points`.

        Args:
            points: ``(P, 3)`` points, packed ``(sum P_b, 3)`` with ``points_lengths``, or a list (one per mesh).
            points_lengths: ``(B,)`` points per mesh of a packed batch.

        Returns:
            :class:`~torchmeshmetric.NearestVertexResult` ``(dists, idx)``, ``idx`` a row of :attr:`ref_points`.

        Raises:
            DeviceError, DTypeError, ShapeError, NonFiniteError, EmptyInputError, ValueError, StaleIndexError: as
                :meth:`point_mesh_distance` (bad points, points wider than the index, a stale index).
        """
        pts = self._check_points(points, points_lengths)
        return self.nearest_vertex_distance_unchecked(pts.points, pts.lengths)

    def nearest_vertex_distance_unchecked(self, points: Tensor, points_lengths: Tensor) -> NearestVertexResult:
        """:meth:`nearest_vertex_distance` for points the caller has validated (packed, finite, dtype and device).

        Args:
            points: ``(P, 3)`` packed query points.
            points_lengths: ``(B,)`` points per indexed mesh.

        Returns:
            As :meth:`nearest_vertex_distance`.
        """
        self._check_current()
        if self._nearest is None and self._origin is None:
            ref, lengths = self._ref_points()
            self._nearest = _NearestIndex(ref, lengths, self.backend, self.max_memory)
        elif self._nearest is None or self.verts.requires_grad:
            if self._nearest is None:
                self._nearest = copy.copy(self._origin._nearest_structure())  # type: ignore[union-attr]
            self._nearest.ref = self._ref_points()[0]  # a fresh graph to the vertices for this call
        return self._nearest.query(points, points_lengths)

    def _face_selector(self) -> Selector:
        """The closest-face structure, built now; a copy's is built on (and kept by) the index it was made from."""
        if self._origin is None:
            return Selector(self.backend, self._faceset, self.max_memory, self.tree)
        if self._origin._faces is None:
            self._origin._faces = self._origin._face_selector()
        return self._origin._faces

    def _nearest_structure(self) -> _NearestIndex:
        """The nearest-vertex structure, built on this index's own vertices if not yet (kept for its copies)."""
        if self._nearest is None:
            ref, lengths = self._ref_points()
            self._nearest = _NearestIndex(ref, lengths, self.backend, self.max_memory)
        return self._nearest

    def __getstate__(self) -> dict[str, Any]:
        # The selection structures are rebuilt on the first query after unpickling (they hold backend functions).
        state = dict(self.__dict__)
        state.update(_faces=None, _nearest=None, _origin=None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        # The unpickled (or deep-copied) tensors are new ones, with counters of their own: watched from now on.
        self.__dict__.update(state)
        for key in ("_verts_sources", "_faces_sources"):
            self.__dict__[key] = tuple((n, t, _version(t)) for n, t, _ in state.get(key, ()))
        if "_centre_rows" not in state:
            # Pickled by a version that centred on every vertex: centre on the referenced ones, as a new index does
            # (the structures are rebuilt on the first query, from the frame set here).
            self._centre_rows = referenced_rows(self._faces_global, int(self.verts.shape[0]))
            self._set_verts(self.verts)

    def with_verts(
        self,
        verts: Tensor | None,
        verts_given: Sequence[tuple[str, Any]] = (),
        faces_given: Sequence[tuple[str, Any]] = (),
    ) -> MeshIndex:
        """A shallow copy over ``verts`` of equal values (same structures; autograd reaches ``verts``).

        ``verts=None`` keeps the index's vertices. The copy also refuses to answer once ``verts`` or one of the
        caller's tensors ``verts_given`` / ``faces_given`` (``(name, tensor)``) changes in place, as the index does
        for the tensors it was built from (which stay watched). A copy that is refitted takes structures of its own.
        ``verts`` is checked, values included (one comparison, O(V), and a device sync on a GPU: 0.12 ms for 164k
        vertices on the CPU, against 55 ms for a query of 10k points on that mesh); the library's own callers, whose
        values are equal by construction, use :meth:`with_verts_unchecked`.

        Args:
            verts: ``(V, 3)`` packed vertices equal in value to the index's, or ``None``.
            verts_given: the caller's vertex tensors to watch, as ``(name, tensor)``.
            faces_given: the caller's face tensors to watch, as ``(name, tensor)``.

        Returns:
            The copy.

        Raises:
            ShapeError, DTypeError, DeviceError: ``verts`` is not ``(V, 3)`` of the index's dtype and device.
            StaleIndexError: ``verts`` differs in value from the index's vertices (the copy would answer for the
                index's mesh, not for ``verts``; until review V it did: ``V + 1`` got the distance of ``V``).

        Example:
            >>> import torch, trimesh
            >>> s = trimesh.creation.icosphere()
            >>> index = MeshIndex(torch.tensor(s.vertices), torch.tensor(s.faces))
            >>> v = torch.tensor(s.vertices, requires_grad=True)
            >>> d = index.with_verts(v).point_mesh_distance(torch.tensor([[0.0, 0, 2]])).dists
            >>> d.sum().backward(); v.grad.abs().sum() > 0
            tensor(True)
        """
        if verts is not None:
            self._check_new_verts(verts)
            if not torch.equal(verts.detach(), self.verts.detach()):
                gap = (verts.detach() - self.verts.detach()).abs().amax(1)
                row = int(gap.argmax())
                raise StaleIndexError(
                    f"verts: expected vertices equal in value to the index's (a copy answers for the index's mesh), "
                    f"found row {row} off by {float(gap[row]):.3g}; refit the index (index.refit(verts)) or build a "
                    "new MeshIndex for this mesh"
                )
        return self.with_verts_unchecked(verts, verts_given, faces_given)

    def with_verts_unchecked(
        self,
        verts: Tensor | None,
        verts_given: Sequence[tuple[str, Any]] = (),
        faces_given: Sequence[tuple[str, Any]] = (),
    ) -> MeshIndex:
        """:meth:`with_verts` for vertices the caller knows equal to the index's (of its shape, dtype and device)."""
        other = MeshIndex.__new__(MeshIndex)
        other.__dict__.update(self.__dict__)  # not copy.copy: __getstate__ drops the structures
        # Structures not built yet are built on the origin, so that the next copy finds them (an IndexCache's hits).
        other._origin = self if self._origin is None else self._origin
        if verts is not None:
            other.verts = verts
            verts_given = [*verts_given, ("verts", verts)]
        other._verts_sources = self._verts_sources + _sources(verts_given)
        other._faces_sources = self._faces_sources + _sources(faces_given)
        if other._nearest is not None:
            other._nearest = copy.copy(other._nearest)
        return other

    def _check_new_verts(self, verts: Tensor) -> None:
        """Require ``verts`` of the index's shape ``(V, 3)``, float dtype and device (O(1))."""
        check_shape(verts, (int(self.verts.shape[0]), 3), "verts")
        check_float(verts, "verts")
        if verts.device != self.device:
            raise DeviceError(f"verts: expected a tensor on the index's device {self.device}, found {verts.device}")
        if verts.dtype != self.dtype:
            raise DTypeError(f"verts: expected the index's dtype {self.dtype}, found {verts.dtype}")

    def refit(self, verts: Tensor) -> None:
        """Move the vertices (same faces, same order): bounds are refitted, not rebuilt; answers stay exact.

        A tree the refits have worn (its node area grown 1.2x since its build, or 256 refits: ``"bvh"``) is rebuilt
        instead, for speed only: the answers are the same bits.

        ``verts`` (often the same tensor, moved in place by an optimizer) is watched from now on instead of the
        vertices the index was built from.

        Args:
            verts: ``(V, 3)`` new packed vertices, of the index's dtype and device.

        Raises:
            ShapeError, DTypeError, DeviceError, NonFiniteError: when ``verts`` does not fit the index.
        """
        self._check_new_verts(verts)
        check_finite(verts, "verts")
        self.refit_unchecked(verts)

    def refit_unchecked(self, verts: Tensor) -> None:
        """:meth:`refit` for ``(V, 3)`` vertices the caller has validated (shape, dtype, device, finite).

        Args:
            verts: the new packed vertices.
        """
        if self._origin is not None:
            # A copy (an IndexCache hit) shares its origin's structures with the cache entry and every other copy:
            # refitting them would move their answers too. The copy takes structures of its own, built on first
            # use for the moved vertices (refitted, not rebuilt, from then on).
            self._origin, self._faces, self._nearest = None, None, None
        self._set_verts(verts)
        self._verts_sources = _sources([("verts", verts)])
        if self._faces is not None:
            self._faces.refit(self._faceset)
        if self._nearest is not None:
            self._nearest.refit(self._ref_points()[0])


def measure_once(
    packed: PackedMeshes, points: Tensor, points_lengths: Tensor, backend: str, max_memory: int
) -> PointMeshResult:
    """:func:`~torchmeshmetric.point_mesh_distance` of validated points on a validated mesh of their dtype.

    The points the mesh's own range scale covers are measured in the mesh's frame (bit for bit as a
    :class:`MeshIndex` of the mesh measures them); the others, if any, in a frame scaled for them as well, so that a
    point far from a small mesh is measured, not refused. One frame for all let one far point shrink every
    coordinate (float32 unit sphere: a point at 1e10 moved the others' distances by 0.03, one at 1e30 made them 0).

    Args:
        packed: the packed meshes, validated, in the points' dtype.
        points: ``(P, 3)`` packed points, validated.
        points_lengths: ``(B,)`` points per mesh.
        backend: a backend name.
        max_memory: the bytes a chunked backend may use.

    Returns:
        As :func:`~torchmeshmetric.point_mesh_distance`.
    """
    index = MeshIndex.from_packed(packed, backend, max_memory, tree="morton")
    num_items, num_points = index.num_items, int(points.shape[0])
    if not (num_points and int(points_lengths.numel()) == num_items):
        return index.point_mesh_distance_unchecked(points, points_lengths)  # raises, naming the fault
    batch, center = item_rows(points_lengths, num_points, index._centers)
    own = in_own_frame((points.detach() - center).abs().amax(-1), index._extent, 4)
    if own is None:
        return index.point_mesh_distance_unchecked(points, points_lengths)
    if not bool(own.any()):  # every point needs the wider frame: one index scaled for them all
        wide = MeshIndex.from_packed(
            packed, backend, max_memory, tree="morton", queries=PackedPoints(points, points_lengths)
        )
        return wide.point_mesh_distance_unchecked(points, points_lengths)
    near, near_lengths = rows_of(own, batch, num_items)
    far, far_lengths = rows_of(~own, batch, num_items)
    far_points = points.index_select(0, far)
    wide = MeshIndex.from_packed(
        packed, backend, max_memory, tree="morton", queries=PackedPoints(far_points, far_lengths)
    )
    parts = (
        index.point_mesh_distance_unchecked(points.index_select(0, near), near_lengths),
        wide.point_mesh_distance_unchecked(far_points, far_lengths),
    )
    return PointMeshResult(*(merge_rows(num_points, (near, far), pair) for pair in zip(*parts, strict=True)))
