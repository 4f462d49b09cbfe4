"""mmetric's connectivity comparison by triangle fans (``compare --mode eqTFAN``), step for step, every line it prints.

mmetric v1.1.7's ``Compare::eqTFAN`` prints, in order:

1. The texture maps' lines, exactly as ``compare --mode equ`` does (the same code in mmetric; here the same
   :func:`~torchmeshmetric.mpeg.comparison.equality.load_equality_model` maps and the same lines).
2. Where the triangle counts are equal and zero (point clouds), the line of ``equ``'s point-cloud branch and nothing
   more: the sorted positions compared, with ``--eqTFAN_epsilon`` as ``equ``'s ``--epsilon``
   (:func:`~torchmeshmetric.mpeg.comparison.equality.point_cloud_verdict`); the position and UV counts are not
   compared first.
3. Where the models' sizes differ, one line and nothing more: ``number of triangles are different``, then ``number of
   positions are different``, then ``number of uv coordinates are different`` (the lists as read from the files).
4. The connectivity compared twice, on positions (``v`` indices) then on texture coordinates (``vt`` indices), each
   printing ``the geometry (texture) connectivity of meshes is equal``, ``... is not equal, early return.`` (with
   ``--eqTFAN_earlyReturn``, the default), ``meshes are not equal, maxV2TA_ != maxV2TB_ `` (a vertex in more
   triangles than any of the other model's), or nothing (differences counted without early return).
5. `` meshes are equal`` (with its leading space), or ``meshes are not equal, N different triangles`` -- N is the
   count of the geometry pass -- followed by the position, UV, colour and normal lists' differences, as ``equ``.

``--eqTFAN_unoriented`` reaches no test in mmetric v1.1.7, so it changes no line, and ``--eqTFAN_epsilon`` applies
to models without triangles only (2.).

The connectivity pass decides whether B is A with its vertices renamed: it walks A's vertices in order, builds the
triangle fans around each (TFAN, the connectivity coder's traversal: the free triangles around the vertex, chained
through shared edges from the least connected one, oriented by the first), encodes each fan (its degree, a case
number, which of its vertices were already visited and their relative order), and searches B for an unvisited vertex
with the same coordinates whose fans, built the same way and starting from the triangle matching A's first one,
encode the same; candidates that do not lead to a full match are backtracked.

The search is path dependent -- which triangle starts a fan, the order adjacency lists are built in, a fan list that
grows across iterations -- so this module follows mmetric's ``mmCompareTFAN.cpp`` operation by operation (the same
loops, the same copies where it copies and the same shared lists where it shares them) instead of deciding vertex
renaming by another route that could disagree on unusual meshes. Only B's candidate vertices are found through a
table of coordinates instead of a scan of all of B (the same candidates, in the same index order). Where mmetric
reads past the end of a list (fans missing for an iteration) :class:`TfanUndefinedError` is raised.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

from torchmeshmetric._checks import check_flag
from torchmeshmetric.mpeg.comparison.equality import (
    EqualityModel,
    _as_model,
    _epsilon,
    _list_differences,
    _points_line,
    _texture_line,
    _texture_status,
    point_cloud_verdict,
)
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.structures import MeshLike

__all__ = ["TfanEquality", "TfanUndefinedError", "tfan_equality"]


class TfanUndefinedError(RuntimeError):
    """mmetric's TFAN comparison reads past the end of one of its lists on these meshes: its result is undefined."""


class _Side:
    """One mesh's index table, coordinates (as tuples) and vertex -> triangles lists, for one component kind."""

    def __init__(self, tri: np.ndarray, coords: np.ndarray) -> None:
        self.tri = [int(x) for x in tri.reshape(-1)]
        self.nt = len(self.tri) // 3
        self.coords = [tuple(float(x) for x in row) for row in coords]
        self.nv = len(self.coords)
        self.v2t: list[list[int]] = [[] for _ in range(self.nv)]
        for t in range(self.nt):
            for k in range(3):
                lst = self.v2t[self.tri[3 * t + k]]
                if t not in lst:
                    lst.append(t)

    def corners(self, t: int) -> list[int]:
        return self.tri[3 * t : 3 * t + 3]


