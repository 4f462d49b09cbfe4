"""Exact closest-face and nearest-point selection by a Triton BVH traversal (CUDA; CPU only in Triton's interpreter).

Tree: :func:`~torchmeshmetric.kernels.accel.lbvh.build_implicit_bvh` (Morton order, complete binary tree in heap
order, built with torch ops on the device). Queries are sorted along a Morton curve (neighbouring lanes walk
similar paths) and each program of the kernel traverses the trees for ``BLOCK`` queries, one lane per query, all
state in registers:

- **stackless ordered traversal with a bit trail**: at an inner node a lane computes the box distances of both
  children, goes to the nearer one (the left one on equal distances) and, when the farther one is also within the
  bound, sets the bit of the child depth in its ``trail``. To backtrack it takes the deepest set bit ``h``, clears
  it and jumps to the sibling of its ancestor at depth ``h`` (``(node >> (depth - h)) ^ 1`` on heap indices),
  whose box is tested again against the (possibly smaller) current bound. A lane is done when its trail is empty;
  the program loops while any lane is active.
- **exact leaf tests**: the squared point-triangle distance uses exactly the floating-point operations, in the
  same order and dtype, of ``region_candidates`` (``kernels/triangle.py``) and of ``tri_sq_dist`` in ``bvh.cpp``;
  the per-face terms that do not depend on the query (``n = ab x ac``, ``n.n``, ``ab.ab``, ``ac.ac``, ``bc.bc``)
  are computed by the very torch expressions of the brute force. Divisions and square roots are IEEE
  round-to-nearest (``div_rn`` / ``sqrt_rn`` in float32) and kernels are compiled with ``enable_fp_fusion=False``
  (no FMA contraction), so the computed squared distance is the brute-force value and the selected face is the
  brute-force argmin, lowest index among equal values.
- **certified pruning**: a node is skipped only when its box distance exceeds
  ``(sqrt(best) (1 + 64 eps) + 64 eps scale)^2`` (``prune_bound`` / ``item_slack`` in ``bvh.cpp``).
- **nearest points**: selection by the computed squared distance ``(dx*dx + dy*dy) + dz*dz`` (the brute force's
  value), lowest index among equal squares, as every backend.

Triton is optional: this module imports it at the top and is itself imported only when the ``"triton"`` backend
runs. Kernels are compiled for CUDA tensors, or run by Triton's interpreter when ``TRITON_INTERPRET=1`` was set
before ``triton`` was first imported (the CPU-testable path; slow, for tests): Triton fixes the mode at import,
for its own library functions too.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import DeviceError, DTypeError
from torchmeshmetric.kernels._common import cross, dot
from torchmeshmetric.kernels.accel.lbvh import ImplicitBVH, build_implicit_bvh, morton_codes, refit_implicit_bvh

try:
    import triton
    import triton.language as tl
except ImportError:  # the library works without triton; this module then only imports (for doctest collection)
    triton = None
    tl = None

__all__ = [
    "LEAF_FACES",
    "LEAF_POINTS",
    "TritonStructure",
    "build_faces",
    "build_points",
    "query_faces",
    "query_points",
    "refit_faces",
    "refit_points",
]

LEAF_FACES = 4
"""Faces per leaf (as ``bvh.cpp``; not tuned on a GPU)."""

LEAF_POINTS = 8
"""Reference points per leaf (as ``bvh.cpp``; not tuned on a GPU)."""

BLOCK_GPU = 32
"""Queries per program on a GPU: one warp (``num_warps=1``), so a program waits only for its own slowest lane."""

BLOCK_INTERPRETED = 1024
"""Queries per program in the interpreter, where every tensor operation costs a Python call."""

LEAF_VECTOR_GPU = False
"""On a GPU, the faces of a leaf are tested one after the other: fewer registers, no layout conversions."""

LEAF_VECTOR_INTERPRETED = True
"""In the interpreter, all faces of a leaf at once (a ``(BLOCK, LEAF)`` tile): fewer Python calls. Tests run both."""

_FACE_FIELDS = tl.constexpr(22) if tl else 22  # a(3) b(3) ab(3) ac(3) bc(3) n(3) nn ab.ab ac.ac bc.bc
_SLACK_ULPS = 64.0
_NO_INDEX = tl.constexpr(2**62) if tl else 2**62  # larger than any primitive index


# ----------------------------------------------------------------------------------------------- kernels
# Decorated at import: Triton fixes the execution mode (compiled or interpreted) when it is first imported, for its
# own library functions too, so the kernels follow the same mode (see `interpreting`).


def _jit(fn: Any) -> Any:
    return triton.jit(fn) if triton else fn


@_jit
def _load3(ptr, mask):  # type: ignore[no-untyped-def]
    """The three values at ``ptr``, ``ptr + 1``, ``ptr + 2`` (0 where masked off)."""
    return (
        tl.load(ptr, mask=mask, other=0.0),
        tl.load(ptr + 1, mask=mask, other=0.0),
        tl.load(ptr + 2, mask=mask, other=0.0),
    )


@_jit
def _box_sq(nodes_ptr, row, mask, px, py, pz):  # type: ignore[no-untyped-def]
    """Squared distance from the query to the box of node ``row`` and whether the box is non-empty."""
    r = nodes_ptr + 6 * row
    lx, ly, lz = _load3(r, mask)
    hx, hy, hz = _load3(r + 3, mask)
    ex = tl.maximum(tl.maximum(lx - px, 0.0), px - hx)
    ey = tl.maximum(tl.maximum(ly - py, 0.0), py - hy)
    ez = tl.maximum(tl.maximum(lz - pz, 0.0), pz - hz)
    return ex * ex + ey * ey + ez * ez, lx <= hx


@_jit
def _traversal_step(  # type: ignore[no-untyped-def]
    nodes_ptr, nbase, node, dep, trail, check, active, inner, bound, px, py, pz
):
    """One step of the stackless ordered traversal for every lane; returns ``(node, dep, trail, check, active)``.

    ``inner`` lanes at an inner node descend to the nearer child whose box passes the bound (the left one on equal
    distances) and mark the farther one pending in ``trail`` (bit = its depth) when it passes too; every other
    active lane backtracks to the sibling of its ancestor at the deepest pending depth (box tested again at the
    next step: ``check``), or finishes when nothing is pending.
    """
    left = nbase + 2 * node
    dl, full_l = _box_sq(nodes_ptr, left, inner, px, py, pz)
    dr, full_r = _box_sq(nodes_ptr, left + 1, inner, px, py, pz)
    ok_l = inner & (dl <= bound) & full_l
    ok_r = inner & (dr <= bound) & full_r
    left_first = dl <= dr
    ok_near = tl.where(left_first, ok_l, ok_r)
    ok_far = tl.where(left_first, ok_r, ok_l)
    descend = ok_near | ok_far
    child = 2 * node + tl.where(ok_near == left_first, 0, 1).to(tl.int64)
    push = (ok_near & ok_far).to(tl.int32) << (dep + 1)
    # Deepest pending depth h = floor(log2(trail)), by binary search (integer only).
    h = tl.zeros_like(dep)
    t = trail
    for k in tl.static_range(4):  # unrolled at compile time: halves of 16, 8, 4 and 2 bits
        s = (t >= (1 << (16 >> k))).to(tl.int32) * (16 >> k)
        h += s
        t = t >> s
    h += (t >= 2).to(tl.int32)
    jump = active & (descend == 0) & (trail != 0)
    sibling = (node >> (dep - h).to(tl.int64)) ^ 1
    node = tl.where(descend, child, tl.where(jump, sibling, node))
    trail = tl.where(descend, trail | push, tl.where(jump, trail ^ (tl.full(h.shape, 1, tl.int32) << h), trail))
    dep = tl.where(descend, dep + 1, tl.where(jump, h, dep))
    check = tl.where(descend, 0, tl.where(jump, 1, check.to(tl.int32))) != 0
    active = active & (descend | jump)
    return node, dep, trail, check, active


@_jit
def _tri_sq_dist(f, m, qx, qy, qz, IS_F64: tl.constexpr):  # type: ignore[no-untyped-def]
    """Squared distance from the query to the face record at ``f``: the operations of ``region_candidates``."""
    ax, ay, az = _load3(f, m)
    bx, by, bz = _load3(f + 3, m)
    abx, aby, abz = _load3(f + 6, m)
    acx, acy, acz = _load3(f + 9, m)
    bcx, bcy, bcz = _load3(f + 12, m)
    nx, ny, nz = _load3(f + 15, m)
    nn, abab, acac = _load3(f + 18, m)
    bcbc = tl.load(f + 21, mask=m, other=0.0)
    apx = qx - ax
    apy = qy - ay
    apz = qz - az
    bpx = qx - bx
    bpy = qy - by
    bpz = qz - bz
    # safe_div(num, den).clamp(0, 1): num / where(den > 0, den, 1), 0 where den <= 0.
    num_ab = apx * abx + apy * aby + apz * abz
    num_ac = apx * acx + apy * acy + apz * acz
    num_bc = bpx * bcx + bpy * bcy + bpz * bcz
    den_ab = tl.where(abab > 0, abab, 1.0)
    den_ac = tl.where(acac > 0, acac, 1.0)
    den_bc = tl.where(bcbc > 0, bcbc, 1.0)
    den_nn = tl.where(nn > 0, nn, 1.0)
    # dot(cross(ap, ac), n) and dot(cross(ab, ap), n)
    c1 = (apy * acz - apz * acy) * nx + (apz * acx - apx * acz) * ny + (apx * acy - apy * acx) * nz
    c2 = (aby * apz - abz * apy) * nx + (abz * apx - abx * apz) * ny + (abx * apy - aby * apx) * nz
    if IS_F64:  # float64 division is IEEE round-to-nearest on every backend
        t_ab = num_ab / den_ab
        t_ac = num_ac / den_ac
        t_bc = num_bc / den_bc
        v = c1 / den_nn
        w = c2 / den_nn
    else:  # float32 '/' may be approximate on a GPU: ask for div.rn
        t_ab = tl.math.div_rn(num_ab, den_ab)
        t_ac = tl.math.div_rn(num_ac, den_ac)
        t_bc = tl.math.div_rn(num_bc, den_bc)
        v = tl.math.div_rn(c1, den_nn)
        w = tl.math.div_rn(c2, den_nn)
    t_ab = tl.minimum(tl.maximum(tl.where(abab > 0, t_ab, 0.0), 0.0), 1.0)
    t_ac = tl.minimum(tl.maximum(tl.where(acac > 0, t_ac, 0.0), 0.0), 1.0)
    t_bc = tl.minimum(tl.maximum(tl.where(bcbc > 0, t_bc, 0.0), 0.0), 1.0)
    v = tl.where(nn > 0, v, 0.0)
    w = tl.where(nn > 0, w, 0.0)
    dx = apx - t_ab * abx
    dy = apy - t_ab * aby
    dz = apz - t_ab * abz
    sq = dx * dx + dy * dy + dz * dz
    dx = apx - t_ac * acx
    dy = apy - t_ac * acy
    dz = apz - t_ac * acz
    sq = tl.minimum(sq, dx * dx + dy * dy + dz * dz)
    dx = bpx - t_bc * bcx
    dy = bpy - t_bc * bcy
    dz = bpz - t_bc * bcz
    sq = tl.minimum(sq, dx * dx + dy * dy + dz * dz)
    inside = (nn > 0) & (v >= 0) & (w >= 0) & (1 - v - w >= 0)  # as kernels/triangle.py: u >= 0 as computed
    dx = (apx - v * abx) - w * acx
    dy = (apy - v * aby) - w * acy
    dz = (apz - v * abz) - w * acz
    return tl.where(inside, tl.minimum(sq, dx * dx + dy * dy + dz * dz), sq)


@_jit
def _point_sq_dist(r, m, qx, qy, qz):  # type: ignore[no-untyped-def]
    """Squared distance from the query to the reference point at ``r``: ``(dx*dx + dy*dy) + dz*dz``."""
    rx, ry, rz = _load3(r, m)
    dx = qx - rx
    dy = qy - ry
    dz = qz - rz
    return dx * dx + dy * dy + dz * dz


@_jit
def _slot_sq_dist(  # type: ignore[no-untyped-def]
    data_ptr, slot, m, qx, qy, qz, IS_FACE: tl.constexpr, IS_F64: tl.constexpr
):
    """Squared distance from the query to the primitive record of ``slot`` (a face or a reference point)."""
    if IS_FACE:
        sq = _tri_sq_dist(data_ptr + _FACE_FIELDS * slot, m, qx, qy, qz, IS_F64)
    else:
        sq = _point_sq_dist(data_ptr + 3 * slot, m, qx, qy, qz)
    return sq


@_jit
def _selection_kernel(  # type: ignore[no-untyped-def]
    pts_ptr,
    order_ptr,
    qitem_ptr,
    nodes_ptr,
    data_ptr,
    prims_ptr,
    node_base_ptr,
    slot_base_ptr,
    depth_ptr,
    slack_ptr,
    first_ptr,
    factor_ptr,
    out_ptr,
    num_queries,
    LEAF: tl.constexpr,
    BLOCK: tl.constexpr,
    IS_F64: tl.constexpr,
    LEAF_VECTOR: tl.constexpr,
    IS_FACE: tl.constexpr,
):
    """Per query, the primitive (``IS_FACE``: face, else reference point) of least computed squared distance.

    ``data_ptr`` holds one record per leaf slot: the face fields of :func:`_face_records` or the point.
    """
    lane = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
    valid = lane < num_queries
    q = tl.load(order_ptr + lane, mask=valid, other=0)
    px = tl.load(pts_ptr + 3 * q, mask=valid, other=0.0)
    py = tl.load(pts_ptr + 3 * q + 1, mask=valid, other=0.0)
    pz = tl.load(pts_ptr + 3 * q + 2, mask=valid, other=0.0)
    item = tl.load(qitem_ptr + q, mask=valid, other=0)
    nbase = tl.load(node_base_ptr + item, mask=valid, other=0)
    sbase = tl.load(slot_base_ptr + item, mask=valid, other=0)
    dmax = tl.load(depth_ptr + item, mask=valid, other=0).to(tl.int32)
    slack = tl.load(slack_ptr + item, mask=valid, other=0.0)
    best_idx = tl.load(first_ptr + item, mask=valid, other=0)
    factor = tl.load(factor_ptr)  # 1 + 64 eps in the working dtype
    inf = px * 0.0 + float("inf")
    best = inf  # squared distance of the best primitive, the comparison key
    bound = inf
    node = tl.full([BLOCK], 1, tl.int64)
    dep = tl.zeros([BLOCK], tl.int32)
    trail = tl.zeros([BLOCK], tl.int32)
    check = valid  # the root's box is tested like a node reached by backtracking
    active = valid
    while tl.max(active.to(tl.int32), axis=0) > 0:
        # Box test of a node reached by backtracking (its parent passed an older, larger bound).
        bd, full = _box_sq(nodes_ptr, nbase + node, active & check, px, py, pz)
        alive = active & ((check == 0) | ((bd <= bound) & full))
        is_leaf = alive & (dep == dmax)
        # Leaf: exact squared distance to each primitive; lexicographic minimum of (squared distance, index).
        first_slot = sbase + (node - (tl.full([BLOCK], 1, tl.int64) << dmax.to(tl.int64))) * LEAF
        if LEAF_VECTOR:  # all primitives of the leaf at once, (BLOCK, LEAF): fewer operations in the interpreter
            slot = first_slot[:, None] + tl.arange(0, LEAF)[None, :]
            pid = tl.load(prims_ptr + slot, mask=is_leaf[:, None], other=-1)
            m = is_leaf[:, None] & (pid >= 0)
            sq = _slot_sq_dist(data_ptr, slot, m, px[:, None], py[:, None], pz[:, None], IS_FACE, IS_F64)
            sq = tl.where(m, sq, float("inf"))
            leaf_sq = tl.min(sq, axis=1)
            leaf_id = tl.min(tl.where(m & (sq == leaf_sq[:, None]), pid, _NO_INDEX), axis=1)
            better = (leaf_sq < best) | ((leaf_sq == best) & (leaf_id < best_idx))
            best = tl.where(better, leaf_sq, best)
            best_idx = tl.where(better, leaf_id, best_idx)
        else:  # one primitive after the other, (BLOCK,): no layout conversion, fewer registers on a GPU
            for j in range(LEAF):  # a loop, not unrolled: half the registers on a GPU
                slot = first_slot + j
                pid = tl.load(prims_ptr + slot, mask=is_leaf, other=-1)
                m = is_leaf & (pid >= 0)
                sq = _slot_sq_dist(data_ptr, slot, m, px, py, pz, IS_FACE, IS_F64)
                better = m & ((sq < best) | ((sq == best) & (pid < best_idx)))
                best = tl.where(better, sq, best)
                best_idx = tl.where(better, pid, best_idx)
        # Certified pruning bound (prune_bound in bvh.cpp).
        root = tl.sqrt(best) if IS_F64 else tl.sqrt_rn(best)
        r = root * factor + slack
        bound = tl.where(best < inf, r * r, best)
        node, dep, trail, check, active = _traversal_step(
            nodes_ptr, nbase, node, dep, trail, check, active, alive & (dep < dmax), bound, px, py, pz
        )
    tl.store(out_ptr + q, best_idx, mask=valid)


# ----------------------------------------------------------------------------------------------- launching


def interpreting() -> bool:
    """Whether this process runs Triton kernels in Triton's interpreter.

    Triton decides when it is first imported (``TRITON_INTERPRET=1`` in the environment at that time) and
    decorates its own library functions (``tl.max``, ``tl.min``) accordingly, so the mode cannot change later.
    """
    return not isinstance(tl.max, triton.runtime.jit.JITFunction)


def _mode(points: Tensor) -> bool:
    """``True`` for the interpreter; raises on a dtype or a device the kernels cannot run on."""
    if triton is None:
        raise ImportError("backend='triton' needs the optional triton package (pip install triton)")
    if points.dtype not in (torch.float32, torch.float64):
        raise DTypeError(f"points: backend='triton' expects float32 or float64, found {points.dtype}")
    if interpreting():
        return True
    if points.device.type != "cuda":
        raise DeviceError(
            f"points: backend='triton' runs on CUDA tensors, found device {points.device.type!r}; on the CPU use "
            "backend='bvh' (or run Triton's slow interpreter, for tests: TRITON_INTERPRET=1 set before triton is "
            "first imported)"
        )
    return False


def _item_slack(lo: Tensor, hi: Tensor, batch: Tensor, num_items: int) -> Tensor:
    """Per-item absolute slack ``64 eps max|coordinate|`` (``item_slack`` in ``bvh.cpp``), ``(B,)``."""
    mag = torch.maximum(lo.abs(), hi.abs()).amax(-1)
    if num_items == 1:
        scale = mag.amax()[None] if mag.numel() else mag.new_zeros(1)
    else:
        scale = mag.new_zeros(num_items).scatter_reduce(0, batch, mag, "amax")
    return scale * (_SLACK_ULPS * torch.finfo(lo.dtype).eps)


def _query_order(points: Tensor, point_batch: Tensor, num_items: int) -> Tensor:
    """Queries sorted by item, then along a Morton curve within the item (coherent lanes)."""
    code = morton_codes(points, point_batch, num_items)
    key = code if num_items == 1 else point_batch * (1 << 30) + code
    return torch.sort(key, stable=True).indices


def _launch(
    name: str,
    points: Tensor,
    point_batch: Tensor,
    tree: ImplicitBVH,
    prim_data: Tensor,
    slack: Tensor,
    first: Tensor,
    interpret: bool,
) -> Tensor:
    num_items = first.numel()
    num_p = points.shape[0]
    out = torch.empty(num_p, dtype=torch.long, device=points.device)
    if num_p == 0:
        return out
    order = _query_order(points, point_batch, num_items)
    # 1 + 64 eps, exact in the working dtype (a power-of-two ulp count); filled on the device, no host copy.
    one_plus = 1.0 + _SLACK_ULPS * torch.finfo(points.dtype).eps
    factor = torch.full((1,), one_plus, dtype=points.dtype, device=points.device)
    block = BLOCK_INTERPRETED if interpret else BLOCK_GPU
    grid = (triton.cdiv(num_p, block),)
    _selection_kernel[grid](
        points.contiguous(),
        order,
        point_batch.long().contiguous(),
        tree.nodes,
        prim_data.contiguous(),
        tree.prims,
        tree.node_base,
        tree.slot_base,
        tree.depth,
        slack,
        first.long().contiguous(),
        factor,
        out,
        num_p,
        LEAF=tree.leaf_size,
        BLOCK=block,
        IS_F64=points.dtype == torch.float64,
        LEAF_VECTOR=LEAF_VECTOR_INTERPRETED if interpret else LEAF_VECTOR_GPU,
        IS_FACE=name == "face",
        num_warps=1,
        enable_fp_fusion=False,
    )
    return out


class TritonStructure(NamedTuple):
    """A kept implicit BVH with its per-slot primitive records and per-item slack (see :func:`build_faces`)."""

    tree: ImplicitBVH
    data: Tensor
    slack: Tensor


def _face_records(verts: Tensor, faces: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Face boxes ``(lo, hi)`` and per-face records, computed by the brute force's own expressions."""
    tri = verts[faces]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, bc = b - a, c - a, c - b
    n = cross(ab, ac)
    data = torch.cat([a, b, ab, ac, bc, n, torch.stack([dot(n, n), dot(ab, ab), dot(ac, ac), dot(bc, bc)], -1)], -1)
    return tri.amin(1), tri.amax(1), data


