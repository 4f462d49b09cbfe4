r"""The registered forms: the temporal metrics for sequences whose connectivity changes from frame to frame.

KG, KSO and STED need one vertex set followed through every frame, in the original and in the distorted sequence.
Captured sequences and simplified ones have a new connectivity every frame, so the library builds that
correspondence (docs/temporal.md argues each choice):

1. **Track the original.** Frame 0's vertices are carried from frame to frame by the registration of original frame
   ``k-1`` onto frame ``k`` (the evaluation's own registrations, through the same cache:
   :func:`~torchmeshmetric.evaluation.register_pairs`), each step's warp applied to the previous step's positions and
   the result put back on the surface of frame ``k`` by its exact closest point. This gives an original sequence with
   frame 0's connectivity, ``(F, V_0, 3)``.
2. **Carry the distorted frames onto it.** Each tracked vertex of frame ``k`` takes the point where its normal line
   meets the distorted frame ``k``, found from its exact closest point (:class:`~torchmeshmetric.kernels.MeshIndex`)
   by a few steps along the normal (:func:`carry_onto`), written as the barycentric blend of the distorted face's
   vertices, so gradients reach the distorted vertices (those of the intersection, :func:`carry_onto`).
3. **The same metrics** on the two ``(F, V_0, 3)`` sequences, with frame 0's faces.

What it sees is what a surface can show: a displacement along the normal moves the closest point; a vertex sliding
*along* the surface leaves no trace (the surface is unchanged), which the exact forms count.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import (
    EmptyInputError,
    ShapeError,
    as_real,
    check_finite,
    check_float,
    check_int,
    check_tensor,
)
from torchmeshmetric.evaluation.pipeline import RegisterFn, RegistrationOptions, register_pairs
from torchmeshmetric.kernels import MeshIndex, PointMeshResult
from torchmeshmetric.registration.cache import CachedRegistration, RegistrationCache
from torchmeshmetric.registration.warp import as_warp
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, power_of_two_above
from torchmeshmetric.temporal.sequences import check_faces_of
from torchmeshmetric.temporal.topology import mesh_edges, referenced_vertices

__all__ = [
    "DEFAULT_NORMAL_STEPS",
    "DEFAULT_WELD",
    "RegisteredPair",
    "TrackedSequence",
    "carry_onto",
    "registered_pair",
    "track_original",
]


#: Frame 0's edges shorter than this fraction of the median edge are welded before tracking (docs/temporal.md).
DEFAULT_WELD = 0.1

_REACH = 10.0

#: Secant steps along the normal of :func:`carry_onto` (docs/temporal.md: 99.5 % of the points have converged by 8).
DEFAULT_NORMAL_STEPS = 8


class TrackedSequence(NamedTuple):
    """The original's frame 0 followed through every frame (step 1 of the module docstring).

    Attributes:
        verts: ``(F, V_0, 3)`` float64 positions of frame 0's referenced vertices in every frame, on each frame's
            surface.
        faces: ``(T_0, 3)`` int64 frame 0's faces (indices into ``verts``' vertices).
        projection: ``(F, V_0)`` how far each warped position was from the surface of its frame before it was put
            back on it (zero in frame 0): the registration's residual where the tracking runs.
        registrations: the ``F - 1`` registrations used (entry ``k-1``: frame ``k-1`` onto frame ``k``).

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> moved = trimesh.Trimesh(sphere.vertices + [0.1, 0.0, 0.0], sphere.faces)
        >>> shift = lambda source, target: (source.verts + torch.tensor([0.1, 0.0, 0.0]), source.faces)
        >>> t = track_original([sphere, moved], registration_fn=shift)
        >>> tuple(t.verts.shape), t.verts.dtype, tuple(t.faces.shape), len(t.registrations)
        ((2, 162, 3), torch.float64, (320, 3), 1)
    """

    verts: Tensor
    faces: Tensor
    projection: Tensor
    registrations: list[CachedRegistration]


class RegisteredPair(NamedTuple):
    """An original and a distorted sequence on one vertex set (the input of the same-connectivity metrics).

    Attributes:
        original: ``(F, V_0, 3)`` the tracked original (:class:`TrackedSequence` ``verts``).
        distorted: ``(F, V_0, 3)`` the distorted frames carried onto it (differentiable in the distorted vertices).
        faces: ``(T_0, 3)`` the faces of both.
        tracking: the :class:`TrackedSequence`.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> finer = trimesh.creation.icosphere(subdivisions=3)  # the same surface, another connectivity
        >>> p = registered_pair([sphere, sphere], [finer, finer], registration_fn=lambda s, t: s)
        >>> tuple(p.original.shape), tuple(p.distorted.shape), tuple(p.faces.shape)  # on the original's 162 vertices
        ((2, 162, 3), (2, 162, 3), (320, 3))
    """

    original: Tensor
    distorted: Tensor
    faces: Tensor
    tracking: TrackedSequence


def _frames(frames: Sequence[MeshLike], name: str) -> list[Mesh]:
    if isinstance(frames, (str, bytes)) or not isinstance(frames, Sequence):
        raise TypeError(f"{name}: expected a sequence of meshes (one per frame), found {type(frames).__name__}")
    if len(frames) < 2:
        raise ShapeError(f"{name}: expected at least 2 frames, found {len(frames)}")
    return [as_mesh(m, name=f"{name}[{k}]") for k, m in enumerate(frames)]


def _compact(mesh: Mesh) -> Mesh:
    """``mesh`` without the vertices no face references (faces renumbered)."""
    used, faces = referenced_vertices(mesh.faces, mesh.num_verts)
    return mesh if bool(used.all()) else Mesh(mesh.verts[used], faces, validate=False)


def check_weld(fraction: object, name: str = "weld") -> None:
    """A weld fraction: a number in ``[0, 1)`` (at 1 half the mesh's edges, those below the median, would weld).

    Raises:
        TypeError: not a number.
        ValueError: outside ``[0, 1)`` (NaN and infinities too).
    """
    value = as_real(fraction, name)
    if value is None:
        raise TypeError(f"{name}: expected a fraction of the median edge length, found {type(fraction).__name__}")
    if not 0 <= value < 1:
        raise ValueError(f"{name}: expected a fraction of the median edge length in [0, 1), found {fraction!r}")


def weld_short_edges(mesh: Mesh, fraction: float, *, backend: str = "auto") -> Mesh:
    """``mesh`` with every edge shorter than ``fraction`` of the median edge length welded to one vertex.

    STED's relative edge differences grow as ``1 / length`` on short edges (a length-weighted variance of
    ``Δ / l`` is ``Σ Δ² / l``), so the slivers that marching cubes and captures leave would let the tracking's noise
    dominate the registered STED_s. The vertices joined by short edges (connected components of the short-edge graph)
    become one, at their mean put back on the surface (its closest point); faces that lose a corner are dropped.

    Args:
        mesh: the mesh (float64).
        fraction: edges shorter than ``fraction`` times the median edge length are welded, in ``[0, 1)``; ``0``
            welds nothing.
        backend: kernel backend of the closest-point query.

    Returns:
        The welded mesh (``mesh`` itself when no edge is short).

    Example:
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-9, 1, 0], [1, 1, 0]], dtype=torch.float64)
        >>> f = torch.tensor([[0, 1, 2], [1, 3, 2], [1, 4, 3]])
        >>> weld_short_edges(Mesh(v, f), 0.05).faces.tolist()  # vertices 2 and 3 become one
        [[0, 1, 2], [1, 3, 2]]
    """
    check_weld(fraction, "fraction")  # its own argument's name (it said "weld")
    if fraction == 0:
        return mesh
    edges = mesh_edges(mesh.faces, mesh.num_verts)
    lengths = (mesh.verts[edges[:, 0]] - mesh.verts[edges[:, 1]]).norm(dim=-1)
    short = edges[lengths < fraction * lengths.median()]
    if short.shape[0] == 0:
        return mesh
    label = torch.arange(mesh.num_verts, device=mesh.verts.device)
    while True:  # each vertex takes the smallest label of its short-edge component
        lowest = torch.minimum(label[short[:, 0]], label[short[:, 1]])
        new = label.clone()
        new.scatter_reduce_(0, short[:, 0], lowest, reduce="amin")
        new.scatter_reduce_(0, short[:, 1], lowest, reduce="amin")
        new = new[new]
        if torch.equal(new, label):
            break
        label = new
    roots, index = torch.unique(label, return_inverse=True)
    counts = torch.bincount(index, minlength=roots.numel()).to(mesh.verts.dtype)[:, None]
    mean = torch.zeros(roots.numel(), 3, dtype=mesh.verts.dtype, device=mesh.verts.device)
    mean = mean.index_add(0, index, mesh.verts) / counts
    faces = index[mesh.faces]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    on_surface = MeshIndex(mesh, backend=backend).point_mesh_distance(mean).closest
    return _compact(Mesh(on_surface, faces[keep], validate=False))


def track_original(
    frames: Sequence[MeshLike],
    *,
    registrations: Sequence[CachedRegistration] | None = None,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    registration_cache: RegistrationCache | None = None,
    device: torch.device | str | None = None,
    backend: str = "auto",
    weld: float = DEFAULT_WELD,
) -> TrackedSequence:
    """Frame 0 of an original sequence followed through every frame by the registrations (module docstring, step 1).

    Args:
        frames: the ``F >= 2`` original frames (any connectivity each).
        registrations: the ``F - 1`` registrations of frame ``k-1`` onto frame ``k`` when already computed (as
            :func:`~torchmeshmetric.evaluation.register_pairs` returns them); default: computed here.
        registration_fn: registration function (default: the library's non-rigid registration).
        registration_options: options of the default registration (part of the cache key).
        registration_cache: a :class:`~torchmeshmetric.registration.RegistrationCache` (``None``: no cache).
        device: where the registration and the tracking run (default: frame 0's device).
        backend: kernel backend of the registration and of the closest-point queries.
        weld: frame 0's edges shorter than this fraction of its median edge are welded first
            (:func:`weld_short_edges`); ``0``: frame 0 as it is.

    Returns:
        :class:`TrackedSequence` (float64, on the CPU or ``device``; no gradient).

    Raises:
        ShapeError: fewer than 2 frames, or a number of registrations other than ``F - 1``.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> moved = trimesh.Trimesh(sphere.vertices + [0.1, 0.0, 0.0], sphere.faces)
        >>> shift = lambda source, target: (source.verts + torch.tensor([0.1, 0.0, 0.0]), source.faces)
        >>> t = track_original([sphere, moved], registration_fn=shift)
        >>> t.verts.shape, float(t.projection.max()) < 1e-6
        (torch.Size([2, 162, 3]), True)
    """
    meshes = _frames(frames, "frames")
    check_weld(weld)  # now, not after the registrations
    if registrations is None:
        registrations = register_pairs(
            meshes,
            registration_fn=registration_fn,
            registration_options=registration_options,
            registration_cache=registration_cache,
            device=device,
            backend=backend,
        )
    if len(registrations) != len(meshes) - 1:
        raise ShapeError(
            f"registrations: expected {len(meshes) - 1} (one per pair of consecutive frames), "
            f"found {len(registrations)}"
        )
    dev = torch.device(device) if device is not None else meshes[0].device
    with torch.no_grad():
        first = weld_short_edges(_compact(meshes[0].to(dev, torch.float64)), weld, backend=backend)
    positions = [first.verts.detach()]
    projection = [torch.zeros(first.num_verts, dtype=torch.float64, device=dev)]
    with torch.no_grad():
        for k in range(1, len(meshes)):
            target = meshes[k].to(dev, torch.float64)
            warp = as_warp(registrations[k - 1], target, meshes[k - 1].to(dev, torch.float64), name="registrations")
            warped = warp(positions[-1])
            hit = MeshIndex(target, backend=backend, tree="morton").point_mesh_distance(warped)
            positions.append(hit.closest)
            projection.append(hit.dists)
    return TrackedSequence(torch.stack(positions), first.faces, torch.stack(projection), list(registrations))


def _edge_scale(x: Tensor, faces: Tensor) -> Tensor:
    """``(V,)`` mean length of the edges at each vertex of ``(x, faces)`` (zero at a vertex without edges)."""
    edges = mesh_edges(faces, x.shape[0])
    length = (x[edges[:, 0]] - x[edges[:, 1]]).norm(dim=-1)
    total = torch.zeros_like(x[:, 0]).index_add(0, edges.flatten(), length.repeat_interleave(2))
    count = torch.bincount(edges.flatten(), minlength=x.shape[0]).to(x.dtype)
    return total / count.clamp_min(1)


def _line_normals(x: Tensor, faces: Tensor) -> tuple[Tensor, Tensor]:
    """``(V, 3)`` the unit normals of the lines :func:`carry_onto` follows and ``(V,)`` the weights of those lines.

    The area-weighted vertex normal (:meth:`~torchmeshmetric.structures.Mesh.vertex_normals`), except at a vertex
    whose faces' area vectors cancel to within their rounding (``64 eps`` of the largest coordinate times the longest
    edge, per face, as :meth:`~torchmeshmetric.structures.Mesh.surface_face_mask` bounds a face's): a fin of two
    faces on the same three vertices, which the weld can fold (one on the demo at resolutions 64, 80 and 120). There
    the sum was rounding noise whose direction changed with the last bits of the vertices and with the CPU's kernels
    (fused multiply-adds), and the line followed it: at resolution 80 a tracked vertex 1e-17 apart under the
    ``scalar`` CPU was carried 1.7e-3 apart (measured). Such a vertex has no line (weight 0, normal zero) and takes its
    closest point, as one without faces of positive area does.

    The weight rises from 0 at ``|total| = bound`` to 1 at ``2 bound`` (``total`` the sum of the area vectors,
    ``bound`` their rounding), as the smoothstep ``s^2 (3 - 2 s)`` of ``s = |total| / bound - 1``, and the carried
    point is ``w`` times the line's point plus ``1 - w`` times the closest point. A hard threshold made the carried
    point, and every figure, jump where ``|total|`` crossed ``bound`` (found by review: a vertex moved 0.035 when a
    coordinate changed by 2e-14). Above the bound the normal's direction is known to within ``bound / |total|``
    (a radian at the lower end, a half at the upper); the smoothstep's zero slope at ``s = 0`` keeps the line's weight
    ``O(s^2)`` where its direction is least known, and at ``s = 1`` the carried point's derivative has no jump. Below
    the bound (rounding: the cross-CPU agreement) and from ``2 bound`` up the carried point is the same bits as
    without the band.
    """
    mesh = Mesh(x, faces, validate=False)
    normal = mesh.vertex_normals()
    if faces.shape[0] == 0:
        return normal, (normal != 0).any(-1).to(x.dtype)
    tri = x[faces]
    edges = torch.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]], dim=1)
    unit = power_of_two_above(edges[:, :2].abs().amax())  # _normal_cross's units (exact)
    longest = (edges / unit).norm(dim=-1).amax(-1)
    noise = 64 * torch.finfo(x.dtype).eps * (tri.abs().amax(dim=(1, 2)) / unit) * longest
    cross = mesh._normal_cross()
    total = torch.zeros_like(x).index_add(0, faces[:, 0], cross).index_add(0, faces[:, 1], cross)
    total = total.index_add(0, faces[:, 2], cross).norm(dim=-1)
    bound = torch.zeros_like(x[:, 0]).index_add(0, faces.flatten(), noise.repeat_interleave(3))
    # (|total| - bound) / bound: its sign is exact, so the weight is 0 exactly where |total| <= bound (as before the
    # band); a bound of 0 (no face of positive size) keeps the threshold, without dividing by it.
    positive = bound > 0
    above = torch.where(positive, (total - bound) / torch.where(positive, bound, 1), (total > 0).to(x.dtype))
    s = above.clamp(0, 1)
    weight = s * s * (3 - 2 * s)
    return torch.where((weight > 0)[:, None], normal, torch.zeros_like(normal)), weight


def _mix(line: Tensor, band: Tensor, weight: Tensor, closest: Tensor) -> Tensor:
    """``line`` with its rows ``band`` replaced by ``weight`` of them plus ``1 - weight`` of ``closest`` (per row)."""
    w = weight[:, None].to(line.dtype)
    return line.index_put((band,), w * line[band] + (1 - w) * closest)


def _region_step(
    verts: Tensor, faces: Tensor, hit: PointMeshResult, q: Tensor, normal: Tensor
) -> tuple[Tensor, Tensor]:
    """The root of ``g(t) = (q - cp(q)) . n`` on the lines ``q + t n`` while ``cp`` stays in its region of its face.

    In one region of a face (its interior, one edge, one vertex) ``r = q - cp`` is ``q``'s offset from the face's
    plane, the edge's line or the vertex, and ``g`` is linear in ``t``: ``g = r . n`` grows by ``(n . w)^2 / |w|^2``
    per unit ``t``, with ``w`` the part of ``n`` across the region (``n``'s component along the face's normal
    ``N``, across the edge ``e`` (``e x (n x e)``), or ``n`` itself at a vertex). Its root is ``t = -(r . w) / (n . w)``
    (the line's crossing of the plane, its closest approach to the edge's line or the vertex). Computed from ``r . w``
    and not from ``g``: ``r`` is along ``w``'s direction to rounding, so ``r . w`` keeps ``|r|``'s relative accuracy,
    where ``g`` loses it by ``n . N`` on a line that grazes the face (its rounding over ``(n . N)^2``).

    The face's edges are taken in units of a power of two near the longest (exact), so ``w`` neither overflows nor
    underflows in float32 at any scale (as in :func:`_carried_point`).

    Args:
        verts: ``(V, 3)`` the distorted frame's vertices.
        faces: ``(T, 3)`` its faces.
        hit: the closest points of ``q`` (their faces, and barycentric coordinates: zeros mark an edge or vertex).
        q: ``(P, 3)`` the line points.
        normal: ``(P, 3)`` the lines' directions ``n``.

    Returns:
        ``(P,)`` the step to the root and ``(P,)`` the slope ``dg/dt``; NaN where the face or the edge is degenerate.
    """
    c = verts[faces[hit.face_idx]]  # (P, 3, 3)
    c = c - c[:, :1]
    c = c / power_of_two_above(c.abs().amax(dim=(1, 2)))[:, None, None]  # corners from the first, in units
    zeros = (hit.bary == 0).sum(-1)
    w = torch.linalg.cross(c[:, 1], c[:, 2], dim=-1)  # interior: the face's normal
    for k in range(3):  # on the edge opposite corner k
        edge = c[:, (k + 2) % 3] - c[:, (k + 1) % 3]
        across = torch.linalg.cross(edge, torch.linalg.cross(normal, edge, dim=-1), dim=-1)
        w = torch.where(((zeros == 1) & (hit.bary[:, k] == 0))[:, None], across, w)
    w = torch.where((zeros >= 2)[:, None], normal, w)  # at a vertex
    along = (normal * w).sum(-1)
    size2 = w.square().sum(-1)
    nan = torch.full_like(along, float("nan"))
    step = torch.where(along != 0, -((q - hit.closest) * w).sum(-1) / along, nan)
    slope = torch.where(size2 > 0, along.square() / size2, nan)
    return step, slope


def _along_normal(
    index: MeshIndex,
    verts: Tensor,
    faces: Tensor,
    x: Tensor,
    normal: Tensor,
    scale: Tensor,
    hit: PointMeshResult,
    steps: int,
) -> tuple[PointMeshResult, Tensor, Tensor]:
    """Secant steps towards the root of ``g(t) = (q - cp(q)) . n`` on the line ``q = x + t n`` (see carry_onto).

    Only the points whose line has not met the surface yet (``|g|`` above ``1e-10`` of the points' bounding-box
    extent) are queried again, so a step costs what remains to be found.

    Where a step's two closest points lie in one region of one face (its interior, an edge, a vertex), ``g`` is
    linear between them and the secant's step is that region's root, computed from the face (:func:`_region_step`),
    not from ``g1 - g0``: on a line that grazes a face (``n . N`` small) ``g`` barely changes along it, ``g1 - g0``
    cancelled and the step was its rounding (up to 1e-3 of its length). A change of 1e-16 in a tracked vertex (the
    registration on another CPU) moved its carried point by 8.8e-6 and the registered KG by 1.4e-5 (the demo at
    resolution 24; docs/temporal.md, "Which digits the input determines").

    Returns:
        The closest points kept, the ``(V, 3)`` line points ``q`` they are the closest points of, and the ``(V,)``
        mask of the lines that met the surface (``|g|`` within the tolerance).
    """
    # The mesh's own size, not its distance to the origin: 1e-10 of max|x| stopped a mesh 1e6 away before its first
    # step, its points fell back to the plain closest points, and the figures moved with a translation (found by
    # review: registered KG -6.8e-4 relative at offset 1e6, STED_s +28 % for a 1e-3 mesh).
    tol = 1e-10 * float((x.amax(0) - x.amin(0)).max())
    # The line is followed within the larger of _REACH times the closest point's distance and the local edge length:
    # farther crossings are another part of the surface (the other side of a thin limb), not this point's
    # displaced surface.
    reach = torch.maximum(_REACH * hit.dists, scale)
    t0 = torch.zeros_like(x[:, 0])
    g0 = ((x - hit.closest) * normal).sum(-1)
    t1 = -g0
    best = PointMeshResult(*(a.clone() for a in hit))
    best_q = x.clone()
    best_g = g0.abs()
    face0, zeros0 = hit.face_idx.clone(), hit.bary == 0  # the region of the closest point at t0
    active = torch.nonzero(best_g > tol).flatten()
    for _ in range(steps):
        if active.numel() == 0:
            break
        q = x[active] + t1[active, None] * normal[active]
        h = index.point_mesh_distance(q)
        g1 = ((q - h.closest) * normal[active]).sum(-1)
        same = (h.face_idx == face0[active]) & ((h.bary == 0) == zeros0[active]).all(-1)
        better = (g1.abs() < best_g[active]) & ((h.closest - x[active]).norm(dim=-1) <= reach[active])
        chosen = active[better]
        for field, value in zip(best, h, strict=True):
            field[chosen] = value[better]
        best_q[chosen] = q[better]
        best_g[chosen] = g1.abs()[better]
        dt = t1[active] - t0[active]
        # Where both points are in one region, the secant's step is that region's (the same in exact arithmetic).
        region_step, region_slope = _region_step(verts, faces, h, q, normal[active])
        exact = same & ~region_step.isnan() & ~region_slope.isnan()
        secant = (g1 - g0[active]) / torch.where(dt == 0, torch.ones_like(dt), dt)  # per unit t
        slope = torch.where(exact, region_slope, secant)
        moving = (slope.abs() > 1e-12) & (dt != 0)
        step = torch.where(exact, region_step, -g1 / torch.where(moving, slope, torch.ones_like(slope)))
        t_next = torch.where(moving, t1[active] + step, t1[active])
        t_next = torch.maximum(torch.minimum(t_next, reach[active]), -reach[active])
        t0[active], g0[active], t1[active] = t1[active], g1, t_next
        face0[active], zeros0[active] = h.face_idx, h.bary == 0
        active = active[(best_g[active] > tol) & moving]
    # The derivative's choice, not the iteration's stop: a line has met the surface within the rounding of its
    # coordinates, absolute (eps of max|x|), which 1e-10 of the extent can be below: float32 (found by review: 176 of
    # 642 lines counted in float32, 642 in float64), or a mesh far from the origin.
    met = max(tol, 64 * torch.finfo(x.dtype).eps * float(x.abs().max()))
    return best, best_q, best_g <= met


def _carried_point(q: Tensor, corners: Tensor, bary: Tensor, normal: Tensor | None, on_line: Tensor) -> Tensor:
    """The carried points as functions of the distorted face's corners, for their derivative (see carry_onto).

    Where the line met the face's interior (``on_line``, every barycentric coordinate > 0), the line-plane
    intersection ``q + n ((a - q) . N) / (n . N)``; elsewhere the closest point of ``q`` in the region the exact
    query found: the plane's projection (interior), the edge line's (one coordinate 0), the vertex (two). A face too
    thin for its plane or line (the denominators vanish) keeps the barycentric blend.

    Each point is computed from its face's first corner ``a``, in units of a power of two near the largest of
    ``q - a``, ``b - a``, ``c - a`` (exact): squared areas of float32 coordinates beyond ~1e9 overflowed and below
    ~1e-8 underflowed, and the NaN reached the value or the gradient (found by review); a mesh far from the origin
    keeps its faces' own size.

    Args:
        q: ``(V, 3)`` the query points (detached).
        corners: ``(V, 3, 3)`` the corners of each point's face (differentiable).
        bary: ``(V, 3)`` the exact query's barycentric coordinates.
        normal: ``(V, 3)`` the unit normals of the lines, or ``None`` (closest points only).
        on_line: ``(V,)`` the points whose line met the surface.
    """
    blend = (bary[..., None] * corners).sum(1)
    a = corners[:, 0]
    local = torch.stack([q - a, corners[:, 1] - a, corners[:, 2] - a], dim=1)  # (V, 3, 3): q, b, c from a
    unit = power_of_two_above(local.detach().abs().amax(dim=(1, 2)))[:, None]  # (V, 1); 1 where all is 0
    ql, bl, cl = (local / unit[:, :, None]).unbind(1)
    plane = torch.linalg.cross(bl, cl, dim=-1)
    area2 = (plane * plane).sum(-1)
    size2 = torch.maximum(bl.square().sum(-1), cl.square().sum(-1)).detach()
    flat = area2 > 1e-24 * size2 * size2  # the plane is defined (torch.where needs finite values on both sides)
    safe_area2 = torch.where(flat, area2, torch.ones_like(area2))
    projected = ql - (ql * plane).sum(-1, keepdim=True) * plane / safe_area2[:, None]
    point = torch.where(flat[:, None], a + projected * unit, blend)
    if normal is not None:
        across = (normal * plane).sum(-1)
        meets = on_line & (bary > 0).all(-1) & flat & (across.abs() > 1e-6 * safe_area2.sqrt()).detach()
        safe_across = torch.where(meets, across, torch.ones_like(across))
        crossing = ql - normal * ((ql * plane).sum(-1) / safe_across)[:, None]
        point = torch.where(meets[:, None], a + crossing * unit, point)
    zeros = (bary == 0).sum(-1)
    ends = torch.stack([torch.zeros_like(bl), bl, cl], dim=1)  # the corners from a, in units
    for k in range(3):  # the edge opposite corner k, where the query landed on it
        u, v = ends[:, (k + 1) % 3], ends[:, (k + 2) % 3]
        length2 = (v - u).square().sum(-1)
        on_edge = (zeros == 1) & (bary[:, k] == 0) & (length2 > 0).detach()
        s_ = ((ql - u) * (v - u)).sum(-1) / torch.where(on_edge, length2, torch.ones_like(length2))
        point = torch.where(on_edge[:, None], a + (u + s_[:, None] * (v - u)) * unit, point)
    return torch.where((zeros >= 2)[:, None], blend, point)


def carry_onto(
    distorted: Sequence[MeshLike],
    tracked: Tensor,
    faces: Tensor | None = None,
    *,
    normal_steps: int = DEFAULT_NORMAL_STEPS,
    backend: str = "auto",
) -> Tensor:
    r"""The distorted frames carried onto tracked vertices: where each vertex's normal line meets its distorted frame.

    For a tracked vertex :math:`x` with unit normal :math:`n` (area-weighted, from ``faces``), the carried point is the
    root of :math:`g(t) = (q - \mathrm{cp}(q))\cdot n` on the line :math:`q = x + t n`, with :math:`\mathrm{cp}` the
    exact closest point on the distorted frame: :math:`g` vanishes where the line meets the surface, and is linear
    in :math:`t` near a planar piece, so secant steps from :math:`t_0 = 0` and :math:`t_1 = (\mathrm{cp}(x) - x)\cdot n`
    reach it in one step there. The point kept is the closest point of the step with the smallest :math:`|g|`
    among those within the larger of 10 times the first closest distance and the local edge length (a farther
    crossing is another part of the surface). Where
    the distorted surface is a displacement of the original along its normals this ends on the displaced point (a
    closest point alone lands short of a narrow bump: it prefers the bump's flanks), which is what the exact forms
    measure (docs/temporal.md gives the measurement). A vertex whose normal is rounding (its faces' area vectors
    cancel) takes its closest point, and just above that rounding a blend of both that is continuous in the input
    (:func:`_line_normals`). ``normal_steps=0`` or ``faces=None`` is the plain closest point.

    Args:
        distorted: the ``F`` distorted frames (any connectivity each).
        tracked: ``(F, V, 3)`` positions to carry onto (e.g. :class:`TrackedSequence` ``verts``).
        faces: ``(T, 3)`` faces of the tracked vertices (their normals); ``None``: closest points only.
        normal_steps: steps of the iteration along the normal after the closest point.
        backend: kernel backend of the closest-point queries.

    Returns:
        ``(F, V, 3)`` carried points, in ``tracked``'s dtype, as barycentric blends of the distorted vertices. Their
        gradient reaches the distorted vertices, as the derivative of the point the definition names with the face
        held fixed: the intersection of the normal line with the face's plane where the line met the surface, else
        the closest point of the last line point in its region of the face (plane, edge or vertex).

    Raises:
        ShapeError: ``tracked`` not ``(F, V, 3)``, or a frame count other than ``tracked``'s.
        DTypeError: ``tracked`` not float32 or float64.
        EmptyInputError: ``tracked`` without a vertex.
        NonFiniteError: NaN or Inf in ``tracked``.
        TypeError: ``tracked`` not a tensor, ``distorted`` not a sequence, ``normal_steps`` not an int.
        ValueError: a negative ``normal_steps``; ``faces`` outside the tracked vertices (``IndexRangeError``).

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> points = torch.as_tensor(sphere.vertices)[None] * 1.5
        >>> onto = carry_onto([sphere], points)
        >>> round(float(onto.norm(dim=-1).max()), 6)  # on the unit sphere's facets
        1.0
    """
    check_tensor(tracked, "tracked", "a torch.Tensor of shape (F, V, 3)")
    if tracked.dim() != 3 or tracked.shape[-1] != 3:
        raise ShapeError(f"tracked: expected a tensor of shape (F, V, 3), found {tuple(tracked.shape)}")
    # tracked's own faults under its own name: they surfaced as the distorted verts' dtype (cast to tracked's) or as
    # MeshIndex's "points" (found by review).
    check_float(tracked, "tracked")
    if tracked.shape[1] == 0:
        raise EmptyInputError(f"tracked: expected at least one vertex, found shape {tuple(tracked.shape)}")
    check_finite(tracked, "tracked")
    if isinstance(distorted, (str, bytes)) or not isinstance(distorted, Sequence):
        raise TypeError(f"distorted: expected a sequence of meshes, found {type(distorted).__name__}")
    if len(distorted) != tracked.shape[0]:
        raise ShapeError(f"distorted: expected {tracked.shape[0]} frame(s) (those of tracked), found {len(distorted)}")
    normal_steps = check_int(normal_steps, "normal_steps", low=0)
    if faces is not None:
        faces = check_faces_of(faces, tracked.shape[1])
    out = []
    for k, frame in enumerate(distorted):
        mesh = as_mesh(frame, name=f"distorted[{k}]")
        verts = mesh.verts.to(tracked.device, tracked.dtype)
        mesh_faces = mesh.faces.to(tracked.device)
        x = tracked[k].detach()
        normal, q, on_line = None, x, torch.zeros_like(x[:, 0], dtype=torch.bool)
        band = torch.zeros(0, dtype=torch.long, device=x.device)  # the vertices between a line and no line
        with torch.no_grad():
            index = MeshIndex(verts.detach(), mesh_faces, backend=backend, tree="morton")  # a few queries: cheap build
            near = hit = index.point_mesh_distance(x)
            if faces is not None and normal_steps:
                tracked_faces = faces.to(tracked.device)
                normal, weight = _line_normals(x, tracked_faces)
                band = torch.nonzero((weight > 0) & (weight < 1)).flatten()
                scale = _edge_scale(x, tracked_faces)
                hit, q, on_line = _along_normal(index, verts.detach(), mesh_faces, x, normal, scale, hit, normal_steps)
        corners = verts[mesh_faces[hit.face_idx]]  # (V, 3, 3)
        blend = (hit.bary.to(verts.dtype)[..., None] * corners).sum(1)
        if band.numel():  # weight of the line's point, the rest the closest point's (_line_normals)
            near_corners = verts[mesh_faces[near.face_idx[band]]]
            near_bary = near.bary[band].to(verts.dtype)
            blend = _mix(blend, band, weight[band], (near_bary[..., None] * near_corners).sum(1))
        if not (torch.is_grad_enabled() and verts.requires_grad):
            out.append(blend)
            continue
        # The value is the exact query's; its derivative that of the point the definition names. The blend with its
        # barycentric coordinates held fixed moved the point with the face's vertices along the surface too: its
        # gradient was off by up to 2x (found by review: STED_s 1.4x, KG 0.34x, against finite differences).
        point = _carried_point(q, corners, hit.bary.to(verts.dtype), normal, on_line)
        if band.numel():
            none = torch.zeros_like(band, dtype=torch.bool)
            closest = _carried_point(x[band], near_corners, near_bary, None, none)
            point = _mix(point, band, weight[band], closest)
        out.append(blend.detach() + (point - point.detach()))
    return torch.stack(out)


def registered_pair(
    original: Sequence[MeshLike],
    distorted: Sequence[MeshLike],
    *,
    registrations: Sequence[CachedRegistration] | None = None,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    registration_cache: RegistrationCache | None = None,
    device: torch.device | str | None = None,
    backend: str = "auto",
    normal_steps: int = DEFAULT_NORMAL_STEPS,
    weld: float = DEFAULT_WELD,
) -> RegisteredPair:
    """Both sequences on the tracked original's vertices: the input of KG, KSO and STED (module docstring).

    Args:
        original: the ``F >= 2`` original frames (any connectivity each).
        distorted: the ``F`` distorted frames (any connectivity each).
        registrations: the ``F - 1`` registrations when already computed (see :func:`track_original`).
        registration_fn: registration function (default: the library's non-rigid registration).
        registration_options: options of the default registration (part of the cache key).
        registration_cache: a :class:`~torchmeshmetric.registration.RegistrationCache` (``None``: no cache).
        device: where the registration and the tracking run.
        backend: kernel backend of the registration and of the closest-point queries.
        normal_steps: steps along the normal when carrying the distorted frames (see :func:`carry_onto`).
        weld: frame 0's short edges welded before tracking (see :func:`track_original`).

    Returns:
        :class:`RegisteredPair`; ``kg_error(p.original, p.distorted)`` and ``sted(p.original, p.distorted, p.faces)``
        are the registered figures.

    Raises:
        ShapeError: fewer than 2 frames, or frame counts that differ.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.temporal import kg_error
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> finer = trimesh.creation.icosphere(subdivisions=3)  # the same surface, another connectivity
        >>> p = registered_pair([sphere, sphere], [finer, finer], registration_fn=lambda s, t: s)
        >>> float(kg_error(p.original, p.distorted)) < 2.0  # only the facets differ
        True
    """
    originals = _frames(original, "original")
    distorteds = _frames(distorted, "distorted")
    if len(originals) != len(distorteds):
        raise ShapeError(f"distorted: expected {len(originals)} frame(s) (those of original), found {len(distorteds)}")
    tracking = track_original(
        originals,
        registrations=registrations,
        registration_fn=registration_fn,
        registration_options=registration_options,
        registration_cache=registration_cache,
        device=device,
        backend=backend,
        weld=weld,
    )
    carried = carry_onto(distorteds, tracking.verts, tracking.faces, normal_steps=normal_steps, backend=backend)
    return RegisteredPair(tracking.verts, carried, tracking.faces, tracking)