def _vl_equal(ca: list[tuple[float, ...]], cb: list[tuple[float, ...]], a: list[int], b: list[int]) -> bool:
    """``areVLEqual``: the coordinates of ``a`` and ``b`` match one to one (first free match wins)."""
    if len(a) != len(b):
        return False
    used = [False] * len(b)
    for i in a:
        for j, vb in enumerate(b):
            if not used[j] and cb[vb] == ca[i]:
                used[j] = True
                break
        else:
            return False
    return True


def _process(
    s: _Side, focus: int, tags_t: list[int], vmap: list[int], conq: list[int], tla: list[int],
    t2t: dict[int, list[int]], degenerate: list[int],
) -> None:  # fmt: skip
    """``processTriangle``: the free triangles around ``focus``, their adjacency, degenerate ones tagged."""
    visited: dict[int, int] = {}
    for t in s.v2t[focus]:
        if tags_t[t] == 0:
            tla.append(t)
        else:
            for c in s.corners(t):
                if c != focus and vmap[c] > vmap[focus]:
                    visited[vmap[c]] = c
    conq.extend(sorted(visited))
    for i, ti in enumerate(tla):
        vt = s.corners(ti)
        for j, tj in enumerate(tla):
            if i != j:
                vn = s.corners(tj)
                shared = sum(1 for x in vn for y in vt if x == y)
                if shared in (2, 3):
                    lst = t2t.setdefault(ti, [])
                    if tj not in lst:
                        lst.append(tj)
    for t in tla:
        if tags_t[t] == 0:
            a, b, c = s.corners(t)
            ca, cb, cc = s.coords[a], s.coords[b], s.coords[c]
            if ca in (cb, cc) or cb == cc:
                tags_t[t] = 1
                degenerate.extend((a, b, c))


def _rotate_like(s: _Side, ref: _Side, t: int, corners: list[int], ref_t: int) -> None:
    """In place, as mmetric: rotate ``corners`` (of ``t``) to start where they match ``ref_t``'s corners."""
    cmp = ref.corners(ref_t)
    for j in range(3):
        if (
            s.coords[corners[j]] == ref.coords[cmp[0]]
            and s.coords[corners[(1 + j) % 3]] == ref.coords[cmp[1]]
            and s.coords[corners[(2 + j) % 3]] == ref.coords[cmp[2]]
        ):
            own = s.corners(t)
            for k in range(3):
                corners[k] = own[(k + j) % 3]


def _fan(
    s: _Side, ref: _Side, focus: int, t_min: int, t2t: dict[int, list[int]], tla: list[int], tags_t: list[int],
    fans: list[list[int]], refer: list[int], compute: bool,
) -> None:  # fmt: skip
    """``computeTriangleFan``: one fan around ``focus`` from ``t_min`` (A: from its least connected free triangle)."""
    if t_min == -1:
        return
    if compute:
        t_min, connec = -1, 100000
        for t in tla:
            if tags_t[t] == 0 and connec > len(t2t.get(t, [])):
                connec, t_min = len(t2t.get(t, [])), t
        refer[0] = t_min
    if t_min == -1:
        return
    vfan = [c for c in s.corners(t_min) if c != focus]
    next_t, tfan, count, a, b = t_min, [t_min], 0, -1, -1
    tags_t[t_min] = 1
    while True:
        old, next_t = next_t, -1
        around = t2t.get(old, [])
        if sum(1 for h in around if tags_t[h] == 0) > 1:
            break  # a non-manifold neighbourhood ends the fan
        for h in around:
            if tags_t[h] != 0:
                continue
            vn = s.corners(h)
            if count == 0:
                if next_t == -1 and refer[1] == -1 and compute:
                    refer[1] = h
                next_t = h
                tags_t[h] = 1
                tfan.append(h)
                if not compute and refer[1] != -1:
                    _rotate_like(s, ref, h, vn, refer[1])
                if len(vfan) < 2:
                    raise TfanUndefinedError("a fan's first triangle has fewer than two other corners")
                for k in range(3):
                    if vn[k] == vfan[0]:
                        a, b = vfan[1], vfan[0]
                        break
                    if vn[k] == vfan[1]:
                        a, b = vfan[0], vfan[1]
                        break
                vfan = [a, b]
                count += 1
                new = next((c for c in vn if c != b and c != focus), -1)
                a, b = b, new
                vfan.append(b)
                break
            if b in vn:
                next_t = h
                tags_t[h] = 1
                tfan.append(h)
                new = next((c for c in vn if c != b and c != focus), -1)
                a, b = b, new
                vfan.append(b)
        if next_t == -1:
            break
    if len(vfan) > 1:
        first = s.corners(tfan[0])
        same = any(
            first[u] == focus and first[(u + 1) % 3] == vfan[0] and first[(u + 2) % 3] == vfan[1] for u in range(3)
        )
        fans.append(vfan if same else vfan[::-1])