def _kept(tree: ImplicitBVH, lo: Tensor, hi: Tensor, batch: Tensor, offsets: Tensor, data: Tensor) -> TritonStructure:
    """The structure of ``tree`` over primitives with boxes ``lo``/``hi`` and per-primitive records ``data``."""
    real = tree.prims >= 0
    slots = torch.where(real[:, None], data[tree.prims.clamp_min(0)], torch.zeros_like(data[:1]))
    return TritonStructure(tree, slots, _item_slack(lo, hi, batch, offsets.numel() - 1))


def _query(kind: str, structure: TritonStructure, points: Tensor, point_batch: Tensor, offsets: Tensor) -> Tensor:
    interpret = _mode(points)
    return _launch(kind, points, point_batch, structure.tree, structure.data, structure.slack, offsets[:-1], interpret)


def build_faces(verts: Tensor, faces: Tensor, face_batch: Tensor, face_offsets: Tensor) -> TritonStructure:
    """Kept face structure of centred faces (global indices into ``verts``).

    Raises:
        DeviceError: on non-CUDA tensors unless ``TRITON_INTERPRET=1``.
        DTypeError: for dtypes other than float32 / float64.
    """
    _mode(verts)
    lo, hi, data = _face_records(verts, faces)
    tree = build_implicit_bvh(lo, hi, face_batch, face_offsets, LEAF_FACES)
    return _kept(tree, lo, hi, face_batch, face_offsets, data)


