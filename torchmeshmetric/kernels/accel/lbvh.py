"""Implicit linear BVH built with a few torch ops on any device (the tree traversed by the Triton backend).

Per item of a ragged batch, the primitives (face boxes, or points) are sorted along a 30-bit Morton curve of their
box centres (as ``bvh.cpp``), then laid out in that order in ``leaf_size`` slots per leaf, leaves filled left to
right and padded to a power of two ``L_b = 2**D_b`` (empty slots: primitive ``-1``; empty leaves: box ``+inf`` /
``-inf``). The tree is the complete binary tree over those leaves in heap order: the node with heap index ``n``
(``1 <= n < 2 L_b``, root ``1``) has children ``2n`` and ``2n + 1`` and depth ``floor(log2 n)``; leaf ``l`` is
node ``L_b + l``. Bounds are reduced level by level with pairwise min/max reshapes: ``D_b`` levels of a handful
of elementwise torch ops each, no Python loop over nodes or items and no data-dependent control flow on the
device, so the build is cheap on a GPU.

Compared with a Karras LBVH (split at the highest differing Morton bit), the object-median split of the Morton
order can straddle a jump of the curve (larger boxes: ``bvh.cpp`` measured ~4x slower queries on the CPU with it),
but it needs no per-node search and makes the tree implicit: no child pointers, a stackless traversal with a bit
trail (see ``triton_traversal.py``), and a build of ``O(log)`` vectorised passes.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

__all__ = ["ImplicitBVH", "build_implicit_bvh", "morton_codes", "refit_implicit_bvh"]


class ImplicitBVH(NamedTuple):
    """A forest of complete binary trees over Morton-sorted primitives, one tree per item.

    Attributes:
        nodes: ``(N, 6)`` node boxes ``[lo_x, lo_y, lo_z, hi_x, hi_y, hi_z]``; the node of item ``b`` with heap
            index ``n`` is row ``node_base[b] + n`` (row ``node_base[b]`` is unused). Empty boxes are
            ``lo = +inf, hi = -inf``.
        prims: ``(S,)`` int64 primitive index (row of the input) of every slot, ``-1`` for padding. Leaf ``l``
            of item ``b`` holds slots ``slot_base[b] + l * leaf_size + [0, leaf_size)``.
        node_base: ``(B,)`` int64 first node row of each item.
        slot_base: ``(B,)`` int64 first slot of each item.
        depth: ``(B,)`` int64 leaf depth ``D_b`` of each item (``2**D_b`` leaves; ``0``: the root is a leaf).
        leaf_size: primitives per leaf.
        levels: the refit's plan for a forest of several items, on the device (``None`` for one item): per level
            ``k`` from the leaves up, the rows of level ``k - 1`` that stay (``None`` where every item does) and the
            node rows level ``k`` fills. Computed once by :func:`build_implicit_bvh` (it reads sizes back to the
            host), so that :func:`refit_implicit_bvh` runs on the device without a host-device synchronisation.
    """

    nodes: Tensor
    prims: Tensor
    node_base: Tensor
    slot_base: Tensor
    depth: Tensor
    leaf_size: int
    levels: tuple[tuple[Tensor | None, Tensor], ...] | None = None


def _spread10(x: Tensor) -> Tensor:
    """Spread the 10 low bits of ``x`` (int64) to every third bit of 30, as ``spread10`` in ``bvh.cpp``."""
    x = x & 0x3FF
    x = (x | (x << 16)) & 0x30000FF
    x = (x | (x << 8)) & 0x300F00F
    x = (x | (x << 4)) & 0x30C30C3
    x = (x | (x << 2)) & 0x9249249
    return x


_SPREAD_TABLES: dict[torch.device, Tensor] = {}


def _spread_table(device: torch.device) -> Tensor:
    """``(1024, 3)`` int64 table: the spread bits of ``q`` for the x, y and z axes (shifted by 2, 1, 0)."""
    if device not in _SPREAD_TABLES:
        spread = _spread10(torch.arange(1024, device=device))
        _SPREAD_TABLES[device] = torch.stack([spread << 2, spread << 1, spread], 1)
    return _SPREAD_TABLES[device]


def _item_bounds(x: Tensor, batch: Tensor, num_items: int) -> tuple[Tensor, Tensor]:
    """Per-item ``(lo, hi)`` ``(B, 3)`` of the rows of ``x``; ``+inf`` / ``-inf`` for empty items."""
    if num_items == 1 and x.shape[0] > 0:
        lo1, hi1 = x.aminmax(dim=0)
        return lo1[None], hi1[None]
    lo = torch.full((num_items, 3), float("inf"), dtype=x.dtype, device=x.device)
    idx = batch[:, None].expand(-1, 3)
    return lo.scatter_reduce(0, idx, x, "amin"), (-lo).scatter_reduce(0, idx, x, "amax")


def morton_codes(x: Tensor, batch: Tensor, num_items: int) -> Tensor:
    """30-bit Morton codes of the rows of ``x`` ``(N, 3)`` within the bounding box of their item.

    Same quantisation as ``bvh.cpp``: ``min(max((x - lo) * 1023.99 / (hi - lo), 0), 1023)`` per axis (``0`` on a
    flat axis), bits interleaved ``x, y, z`` from the most significant.

    Args:
        x: ``(N, 3)`` float positions.
        batch: ``(N,)`` int64 item of each row.
        num_items: number of items ``B``.

    Returns:
        ``(N,)`` int64 codes in ``[0, 2**30)``.

    Example:
        >>> import torch
        >>> x = torch.tensor([[0.0, 0, 0], [1.0, 1, 1], [1.0, 0, 0]])
        >>> morton_codes(x, torch.zeros(3, dtype=torch.long), 1).tolist()
        [0, 1073741823, 613566756]
    """
    lo, hi = _item_bounds(x, batch, num_items)
    ext = hi - lo
    flat = ~(ext > 0)
    inv = torch.where(flat, torch.zeros_like(ext), 1023.99 / torch.where(flat, torch.ones_like(ext), ext))
    q = (x - lo) * inv if num_items == 1 else (x - lo[batch]) * inv[batch]
    q = q.clamp(0, 1023).long()
    # One gather from a table instead of ~30 bit operations (each a kernel launch on a GPU); the bits of the three
    # axes do not overlap, so their sum is their bitwise or.
    return _spread_table(x.device).gather(0, q).sum(1)


def build_implicit_bvh(lo: Tensor, hi: Tensor, batch: Tensor, offsets: Tensor, leaf_size: int) -> ImplicitBVH:
    """Build one implicit complete BVH per item over primitive boxes (see the module comment).

    Args:
        lo: ``(N, 3)`` lower corners of the primitive boxes (for points: the points).
        hi: ``(N, 3)`` upper corners.
        batch: ``(N,)`` int64 item of each primitive; items are contiguous and in order.
        offsets: ``(B + 1,)`` int64 first primitive of each item, ``offsets[-1] == N``.
        leaf_size: primitives per leaf (``>= 1``).

    Returns:
        :class:`ImplicitBVH`; an item without primitives gets a single empty leaf.

    Example:
        >>> import torch
        >>> pts = torch.tensor([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
        >>> t = build_implicit_bvh(pts, pts, torch.zeros(3, dtype=torch.long), torch.tensor([0, 3]), 2)
        >>> t.depth.tolist(), t.prims.tolist(), t.nodes[1].tolist()
        ([1], [0, 1, 2, -1], [0.0, 0.0, 0.0, 5.0, 0.0, 0.0])
    """
    if leaf_size < 1:
        raise ValueError(f"leaf_size: expected a positive number of primitives per leaf, found {leaf_size}")
    device = lo.device
    num_items = offsets.numel() - 1
    lengths = offsets[1:] - offsets[:-1]
    # Host copy of the per-item sizes: the number of levels and of nodes decide tensor shapes.
    leaves_needed = ((lengths + leaf_size - 1) // leaf_size).clamp_min(1).tolist()
    depth_list = [max(0, (int(n) - 1).bit_length()) for n in leaves_needed]
    num_leaves = [1 << d for d in depth_list]
    depth = torch.tensor(depth_list, dtype=torch.long, device=device)
    leaves = torch.tensor(num_leaves, dtype=torch.long, device=device)
    leaf_base = torch.cumsum(leaves, 0) - leaves
    node_base = 2 * leaf_base
    slot_base = leaf_base * leaf_size
    total_leaves = sum(num_leaves)

    # Morton order of the primitives within their item (stable: equal codes keep their index order).
    n = lo.shape[0]
    code = morton_codes(0.5 * (lo + hi), batch, num_items)
    key = code if num_items == 1 else batch * (1 << 30) + code
    order = torch.sort(key, stable=True).indices
    sorted_batch = batch[order]
    rank = torch.arange(n, device=device) - offsets[sorted_batch]
    prims = torch.full((total_leaves * leaf_size,), -1, dtype=torch.long, device=device)
    prims[slot_base[sorted_batch] + rank] = order

    levels = None if num_items == 1 else _level_plan(depth_list, node_base)
    nodes = _node_bounds(prims, lo, hi, leaf_size, levels)
    return ImplicitBVH(nodes, prims, node_base, slot_base, depth, leaf_size, levels)


def refit_implicit_bvh(tree: ImplicitBVH, lo: Tensor, hi: Tensor) -> ImplicitBVH:
    """The same tree (slots, layout) with node boxes recomputed for moved primitive boxes ``lo`` / ``hi``.

    Example:
        >>> import torch
        >>> pts = torch.tensor([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
        >>> t = build_implicit_bvh(pts, pts, torch.zeros(3, dtype=torch.long), torch.tensor([0, 3]), 2)
        >>> refit_implicit_bvh(t, 2 * pts, 2 * pts).nodes[1].tolist()
        [0.0, 0.0, 0.0, 10.0, 0.0, 0.0]
    """
    levels = tree.levels
    if levels is None and tree.depth.numel() > 1:  # a forest built without its plan: make it (host reads)
        levels = _level_plan([int(d) for d in tree.depth.tolist()], tree.node_base)
        tree = tree._replace(levels=levels)
    return tree._replace(nodes=_node_bounds(tree.prims, lo, hi, tree.leaf_size, levels))


def _level_plan(depth_list: list[int], node_base: Tensor) -> tuple[tuple[Tensor | None, Tensor], ...]:
    """:attr:`ImplicitBVH.levels` of a forest of items with leaf depths ``depth_list`` (several items).

    The boolean selections and the per-item counts read sizes back to the host: done once per tree, here.
    """
    device = node_base.device
    num_items = len(depth_list)
    depth = torch.tensor(depth_list, dtype=torch.long, device=device)
    leaves = 1 << depth
    total = sum(1 << d for d in depth_list)
    entry_item = torch.repeat_interleave(torch.arange(num_items, device=device), leaves, output_size=total)
    plan: list[tuple[Tensor | None, Tensor]] = []
    for k in range(max(depth_list) + 1):
        keep = None
        if k > 0:
            if (k - 1) in depth_list:  # items whose root was level k - 1 leave the level arrays
                keep = (depth[entry_item] >= k).nonzero().squeeze(1)
                entry_item = entry_item[keep]
            # Every kept item has an even number of entries at level k - 1, starting at an even position.
            entry_item = entry_item[::2]
        counts = torch.where(depth >= k, leaves >> k, torch.zeros_like(leaves))
        start = torch.cumsum(counts, 0) - counts
        local = torch.arange(entry_item.numel(), device=device) - start[entry_item]
        plan.append((keep, node_base[entry_item] + (leaves[entry_item] >> k) + local))
    return tuple(plan)


def _node_bounds(
    prims: Tensor, lo: Tensor, hi: Tensor, leaf_size: int, levels: tuple[tuple[Tensor | None, Tensor], ...] | None
) -> Tensor:
    """``(N, 6)`` node boxes of the implicit trees whose slots hold ``prims`` (boxes ``lo`` / ``hi``).

    ``levels``: :attr:`ImplicitBVH.levels` (``None`` for one item). Only device work: no value is read back.
    """
    device, dtype = lo.device, lo.dtype
    total_leaves = prims.numel() // leaf_size
    # Leaf boxes, then one pairwise reduction per level. Boxes are held as [lo, -hi] so that one amin reduces both
    # halves (padding: +inf, an empty box); the upper corners are negated back at the end (negation is exact).
    real = prims >= 0
    slot_box = torch.where(real[:, None], torch.cat([lo, -hi], 1)[prims.clamp_min(0)], float("inf"))
    level = slot_box.view(total_leaves, leaf_size, 6).amin(1)
    nodes = torch.full((2 * total_leaves, 6), float("inf"), dtype=dtype, device=device)
    if levels is None:
        width = total_leaves
        while True:
            nodes[width : 2 * width] = level
            if width == 1:
                break
            level = level.view(-1, 2, 6).amin(1)
            width //= 2
    else:
        for k, (keep, rows) in enumerate(levels):
            if k > 0:
                if keep is not None:
                    level = level.index_select(0, keep)
                level = level.view(-1, 2, 6).amin(1)
            nodes[rows] = level
    nodes[:, 3:] = -nodes[:, 3:]
    return nodes