def _case(degree: int, ops: list[int], verts: list[int]) -> int:
    """The case number of mmetric's ``IsCase0`` ... ``IsCase8`` (9: none)."""
    inner_zero = all(o == 0 for o in ops[1 : degree - 1])
    if len(verts) == 2 and degree >= 2 and verts == [-1, -2] and ops[0] == 1 and ops[degree - 1] == 1 and inner_zero:
        return 0
    if degree >= 2 and verts and verts[0] == -1 and verts[-1] == -2 and ops[0] == 1 and ops[degree - 1] == 1:
        return 1
    head_zero = all(o == 0 for o in ops[: degree - 1])
    tail_zero = all(o == 0 for o in ops[1:degree])
    if degree >= 2 and verts == [-1] and ops[degree - 1] == 1 and head_zero:
        return 2
    if degree >= 2 and verts == [-2] and ops[degree - 1] == 1 and head_zero:
        return 3
    if degree >= 2 and verts == [-1] and ops[0] == 1 and tail_zero:
        return 4
    if degree >= 2 and verts == [-2] and ops[0] == 1 and tail_zero:
        return 5
    if not verts and all(o == 0 for o in ops[:degree]):
        return 6
    if len(verts) == 2 and degree >= 2 and verts == [-2, -1] and ops[0] == 1 and ops[degree - 1] == 1 and inner_zero:
        return 7
    if degree >= 2 and verts and verts[0] == -2 and verts[-1] == -1 and ops[0] == 1 and ops[degree - 1] == 1:
        return 8
    return 9


@dataclass
class _Code:
    """``getTrianglesFansStatus``'s outputs for one iteration."""

    nbr: list[int] = field(default_factory=list)
    degree: list[int] = field(default_factory=list)
    cases: list[int] = field(default_factory=list)
    ops: list[int] = field(default_factory=list)
    verts: list[int] = field(default_factory=list)


def _status(
    focus: int, vl: list[int], tags_v: list[int], tags_tmp: list[int], vmap: list[int], count: int,
    fans: list[list[int]], conq_in: list[int], code: _Code,
) -> int:  # fmt: skip
    """``getTrianglesFansStatus``: encode the fans; returns the new vertex count (``tags_v`` may be ``tags_tmp``)."""
    conq = list(conq_in)  # passed by value in mmetric
    if fans:
        code.nbr.append(len(fans))
    for fan in fans:
        code.degree.append(len(fan))
        verts: list[int] = []
        ops: list[int] = []
        for k, v0 in enumerate(fan):
            if v0 in fan[:k]:
                tags_v[v0] = 1
            if tags_v[v0] == 0:
                ops.append(0)
            if tags_tmp[v0] == 0:
                vmap[v0] = count
                count += 1
                conq.append(vmap[v0])
                vl.append(v0)
            if tags_v[v0] != 0:
                ops.append(1)
                pos = next((u + 1 for u, x in enumerate(conq) if x == vmap[v0]), 0)
                verts.append(-pos if pos else vmap[v0] - vmap[focus])
            if tags_tmp[v0] == 0:
                tags_tmp[v0] = 1
        degree = code.degree[-1]
        case = _case(degree, ops, verts)
        if case in (1, 8):
            code.ops += ops[1 : degree - 1]
            code.verts += verts[1 : len(verts) - 1]
        elif case == 9:
            code.ops += ops[:degree]
            code.verts += verts
        code.cases.append(case)
    return count


