"""The order in which mmetric sorts a point cloud's positions (equ / eqTFAN modes, their ``--outputModelA/B``).

mmetric sorts the positions with ``std::sort`` and ``CompareVertex<true, false, false, false>``: lexicographic on
(x, y, z) with C's ``<``, so -0.0 and 0.0 are equal there. ``std::sort`` is not stable: points equal for it come out
in an order its algorithm decides. That order is invisible unless the tied points differ in their bits -- a -0.0
against a 0.0 -- and then it shows in the sorted file (``-0`` or ``0`` first). :func:`mmetric_point_order` takes
numpy's stable sort when no tie mixes bit patterns (every order of such ties writes the same file), and otherwise
runs libstdc++'s introsort (GCC's ``std::sort``: median-of-three quicksort to 16-element runs, heapsort past a
depth of ``2 * floor(log2(n))``, then insertion sort), the one mmetric v1.1.7 is built with, on the points' ranks.
Measured on the v1.1.7 binary: 5 points with signed zeros come out in input order (insertion sort), 200 points with
signed zeros in the order this emulation gives. The replay runs in C++ (``native/point_order.cpp``, the same steps
written out, not this build's ``std::sort``, whose order of ties is its library's); :func:`_introsort` is its Python
reference, used where the extension cannot be built.
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric import native

__all__ = ["lexicographic_order", "mmetric_point_order"]

_THRESHOLD = 16  # libstdc++'s _S_threshold: runs at most this long are left to the final insertion sort


def lexicographic_order(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positions as mmetric's ``<`` compares them and a stable lexicographic order of them.

    Enough to compare sorted clouds (ties are equal points, kept in input order); :func:`mmetric_point_order` places
    ties as mmetric does.

    Args:
        positions: ``(N, 3)`` float32 positions, not NaN (``<`` orders no NaN).

    Returns:
        ``(keys, order)``: ``(N, 3)`` float32 keys (-0.0 made 0.0) and ``(N,)`` indices sorting them on (x, y, z).

    Example:
        >>> keys, order = lexicographic_order(np.array([[1, 0, 0], [-0.0, 2, 0]], np.float32))
        >>> keys[order].tolist()
        [[0.0, 2.0, 0.0], [1.0, 0.0, 0.0]]
    """
    keys = np.asarray(positions, np.float32).reshape(-1, 3) + np.float32(0.0)  # -0.0 + 0.0 is 0.0, as C's < sees it
    # np.lexsort((z, y, x))'s order, as two stable sorts of unsigned integers that order as the floats do: (x, y)
    # packed in 64 bits after z (lexsort's three float passes took 0.6 s at 1M points, these 0.3 s)
    bits = keys.view(np.uint32)
    ordered = np.where(bits >> 31 != 0, ~bits, bits | np.uint32(0x80000000))  # negatives reversed, below positives
    by_z = np.argsort(ordered[:, 2], kind="stable")
    xy = (ordered[by_z, 0].astype(np.uint64) << np.uint64(32)) | ordered[by_z, 1]
    return keys, by_z[np.argsort(xy, kind="stable")]


def mmetric_point_order(positions: np.ndarray) -> np.ndarray:
    """The permutation mmetric's ``std::sort`` of the positions applies (the sorted points are ``positions[order]``).

    Args:
        positions: ``(N, 3)`` float32 positions, finite (a NaN breaks the ordering ``std::sort`` needs).

    Returns:
        ``(N,)`` int64 indices into ``positions``, in mmetric's sorted order.

    Example:
        >>> p = np.array([[0, 1, 0], [-0.0, 1, 0], [-0.0, 0, 0], [0, 0, 0]], np.float32)
        >>> mmetric_point_order(p).tolist()
        [2, 3, 0, 1]
    """
    p = np.asarray(positions, np.float32).reshape(-1, 3)
    keys, order = lexicographic_order(p)
    rank = _tie_ranks(p, keys, order)
    if rank is None:
        return order.astype(np.int64)  # ties are bit-identical: any order of them is the same file
    ext = native.try_load("pcc")  # None without a C++ compiler: the Python replay (seconds at 1M points)
    if ext is not None:
        return ext.introsort_permutation(torch.from_numpy(rank)).numpy()
    return np.asarray(_introsort(rank.tolist()), np.int64)


