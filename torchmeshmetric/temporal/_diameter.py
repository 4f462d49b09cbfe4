r"""The farthest pair of a point set, exact and fast on round shapes: STED's diameter ``D`` (:mod:`.sted`).

:func:`farthest_pair` returns the pair that a float64 brute force over all ``V²`` pairs returns: the largest
``((x_i - x_j) ** 2).sum()``, the first in row-major order among ties. Three steps:

1. a lower bound ``L`` (the farthest of the extreme points along 13 directions) and, by the triangle inequality
   through the midpoint ``o`` of its pair, the points that can be in a pair at least ``sqrt(L)`` apart (on a box,
   its corners; on a sphere, all);
2. one point per group of identical points (the smallest index: the tie rule's);
3. a branch and bound over a k-d tree of those, a dual-tree search like Har-Peled's practical diameter (SoCG 2001):
   node pairs are split level by level and dropped once an upper bound of their squared distances falls below the
   best squared distance found; the surviving leaf pairs are compared point by point, in blocks.

Two upper bounds of a node pair, the smaller kept:

* **boxes**: the nodes' axis-aligned boxes, per axis the larger of ``(a_hi - b_lo)²`` and ``(b_hi - a_lo)²``;
* **cones**: seen from ``o``, each node's points lie within a cone of axis :math:`\nu` and half-angle
  :math:`\alpha` and within a distance :math:`\rho` of ``o``, so two points of two nodes make an angle at most
  :math:`\theta = \beta + \alpha_a + \alpha_b` (:math:`\beta` the angle of the axes) and
  :math:`|p - q|^2 \le \rho_a^2 + \rho_b^2 - 2 \rho_a \rho_b \cos\theta`.

Boxes alone prune badly on a sphere: a box of a patch sticks out of the sphere by about its own width, as far as the
patches themselves differ, so every leaf keeps hundreds of partners (1.2 M leaf pairs for 100 000 points on a unit
sphere, 8.9 s, measured). The cone follows the curvature: a leaf keeps the few leaves within its and their own
angular width of its antipode (30 000 leaf pairs, 0.5 s). On other shapes the boxes do most of the pruning.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from torchmeshmetric.kernels._common import dot

__all__ = ["farthest_pair", "squared_distances"]

#: Points per leaf of the tree (measured on 20k to 300k points on a sphere: 8 and 32 within 20 % of 16).
LEAF_SIZE = 16
#: Elements of one block of pairwise differences: bounded memory whatever the number of points.
BLOCK = 2**22
#: Node pairs refined together, so that the traversal's memory is bounded too (a depth-first walk over chunks).
PAIRS = 2**15
#: The prunes' rounding margin, relative to the best squared distance (see :func:`_threshold`).
MARGIN = 2.0**-40
#: The prunes' absolute margin, for squares that underflow (see :func:`_threshold`).
TINY = 2.0**-1000
#: Slack of the cone bound's cosine (see :meth:`_Nodes.upper`).
ANGLE_SLACK = 2.0**-20
#: Nodes whose cone is wider than 60° (cosine below 0.5) use the box bound alone.
CONE_COSINE = 0.5

# Axes, face and body diagonals: the extreme points along them give a first lower bound L of the squared diameter,
# at least D²/3 (the axes' extents alone: D² <= the sum of their squares <= 3 times the largest).
_DIRECTIONS = (
    (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1),
    (1, 1, 1), (1, 1, -1), (1, -1, 1), (-1, 1, 1),
)  # fmt: skip


def squared_distances(a: Tensor, b: Tensor) -> Tensor:
    """``(dx*dx + dy*dy) + dz*dz``, ``d = a - b``: the squared distances of :func:`farthest_pair`, the brute force's.

    Every squared distance the search compares is computed by this one expression, so its values are the brute
    force's, bit for bit (a sum of three terms, in one order: explicit adds, not a ``.sum(-1)`` reduction, whose
    order is the device's choice and differs on CUDA, see ``kernels._common.dot``).

    Args:
        a: ``(..., 3)`` points.
        b: ``(..., 3)`` points, broadcastable with ``a``.

    Returns:
        ``(...)`` the squared distances, in their dtype.

    Example:
        >>> squared_distances(torch.tensor([[0.0, 0, 0]]), torch.tensor([[1.0, 2, 2]])).tolist()
        [9.0]
    """
    d = a - b
    return dot(d, d)


def _threshold(lower: float) -> float:
    """The smallest upper bound a node pair may have and still hold a pair at squared distance ``>= lower``.

    Every bound and every squared distance here is computed in float64 from coordinates whose differences are at
    most a few ``D`` (``D`` the diameter; the centre ``o`` lies within ``D`` of every point), by a few dozen
    operations, each rounded to 2^-53 of its result: a bound is at most a few hundred ulps of ``D²`` below its
    exact value, a squared distance as much above. ``lower`` is a squared distance the search has computed, at
    least ``D²/3``, so the margin 2^-40 ``lower`` (2^13 ulps of ``lower``, over 2 700 ulps of ``D²``) covers them.
    Underflow (coordinates below ~1e-154) adds at most a few 2^-1074 per square (and a product of two radii of
    which one underflowed at most 2^-1028 more): the absolute 2^-1000 covers those. A ``lower`` that overflowed
    (coordinates above ~1e154) gives NaN, and every comparison is written ``~(bound < threshold)``: all kept.
    """
    return lower - MARGIN * lower - TINY


def _candidates(x: Tensor) -> tuple[float, Tensor, Tensor]:
    """A first lower bound ``L`` of the largest squared distance, the cones' apex, and the points that can reach ``L``.

    Returns:
        ``L`` (a squared distance between two of the points), the ``(3,)`` apex ``o`` and the ``(C,)`` increasing
        indices of the points that can belong to a pair at squared distance ``>= L``.
    """
    proj = x @ torch.tensor(_DIRECTIONS, dtype=x.dtype, device=x.device).T
    ext = torch.unique(torch.cat([proj.argmax(0), proj.argmin(0)]))
    d2 = squared_distances(x[ext][:, None], x[ext][None])
    flat = int(d2.argmax())
    i, j = ext[flat // ext.shape[0]], ext[flat % ext.shape[0]]
    lower = float(d2.flatten()[flat])
    # The apex: the middle of a long pair, near the centre of a round shape (a shape's box centre is not: three
    # quarters of a sphere kept 14x more leaf pairs around it, measured).
    centre = x[i] + 0.5 * (x[j] - x[i])
    # A pair at least sqrt(L) apart has r_i + r_j >= sqrt(L) (r the distance to the apex, triangle inequality), so
    # only points with r >= sqrt(L) - max(r) can be in it: on a box, its corners. The margin 2^-40 (sqrt(L) + max r)
    # covers the few ulps of those figures' rounding, 2^-500 the norms that underflow; a threshold that overflowed
    # to NaN keeps every point.
    r = torch.linalg.vector_norm(x - centre, dim=1)
    root, largest = math.sqrt(lower), float(r.max())
    keep = ~(r < root - largest - MARGIN * (root + largest) - 2.0**-500)
    return lower, centre, torch.nonzero(keep).flatten()


def _distinct(x: Tensor, index: Tensor) -> Tensor:
    """The smallest of ``index`` (increasing) of each group of the points ``x[index]`` with the same bits.

    Duplicates cost a tree search nothing to drop and everything to keep: points piled on the corners of a box tie
    by the thousand (every pair of opposite corners), and no bound can drop one of them.
    """
    bits = x[index].view(torch.int64)
    order = torch.argsort(bits[:, 2], stable=True)
    for k in (1, 0):  # a stable lexicographic sort: the first point of a group is its smallest index
        order = order[torch.argsort(bits[order, k], stable=True)]
    sorted_bits = bits[order]
    new = torch.ones(order.shape[0], dtype=torch.bool, device=x.device)
    new[1:] = (sorted_bits[1:] != sorted_bits[:-1]).any(1)
    return index[order[new]]


class _Nodes:
    """The bounds' data of the nodes ``active`` of one level of the tree (other rows unused).

    Args:
        blocks: ``(N, S, 3)`` the level's nodes, ``S`` points each.
        active: ``(A,)`` the nodes whose data is computed.
        centre: ``(3,)`` the cones' apex ``o``.
    """

    def __init__(self, blocks: Tensor, active: Tensor, centre: Tensor) -> None:
        pts = blocks[active]
        rel = pts - centre
        zero = (rel == 0).all(-1)  # at the apex: no direction, and any angle bounds |p - q| (|p - o| = 0)
        norm = torch.linalg.vector_norm(rel, dim=-1)
        # A norm below 2^-500 may have lost digits to underflow: its direction is not trusted (no cone).
        trusted = norm >= 2.0**-500
        unit = rel / torch.where(trusted, norm, 1.0)[..., None]
        axis = unit.sum(1)
        axis = axis / torch.linalg.vector_norm(axis, dim=-1, keepdim=True).clamp_min(2.0**-500)
        dots = (unit * axis[:, None, :]).sum(-1)
        cos = torch.where(zero, 1.0, torch.where(trusted, dots, -1.0)).amin(1)
        rows = blocks.shape[0]

        def full(value: Tensor) -> Tensor:
            out = value.new_zeros((rows, *value.shape[1:]))
            out[active] = value
            return out

        self.lo, self.hi = full(pts.amin(1)), full(pts.amax(1))
        self.axis, self.cos = full(axis), full(cos)
        self.sin = (1.0 - self.cos * self.cos).clamp_min(0.0).sqrt()
        self.rho = full((rel * rel).sum(-1).amax(1).sqrt())
        self.cone = self.cos >= CONE_COSINE

    def upper(self, i: Tensor, j: Tensor) -> Tensor:
        """``(P,)`` upper bounds of the squared distances between the points of nodes ``i`` and ``j``."""
        d = torch.maximum(self.hi[i] - self.lo[j], self.hi[j] - self.lo[i])
        box = (d * d).sum(-1)
        # cos(beta + alpha_i + alpha_j) by the angle-sum formulas, from the axes' dot and cross products (accurate
        # to ~1e-15 at every angle, unlike an arccos near 0 or pi) and the cones' cosines and sines. A sine from a
        # cosine near 1 has lost half its digits (~3e-8), and a cone's true half-angle exceeds the one of its
        # rounded cosine by as much: the slack 2^-20 (~1e-6) covers those ~2e-7 in the cosine of theta (cos is
        # 1-Lipschitz), and costs the bound 2e-6 rho², far below a leaf's width squared. When theta may reach pi
        # (cos(alpha) + cos(beta) < slack) the cosine is -1.
        ai, aj = self.axis[i], self.axis[j]
        cos_b = (ai * aj).sum(-1)
        sin_b = torch.linalg.vector_norm(torch.linalg.cross(ai, aj), dim=-1)
        ci, cj, si, sj = self.cos[i], self.cos[j], self.sin[i], self.sin[j]
        cos_a, sin_a = ci * cj - si * sj, si * cj + ci * sj
        wide = cos_a + cos_b < ANGLE_SLACK
        cos_t = torch.where(wide, -1.0, cos_b * cos_a - sin_b * sin_a - ANGLE_SLACK).clamp(-1.0, 0.0)
        ri, rj = self.rho[i], self.rho[j]
        cone = ri * ri + rj * rj - 2.0 * ri * rj * cos_t
        return torch.where(self.cone[i] & self.cone[j], torch.minimum(box, cone), box)


class _Search:
    """One farthest-pair search over the points ``x[first]`` (distinct candidates), see :func:`farthest_pair`."""

    def __init__(self, x: Tensor, first: Tensor, lower: float, centre: Tensor) -> None:
        self.n = x.shape[0]
        self.lower, self.centre = lower, centre
        m = first.shape[0]
        self.depth = ((m - 1) // LEAF_SIZE).bit_length()  # the fewest levels with leaves of <= LEAF_SIZE points
        self.size = -(-m // 2**self.depth)
        # Padded with copies of the first point to 2^depth leaves of `size` points: every node of level k is then a
        # block of y.view(2^k, -1, 3). A copy adds only pairs that its original already makes.
        self.f = torch.cat([first, first[:1].expand(self.size * 2**self.depth - m)])  # original index of each point
        self.y = x[self.f]
        self.split = [torch.zeros(2**k, dtype=torch.bool, device=x.device) for k in range(self.depth)]
        self.best, self.key = -math.inf, 0

    def threshold(self) -> float:
        return _threshold(max(self.lower, self.best))

    def run(self) -> tuple[int, int]:
        zero = torch.zeros(1, dtype=torch.long, device=self.y.device)
        stack = [(0, zero, zero, torch.full((1,), math.inf, dtype=self.y.dtype, device=self.y.device))]
        while stack:  # depth first over chunks of node pairs: memory bounded, the highest bounds first
            level, a, b, ub = stack.pop()
            keep = ~(ub < self.threshold())  # NaN (an overflowed bound) is kept
            a, b, ub = a[keep], b[keep], ub[keep]
            if a.shape[0] == 0:
                continue
            if level == self.depth:
                self.leaves(a, b, ub)
                continue
            a, b, ub = self.refine(level, a, b)
            chunks = list(zip(a.split(PAIRS), b.split(PAIRS), ub.split(PAIRS), strict=True))
            stack.extend((level + 1, *chunk) for chunk in reversed(chunks))
        return self.key // self.n, self.key % self.n

    def refine(self, level: int, a: Tensor, b: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """The child pairs of the node pairs ``(a, b)`` of ``level`` that can reach the bound, highest bound first."""
        blocks = self.y.view(2**level, -1, 3)
        nodes = torch.unique(torch.cat([a, b]))
        todo = nodes[~self.split[level][nodes]]
        if todo.shape[0] > 0:  # split each node once, at the median of its widest axis
            pts = blocks[todo]
            widest = (pts.amax(1) - pts.amin(1)).argmax(1)
            key = pts.gather(2, widest[:, None, None].expand(-1, pts.shape[1], 1)).squeeze(2)
            order = key.argsort(dim=1, stable=True)
            blocks[todo] = pts.gather(1, order[..., None].expand(-1, -1, 3))
            f = self.f.view(2**level, -1)
            f[todo] = f[todo].gather(1, order)
            self.split[level][todo] = True
        ca = torch.cat([2 * a, 2 * a, 2 * a + 1, 2 * a + 1])
        cb = torch.cat([2 * b, 2 * b + 1, 2 * b, 2 * b + 1])
        keep = ca <= cb  # a node paired with itself has three child pairs, not four
        ca, cb = ca[keep], cb[keep]
        children = self.y.view(2 ** (level + 1), -1, 3)
        ub = _Nodes(children, torch.unique(torch.cat([ca, cb])), self.centre).upper(ca, cb)
        keep = ~(ub < self.threshold())
        ca, cb, ub = ca[keep], cb[keep], ub[keep]
        if ca.shape[0] > 0:  # the first points of the surviving pairs: a better lower bound, cheaply
            self.lower = max(self.lower, float(squared_distances(children[ca, 0], children[cb, 0]).max()))
        order = torch.argsort(ub, descending=True, stable=True)
        return ca[order], cb[order], ub[order]

    def leaves(self, a: Tensor, b: Tensor, ub: Tensor) -> None:
        """Compare the points of the leaf pairs ``(a, b)`` (bounds ``ub``, highest first), all pairs, in blocks."""
        p = self.y.view(2**self.depth, self.size, 3)
        f = self.f.view(2**self.depth, self.size)
        step = max(1, BLOCK // (3 * self.size * self.size))
        for s in range(0, a.shape[0], step):
            live = ~(ub[s : s + step] < self.threshold())
            if not bool(live[0]):  # sorted: no later pair can reach the best either
                return
            ca, cb = a[s : s + step][live], b[s : s + step][live]
            d2 = squared_distances(p[ca][:, :, None, :], p[cb][:, None, :, :])
            value = float(d2.max())
            if value < self.best:
                continue
            # The tie rule: the brute force's first pair in row-major order is the smallest (min, max) of original
            # indices among the largest (d(i, j) == d(j, i) bit for bit; a copy stands for its original's index).
            hit = torch.nonzero(d2 == value)
            fi, fj = f[ca[hit[:, 0]], hit[:, 1]], f[cb[hit[:, 0]], hit[:, 2]]
            key = int((torch.minimum(fi, fj) * self.n + torch.maximum(fi, fj)).min())
            self.key = key if value > self.best else min(self.key, key)
            self.best = value


def farthest_pair(x: Tensor) -> tuple[int, int]:
    """Indices ``(i, j)`` of the two farthest of the ``(V, 3)`` float64 points (no gradient), ``i <= j``.

    Exact: the pair a float64 brute force over all ``V²`` pairs finds, the largest ``((x_i - x_j) ** 2).sum()``,
    the first in row-major order among ties (``(0, 0)`` when all points coincide), by the branch and bound of the
    module docstring. Cost: ``O(V log V)`` to sort the points into the tree, then on a sphere about 50 squared
    distances per point (measured; 100 000 points: ~0.5 s on one CPU core), far fewer on most shapes (a captured
    frame of 20 000 vertices: ~10 ms). ``O(V²)`` only where most pairs lie within ~1e-12 (relative) of the largest
    (two clusters each 1e-12 of their distance wide), or where the squares underflow (coordinates below ~1e-154)
    or overflow (above ~1e154). Memory: blocks of ``2**22`` elements and chunks of ``2**15`` node pairs.

    Args:
        x: ``(V, 3)`` float64 points, ``V >= 1``, finite.

    Returns:
        ``(i, j)`` Python ints.

    Example:
        >>> farthest_pair(torch.tensor([[0.0, 0, 0], [3.0, 4.0, 0], [1.0, 1.0, 0]], dtype=torch.float64))
        (0, 1)
    """
    x = x.contiguous()
    lower, centre, candidates = _candidates(x)
    first = _distinct(x, candidates)
    if first.shape[0] == 1:  # all points coincide (else L's pair is two candidates): the brute force's (0, 0)
        return 0, 0
    return _Search(x, first, lower, centre).run()