@dataclass
class _State:
    """A mesh's traversal state (tags of triangles and vertices, traversal numbers and their count)."""

    tags_t: list[int]
    tags_v: list[int]
    vmap: list[int]
    count: int

    def copy(self) -> _State:
        return _State(list(self.tags_t), list(self.tags_v), list(self.vmap), self.count)


@dataclass
class _Snapshot:
    """mmetric's ``TFanStateInfo``."""

    iteration: int = 0
    fan_id: int = 0
    fans: list[list[list[int]]] = field(default_factory=list)
    remain: list[bool] = field(default_factory=list)
    tags_t_list: list[list[int]] = field(default_factory=list)
    count: int = 0
    vmap: list[int] = field(default_factory=list)
    tags_v: list[int] = field(default_factory=list)

    def copy(self) -> _Snapshot:
        return _Snapshot(
            self.iteration, self.fan_id, [[list(f) for f in fl] for fl in self.fans], list(self.remain),
            [list(t) for t in self.tags_t_list], self.count, list(self.vmap), list(self.tags_v),
        )  # fmt: skip


def _fans_b(
    s: _Side, ref: _Side, focus: int, tags_t: list[int], tags_v_tmp: list[int], tags_v_list: list[list[int]],
    tags_t_list: list[list[int]], fans_list: list[list[list[int]]], tla: list[int], t2t: dict[int, list[int]],
    refer_min: int, refer_next: int, ref_focus: int, remain: list[bool],
) -> None:  # fmt: skip
    """``buildTriangleFanB``: B's candidate fans, starting from the triangles that match A's first ones."""
    if refer_min == -1:
        return
    starts: list[int] = []
    nexts: list[list[int]] = []
    connec = 10000000
    rmin = ref.corners(refer_min)
    for t in tla:
        if tags_t[t] != 0:
            continue
        t_min = -1
        vt = s.corners(t)
        for j in range(3):
            r = (rmin[j], rmin[(1 + j) % 3], rmin[(2 + j) % 3])
            if (
                s.coords[vt[0]] == ref.coords[r[0]] and s.coords[vt[1]] == ref.coords[r[1]]
                and s.coords[vt[2]] == ref.coords[r[2]]
                and any(vt[k] == focus and r[k] == ref_focus for k in range(3))
                and connec >= len(t2t.get(t, []))
            ):  # fmt: skip
                connec, t_min = len(t2t.get(t, [])), t
                break
        if t_min == -1:
            continue
        found: list[int] = []
        if refer_next != -1:
            rn = ref.corners(refer_next)
            for h, nb in enumerate(t2t.get(t_min, [])):
                if tags_t[nb] == 0:
                    vn = s.corners(nb)
                    for j in range(3):
                        if all(s.coords[vn[k]] == ref.coords[rn[(k + j) % 3]] for k in range(3)):
                            found.append(h)
                            break
        starts.append(t_min)
        nexts.append(found or [-1])
    refer = [refer_min, refer_next]
    for t_min, choices in zip(starts, nexts, strict=True):
        options: list[int | None] = list(choices) if refer_next != -1 else [None]
        for choice in options:
            tags = list(tags_t)
            adjacency = {k: list(v) for k, v in t2t.items()} if refer_next != -1 else t2t
            if choice is not None and choice != -1:  # the neighbour matching A's second triangle goes first
                lst = adjacency[t_min]
                lst[choice], lst[0] = lst[0], lst[choice]
            fan: list[list[int]] = []
            _fan(s, ref, focus, t_min, adjacency, tla, tags, fan, refer, False)
            fans_list.append(fan)
            tags_t_list.append(tags)
            tags_v_list.append(list(tags_v_tmp))
            remain.append(any(tags[t] == 0 for t in tla))