def _tie_ranks(p: np.ndarray, keys: np.ndarray, order: np.ndarray) -> np.ndarray | None:
    """``(N,)`` int64 dense ranks of the points under mmetric's ``<``, or ``None`` where no tie mixes bit patterns."""
    if len(order) < 2:
        return None
    ks, bits = keys[order], p[order].view(np.uint32)
    tied = (ks[1:] == ks[:-1]).all(axis=1)
    if not (tied & (bits[1:] != bits[:-1]).any(axis=1)).any():
        return None
    rank = np.empty(len(order), np.int64)
    rank[order] = np.concatenate([[0], np.cumsum(~tied)])
    return rank


def _introsort(rank: list[int]) -> list[int]:
    """libstdc++'s ``std::sort`` of ``range(len(rank))`` by ``rank``, step for step: the permutation it leaves."""
    a = list(range(len(rank)))
    n = len(a)

    def less(i: int, j: int) -> bool:
        return rank[i] < rank[j]

    def adjust_heap(first: int, hole: int, length: int, value: int) -> None:
        top, child = hole, hole
        while child < (length - 1) // 2:
            child = 2 * (child + 1)
            if less(a[first + child], a[first + child - 1]):
                child -= 1
            a[first + hole] = a[first + child]
            hole = child
        if length % 2 == 0 and child == (length - 2) // 2:
            child = 2 * (child + 1)
            a[first + hole] = a[first + child - 1]
            hole = child - 1
        parent = (hole - 1) // 2
        while hole > top and less(a[first + parent], value):
            a[first + hole] = a[first + parent]
            hole = parent
            parent = (hole - 1) // 2
        a[first + hole] = value

    def heap_sort(first: int, last: int) -> None:  # std::__partial_sort(first, last, last): make_heap, sort_heap
        length = last - first
        if length >= 2:
            for parent in range((length - 2) // 2, -1, -1):
                adjust_heap(first, parent, length, a[first + parent])
        while last - first > 1:
            last -= 1
            value = a[last]
            a[last] = a[first]
            adjust_heap(first, 0, last - first, value)

    def median_to_first(result: int, x: int, y: int, z: int) -> None:
        if less(a[x], a[y]):
            m = y if less(a[y], a[z]) else (z if less(a[x], a[z]) else x)
        elif less(a[x], a[z]):
            m = x
        else:
            m = z if less(a[y], a[z]) else y
        a[result], a[m] = a[m], a[result]

    def partition(first: int, last: int, pivot: int) -> int:
        while True:
            while less(a[first], a[pivot]):
                first += 1
            last -= 1
            while less(a[pivot], a[last]):
                last -= 1
            if not first < last:
                return first
            a[first], a[last] = a[last], a[first]
            first += 1

    def loop(first: int, last: int, depth: int) -> None:
        while last - first > _THRESHOLD:
            if depth == 0:
                heap_sort(first, last)
                return
            depth -= 1
            median_to_first(first, first + 1, first + (last - first) // 2, last - 1)
            cut = partition(first + 1, last, first)
            loop(cut, last, depth)
            last = cut

    def linear_insert(last: int) -> None:  # unguarded: an element not above it exists to its left
        value = a[last]
        nxt = last - 1
        while less(value, a[nxt]):
            a[last] = a[nxt]
            last = nxt
            nxt -= 1
        a[last] = value

    def insertion_sort(first: int, last: int) -> None:
        for i in range(first + 1, last):
            if less(a[i], a[first]):
                value = a[i]
                a[first + 1 : i + 1] = a[first:i]
                a[first] = value
            else:
                linear_insert(i)

    loop(0, n, 2 * (n.bit_length() - 1))
    if n > _THRESHOLD:
        insertion_sort(0, _THRESHOLD)
        for i in range(_THRESHOLD, n):
            linear_insert(i)
    else:
        insertion_sort(0, n)
    return a