def refit_faces(
    structure: TritonStructure, verts: Tensor, faces: Tensor, face_batch: Tensor, face_offsets: Tensor
) -> TritonStructure:
    """The same tree with boxes, records and slack of moved vertices (no new Morton order)."""
    lo, hi, data = _face_records(verts, faces)
    return _kept(refit_implicit_bvh(structure.tree, lo, hi), lo, hi, face_batch, face_offsets, data)


def query_faces(structure: TritonStructure, points: Tensor, point_batch: Tensor, face_offsets: Tensor) -> Tensor:
    """Closest face per centred point through a kept structure, exact, lowest index on ties."""
    return _query("face", structure, points, point_batch, face_offsets)


def build_points(ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor) -> TritonStructure:
    """Kept point structure of centred reference points."""
    _mode(ref)
    tree = build_implicit_bvh(ref, ref, ref_batch, ref_offsets, LEAF_POINTS)
    return _kept(tree, ref, ref, ref_batch, ref_offsets, ref)


def refit_points(structure: TritonStructure, ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor) -> TritonStructure:
    """The same tree with boxes, slot points and slack of moved reference points."""
    return _kept(refit_implicit_bvh(structure.tree, ref, ref), ref, ref, ref_batch, ref_offsets, ref)


def query_points(structure: TritonStructure, points: Tensor, point_batch: Tensor, ref_offsets: Tensor) -> Tensor:
    """Nearest reference row per centred point through a kept structure, exact, lowest index on ties."""
    return _query("nearest", structure, points, point_batch, ref_offsets)