def _vertex_a(
    a: _Side, v: int, sa: _State, conq: list[int], degenerate: list[int],
) -> tuple[list[list[list[int]]], list[_Code], list[list[int]], list[int], list[int]]:  # fmt: skip
    """A's iterations around ``v``: fans, their codes, visited lists and the first / next triangles per iteration."""
    fans_list: list[list[list[int]]] = []
    codes: list[_Code] = []
    vls: list[list[int]] = []
    mins: list[int] = []
    nexts: list[int] = []
    sa.vmap[v] = sa.count
    sa.count += 1
    iteration, remain = 0, True
    while remain:
        t2t: dict[int, list[int]] = {}
        refer = [-1, -1]
        vl = [v]
        tla: list[int] = []
        _process(a, v, sa.tags_t, sa.vmap, conq, tla, t2t, degenerate)
        if tla:
            fans: list[list[int]] = []
            _fan(a, a, v, 0, t2t, tla, sa.tags_t, fans, refer, True)
            if fans:
                fans_list.append(fans)
            remain = any(sa.tags_t[t] == 0 for t in tla)
        else:
            remain = False
        if fans_list:
            if iteration >= len(fans_list):
                raise TfanUndefinedError(f"vertex {v} of A: no fans in iteration {iteration}")
            code = _Code()
            sa.count = _status(v, vl, sa.tags_v, sa.tags_v, sa.vmap, sa.count, fans_list[iteration], conq, code)
            codes.append(code)
            vls.append(vl)
        mins.append(refer[0])
        nexts.append(refer[1])
        iteration += 1
    return fans_list, codes, vls, mins, nexts


def _candidates(
    a: _Side, b: _Side, v: int, sa: _State, sb: _State, by_coords: dict[tuple[float, ...], list[int]],
) -> list[_State]:  # fmt: skip
    """``compareTriangleFans``: B's states after matching A's vertex ``v`` to each fitting unvisited vertex of B."""
    conq_a: list[int] = []
    deg_a: list[int] = []
    fans_a, codes, vls, mins, nexts = _vertex_a(a, v, sa, conq_a, deg_a)
    iterations = len(mins)
    out: list[_State] = []
    for vb in by_coords.get(a.coords[v], []):
        if sb.tags_v[vb]:
            continue
        found = _match_b(a, b, v, vb, sb, fans_a, codes, vls, mins, nexts, deg_a, iterations)
        if found is not None:
            out.append(found)
    return out


def _match_b(
    a: _Side, b: _Side, v: int, vb: int, sb: _State, fans_a: list[list[list[int]]], codes: list[_Code],
    vls: list[list[int]], mins: list[int], nexts: list[int], deg_a: list[int], iterations: int,
) -> _State | None:  # fmt: skip
    """One candidate ``vb`` of B: mmetric's search over B's fan choices, with its backtracking stack."""
    t2t: dict[int, list[int]] = {}
    tags_t = list(sb.tags_t)
    vmap, tags_v = list(sb.vmap), list(sb.tags_v)
    tags_v_list: list[list[int]] = []
    count = sb.count
    tags_v[vb], vmap[vb] = 1, count
    count += 1
    fans_b: list[list[list[int]]] = []
    conq_b: list[int] = []
    deg_b: list[int] = []
    tags_t_list: list[list[int]] = []
    remain: list[bool] = []
    it, need, pid, found = 0, True, 0, False
    si = _Snapshot()
    stack: list[_Snapshot] = []
    while it < iterations:
        found = False
        if need:
            tlb: list[int] = []
            _process(b, vb, tags_t, vmap, conq_b, tlb, t2t, deg_b)
            _fans_b(
                b, a, vb, tags_t, tags_v, tags_v_list, tags_t_list, fans_b, tlb, t2t, mins[it], nexts[it], v, remain
            )
            pid = 0
            si = _Snapshot(it, 0, [[list(f) for f in fl] for fl in fans_b], list(remain),
                           [list(t) for t in tags_t_list], count, list(vmap), list(tags_v))  # fmt: skip
        if fans_b:
            for p in range(pid, len(fans_b)):
                if it >= len(codes):
                    raise TfanUndefinedError(f"vertex {v} of A: no fan code for iteration {it}")
                vl = [vb]
                code = _Code()
                count = _status(vb, vl, tags_v_list[p], tags_v, vmap, count, fans_b[p], conq_b, code)
                want = codes[it]
                if (
                    code.cases == want.cases and code.degree == want.degree
                    and _vl_equal(a.coords, b.coords, vls[it], vl)
                    and code.ops == want.ops and code.verts == want.verts
                    and _vl_equal(a.coords, b.coords, deg_a, deg_b)
                ):  # fmt: skip
                    found = True
                    tags_t = list(tags_t_list[p])
                    it += 1
                    need = True
                    si.fan_id = p
                    stack.append(si.copy())
                    break
                it, remain, tags_v = si.iteration, list(si.remain), list(si.tags_v)
                fans_b = [[list(f) for f in fl] for fl in si.fans]
                count, vmap, tags_t_list = si.count, list(si.vmap), [list(t) for t in si.tags_t_list]
        elif _vl_equal(a.coords, b.coords, deg_a, deg_b) and not fans_a:
            found = True
            it += 1
        if not found and not stack:
            break
        if not found:
            si = stack.pop()
            it, remain, tags_v = si.iteration, list(si.remain), list(si.tags_v)
            fans_b = [[list(f) for f in fl] for fl in si.fans]
            count, vmap, tags_t_list = si.count, list(si.vmap), [list(t) for t in si.tags_t_list]
            pid = si.fan_id + 1
            need = False
    if it == iterations and found:
        return _State(tags_t, tags_v, vmap, count)
    return None


def _connectivity(a: _Side, b: _Side, early: bool) -> tuple[int, str]:
    """``compareConnectivity``: the differences counted and how the pass ended (see :attr:`TfanEquality.geometry`)."""
    max_a = max((len(x) for x in a.v2t), default=0)
    max_b = max((len(x) for x in b.v2t), default=0)
    if max_a != max_b:
        return 1, "valence"
    sa = _State([0] * a.nt, [0] * a.nv, [-1] * a.nv, 0)
    sb = _State([0] * b.nt, [0] * b.nv, [-1] * b.nv, 0)
    by_coords: dict[tuple[float, ...], list[int]] = {}
    for i, c in enumerate(b.coords):
        by_coords.setdefault(c, []).append(i)
    diffs = 0
    repeats: list[int] = []
    for v in range(a.nv):
        if sa.tags_v[v]:
            continue
        saved = sa.copy()
        sa.tags_v[v] = 1
        found = _candidates(a, b, v, sa, sb, by_coords)
        if not found:
            diffs += 1
            if early:
                return diffs, "early return"
        elif len(found) > 1:  # a vertex B has several matches for: decided after the others
            sa = saved
            repeats.append(v)
        else:
            sb = found[0]
    stack: list[tuple[_State, _State]] = []
    for v in repeats:
        if sa.tags_v[v]:
            continue
        sa.tags_v[v] = 1
        found = _candidates(a, b, v, sa, sb, by_coords)
        if not found:
            if not stack:
                diffs += 1
                if early:
                    return diffs, "early return"
            else:
                sa, sb = stack.pop()
            continue
        stack += [(sa.copy(), other) for other in found[1:]]
        sb = found[0]
    return diffs, ("equal" if diffs == 0 else "counted")


@dataclass(frozen=True)
class TfanEquality:
    """The outcome of :func:`tfan_equality`: mmetric's figures, its lines through :meth:`report`.

    Attributes:
        equal: both connectivity passes found every vertex of A in B (mmetric's `` meshes are equal``).
        textures: the texture maps compared, as :attr:`~torchmeshmetric.mpeg.MeshEquality.textures` (one entry per
            pair of maps where either model has one, or ``"set sizes"`` / ``"skipped"``; empty without maps).
        triangles_a: triangle count of A (``triangles_b``: of B).
        positions_a: position count of A (``positions_b``: of B).
        uvs_a: texture-coordinate count of A, as listed in the file (``uvs_b``: of B).
        geometry: how the pass on positions ended: ``"equal"``, ``"early return"`` (a vertex of A without a match,
            the pass stopped), ``"counted"`` (differences counted to the end; mmetric prints no line), ``"valence"``
            (the most triangles around one vertex differs: mmetric's ``maxV2TA_ != maxV2TB_``), or ``None`` when the
            counts differ (mmetric stops before the passes).
        texture: the same for the pass on texture coordinates.
        geometry_differences: the vertices of A the geometry pass found no match for (1 after an early return or a
            valence difference), which mmetric prints as ``N different triangles``; ``None`` when the counts differ.
        texture_differences: the same for the texture pass (mmetric does not print it).
        position_differences: positions that differ index by index, plus the difference of the position counts.
        uv_differences: the same for the UV lists.
        color_differences: the same for the colour lists.
        normal_differences: the same for the normal lists.
        points: neither model has a triangle: their sorted positions were compared (mmetric's point-cloud branch,
            as ``equ``'s); ``geometry``, ``texture`` and their differences are then ``None``.
        point_differences: point clouds compared with ``epsilon`` > 0 and as many points on both sides: the sorted
            points at distance ``>= epsilon``; ``None`` otherwise.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
        >>> a = TexturedMesh(Mesh(v, torch.tensor([[0, 1, 2], [1, 3, 2]])))
        >>> b = TexturedMesh(Mesh(v, torch.tensor([[3, 2, 1], [2, 0, 1]])))
        >>> e = tfan_equality(a, b)
        >>> e.equal, e.geometry, e.texture, e.triangles_b
        (True, 'equal', 'equal', 2)
    """

    equal: bool
    textures: tuple[str, ...]
    triangles_a: int
    triangles_b: int
    positions_a: int
    positions_b: int
    uvs_a: int
    uvs_b: int
    geometry: str | None
    texture: str | None
    geometry_differences: int | None
    texture_differences: int | None
    position_differences: int
    uv_differences: int
    color_differences: int
    normal_differences: int
    points: bool = False
    point_differences: int | None = None

    def report(self) -> str:
        """Every line mmetric's ``compare --mode eqTFAN`` prints between ``eqTFAN_Epsilon = ...`` and its timing.

        Returns:
            One or more lines, without a trailing newline.

        Example:
            >>> r = TfanEquality(False, ("3 pixel differences",), 2, 2, 4, 4, 0, 0, "early return", "equal", 1, 0,
            ...                  1, 0, 0, 0)
            >>> print(r.report())
            texture maps are not equal: 3pixel differences
            the geometry connectivity of meshes is not equal, early return.
            the texture connectivity of meshes is equal
            meshes are not equal, 1 different triangles
            Position differences: 1
            UV coords differences: 0
            Colors differences: 0
            Normals differences: 0
        """
        lines = [_texture_line(t) for t in self.textures]
        if self.points:
            return "\n".join([*lines, _points_line(self.equal, self.point_differences)])
        for what, a, b in (
            ("triangles", self.triangles_a, self.triangles_b),
            ("positions", self.positions_a, self.positions_b),
            ("uv coordinates", self.uvs_a, self.uvs_b),
        ):
            if a != b:
                return "\n".join([*lines, f"meshes are not equal, number of {what} are different {a} vs {b}"])
        for kind, status in (("geometry", self.geometry), ("texture", self.texture)):
            if status == "valence":
                lines.append("meshes are not equal, maxV2TA_ != maxV2TB_ ")
            elif status == "early return":
                lines.append(f"the {kind} connectivity of meshes is not equal, early return.")
            elif status == "equal":
                lines.append(f"the {kind} connectivity of meshes is equal")
        if self.equal:
            return "\n".join([*lines, " meshes are equal"])
        lines += [
            f"meshes are not equal, {self.geometry_differences} different triangles",
            f"Position differences: {self.position_differences}",
            f"UV coords differences: {self.uv_differences}",
            f"Colors differences: {self.color_differences}",
            f"Normals differences: {self.normal_differences}",
        ]
        return "\n".join(lines)


class _Counts(TypedDict):
    """The list sizes mmetric compares first, as keyword arguments of :class:`TfanEquality`."""

    triangles_a: int
    triangles_b: int
    positions_a: int
    positions_b: int
    uvs_a: int
    uvs_b: int


def tfan_equality(
    a: EqualityModel | TexturedMesh | MeshLike,
    b: EqualityModel | TexturedMesh | MeshLike,
    early_return: bool = True,
    epsilon: float = 0.0,
) -> TfanEquality:
    """Whether B is A with its vertices (and texture coordinates) renamed, as ``mm compare --mode eqTFAN`` decides.

    Args:
        a: reference mesh (``--inputModelA``): :func:`~torchmeshmetric.mpeg.load_equality_model` reads a file as
            mmetric does (its lists and texture maps); a :class:`~torchmeshmetric.mpeg.TexturedMesh` (or any mesh
            form) gives its own arrays (UVs per corner, its texture as its one map).
        b: distorted mesh (``--inputModelB``).
        early_return: ``--eqTFAN_earlyReturn`` (default true): each pass stops at the first vertex without a match.
        epsilon: ``--eqTFAN_epsilon``: for models without triangles (point clouds), the distance at which two sorted
            points differ (0: they must be equal); ignored for meshes, as mmetric ignores it.

    Returns:
        :class:`TfanEquality` (the verdict, the counts, mmetric's lines through ``report()``).

    Raises:
        ValueError: ``epsilon`` negative, NaN or beyond float32.
        TfanUndefinedError: mmetric reads past one of its lists on these meshes.

    Example:
        >>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
        >>> a = EqualityModel(v, np.array([[0, 1, 2], [1, 3, 2]]))
        >>> b = EqualityModel(v[[3, 2, 1, 0]], np.array([[3, 2, 1], [2, 0, 1]]))  # renamed vertices and faces
        >>> print(tfan_equality(a, b).report())
        the geometry connectivity of meshes is equal
        the texture connectivity of meshes is equal
         meshes are equal
    """
    early_return = check_flag(early_return, "early_return")
    _epsilon(epsilon)  # checked for meshes too: a bad value is refused whatever the models
    a, b = _as_model(a, "a"), _as_model(b, "b")
    fa, fb = len(a.triangles), len(b.triangles)
    counts = _Counts(
        triangles_a=fa,
        triangles_b=fb,
        positions_a=len(a.positions),
        positions_b=len(b.positions),
        uvs_a=len(a.uvs),
        uvs_b=len(b.uvs),
    )
    lists = _list_differences(a, b)
    textures = _texture_status(a.textures, b.textures)
    if fa == 0 and fb == 0:  # mmetric's point-cloud branch, before the position and UV counts
        equal, diffs = point_cloud_verdict(a.positions, b.positions, epsilon)
        return TfanEquality(equal, textures, **counts, geometry=None, texture=None, geometry_differences=None,
                            texture_differences=None, **lists, points=True, point_differences=diffs)  # fmt: skip
    if fa != fb or counts["positions_a"] != counts["positions_b"] or counts["uvs_a"] != counts["uvs_b"]:
        return TfanEquality(False, textures, **counts, geometry=None, texture=None, geometry_differences=None,
                            texture_differences=None, **lists)  # fmt: skip
    geo_diffs, geo = _connectivity(_Side(a.triangles, a.positions), _Side(b.triangles, b.positions), early_return)
    uv_diffs, uv = _connectivity(_Side(a.triangles_uv, a.uvs), _Side(b.triangles_uv, b.uvs), early_return)
    equal = geo_diffs == 0 and uv_diffs == 0
    return TfanEquality(equal, textures, **counts, geometry=geo, texture=uv, geometry_differences=geo_diffs,
                        texture_differences=uv_diffs, **lists)  # fmt: skip
