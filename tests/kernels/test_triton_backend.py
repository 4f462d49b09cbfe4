"""The "triton" backend against the brute force, on the CPU through Triton's interpreter (TRITON_INTERPRET=1).

The interpreter runs the very kernel source that CUDA compiles (same operations, numpy float32/float64 arithmetic,
no FMA), so these tests check the traversal logic, the certified pruning and the bit-exact distance expression.
Sizes are small: every tensor operation of the kernel costs a Python call there. CUDA tests run only with a GPU.

TRITON_INTERPRET=1 must be set before triton is imported (Triton decorates its own ``tl.max``/``tl.min`` at import),
so in a normal run the interpreter tests are skipped here and run by ``test_interpreter_suite`` in a subprocess
with the variable set; ``TRITON_INTERPRET=1 python -m pytest tests/kernels/test_triton_backend.py`` runs them
directly.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

triton = pytest.importorskip("triton")

from torchmeshmetric import DeviceError, DTypeError, MeshIndex  # noqa: E402
from torchmeshmetric.kernels.accel import triton_traversal  # noqa: E402
from torchmeshmetric.kernels.accel.lbvh import build_implicit_bvh, morton_codes  # noqa: E402
from torchmeshmetric.kernels.nearest import nearest_vertex_distance  # noqa: E402
from torchmeshmetric.kernels.point_triangle import point_mesh_distance  # noqa: E402

DTYPES = [torch.float32, torch.float64]
ROOT = Path(__file__).resolve().parents[2]
_NEEDS_CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


def CUDA(test):  # noqa: N802  (a decorator named as the marks it applies)
    """Selected by ``pytest -m cuda`` and skipped without a CUDA device."""
    return pytest.mark.cuda(_NEEDS_CUDA(test))


INTERPRETING = triton_traversal.interpreting()
interpreted = pytest.mark.skipif(
    not INTERPRETING, reason="needs TRITON_INTERPRET=1 before triton's import: run by test_interpreter_suite"
)


@pytest.fixture
def interpret():
    """Marks a test that runs kernels in Triton's interpreter."""


@pytest.fixture
def gpu_config(monkeypatch):
    """The GPU's launch configuration in the interpreter: 32-lane programs, the faces of a leaf one by one."""
    monkeypatch.setattr(triton_traversal, "BLOCK_INTERPRETED", triton_traversal.BLOCK_GPU)
    monkeypatch.setattr(triton_traversal, "LEAF_VECTOR_INTERPRETED", triton_traversal.LEAF_VECTOR_GPU)


def same_faces(points, verts, faces, *, exact=True, **kw):
    ref = point_mesh_distance(points, verts, faces, backend="bruteforce", **kw)
    got = point_mesh_distance(points, verts, faces, backend="triton", **kw)
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    torch.testing.assert_close(got.dists, ref.dists, rtol=0, atol=1e-6 * diag)
    diff = (got.face_idx != ref.face_idx).nonzero()[:, 0]
    # Only an exactly equidistant face may differ.
    assert torch.equal(got.dists[diff], ref.dists[diff]), f"different non-tied faces at {diff[:5].tolist()}"
    if exact:  # the selection replays the brute force: same face, same distance bit for bit
        assert torch.equal(got.face_idx, ref.face_idx)
        assert torch.equal(got.dists, ref.dists)
    return ref, got


def same_nearest(points, ref_points, **kw):
    ref = nearest_vertex_distance(points, ref_points, backend="bruteforce", **kw)
    got = nearest_vertex_distance(points, ref_points, backend="triton", **kw)
    assert torch.equal(got.idx, ref.idx)
    assert torch.equal(got.dists, ref.dists)
    return ref, got


def _degenerate_mesh(dtype):
    """Zero-area, collinear, point, duplicated-vertex and duplicated faces (as in test_accel_equality)."""
    verts = torch.tensor(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [3, 0, 0], [1, 0, 0], [0, 0, 1], [0.5, 0.5, 0.0]],
        dtype=dtype,
    )
    faces = torch.tensor([[0, 1, 2], [1, 3, 2], [1, 4, 5], [4, 4, 4], [1, 6, 3], [0, 2, 7], [0, 1, 2], [8, 8, 1]])
    return verts, faces


def _local_soup(g, nf, dtype, size=0.3):
    """Random small triangles scattered in a cube: a BVH-friendly but irregular mesh."""
    centres = torch.rand(nf, 1, 3, generator=g, dtype=dtype) * 4 - 2
    verts = (centres + size * torch.randn(nf, 3, 3, generator=g, dtype=dtype)).reshape(-1, 3)
    return verts, torch.arange(3 * nf).reshape(nf, 3)


# ----------------------------------------------------------------------------------------------- lbvh (plain torch)


@pytest.mark.parametrize("leaf", [1, 3, 4])
def test_lbvh_bounds_contain_their_primitives_and_leaves_partition_them(leaf):
    g = torch.Generator().manual_seed(0)
    lengths = torch.tensor([5, 0, 17, 1, 64, 2])
    offsets = torch.cat([torch.zeros(1, dtype=torch.long), lengths.cumsum(0)])
    batch = torch.repeat_interleave(torch.arange(len(lengths)), lengths)
    lo = torch.randn(int(offsets[-1]), 3, generator=g, dtype=torch.float64)
    hi = lo + torch.rand(lo.shape, generator=g, dtype=torch.float64)
    t = build_implicit_bvh(lo, hi, batch, offsets, leaf)
    assert t.prims.numel() == int(sum(1 << int(d) for d in t.depth)) * leaf
    for b in range(len(lengths)):
        n_b = int(lengths[b])
        depth = int(t.depth[b])
        assert (1 << depth) * leaf >= max(n_b, 1) and (depth == 0 or (1 << (depth - 1)) * leaf < n_b)
        slots = t.prims[int(t.slot_base[b]) : int(t.slot_base[b]) + (leaf << depth)]
        real = slots[slots >= 0]
        # Every primitive of the item in exactly one slot (one leaf), real slots first.
        assert sorted(real.tolist()) == list(range(int(offsets[b]), int(offsets[b + 1])))
        assert bool((slots[:n_b] >= 0).all()) and bool((slots[n_b:] < 0).all())
        for node in range(1, 2 << depth):
            level = node.bit_length() - 1
            span = 1 << (depth - level)
            first_leaf = (node << (depth - level)) - (1 << depth)
            under = slots[first_leaf * leaf : (first_leaf + span) * leaf]
            under = under[under >= 0]
            box = t.nodes[int(t.node_base[b]) + node]
            if under.numel():  # the box is exactly the union of the primitive boxes below the node
                assert torch.equal(box[:3], lo[under].amin(0)) and torch.equal(box[3:], hi[under].amax(0))
            else:
                assert bool((box[:3] == float("inf")).all()) and bool((box[3:] == float("-inf")).all())


def test_lbvh_leaves_follow_the_morton_curve():
    g = torch.Generator().manual_seed(1)
    x = torch.rand(200, 3, generator=g)
    t = build_implicit_bvh(x, x, torch.zeros(200, dtype=torch.long), torch.tensor([0, 200]), 4)
    codes = morton_codes(x, torch.zeros(200, dtype=torch.long), 1)
    slot_codes = codes[t.prims[t.prims >= 0]]
    assert bool((slot_codes[1:] >= slot_codes[:-1]).all())


def test_morton_codes_interleave_the_quantised_axes():
    from torchmeshmetric.kernels.accel.lbvh import _spread10

    g = torch.Generator().manual_seed(2)
    x = torch.randn(500, 3, generator=g, dtype=torch.float64)
    x[:, 2] = 0.5  # a flat axis quantises to 0
    batch = torch.cat([torch.zeros(200, dtype=torch.long), torch.ones(300, dtype=torch.long)])
    codes = morton_codes(x, batch, 2)
    for b, rows in ((0, slice(0, 200)), (1, slice(200, 500))):
        xb = x[rows]
        lo, hi = xb.amin(0), xb.amax(0)
        inv = torch.where(hi > lo, 1023.99 / torch.where(hi > lo, hi - lo, torch.ones_like(hi)), torch.zeros_like(hi))
        q = ((xb - lo) * inv).clamp(0, 1023).long()
        expected = (_spread10(q[:, 0]) << 2) | (_spread10(q[:, 1]) << 1) | _spread10(q[:, 2])
        assert torch.equal(codes[rows], expected), b
    assert int(codes.max()) < 2**30


def test_lbvh_rejects_an_empty_leaf_size():
    x = torch.zeros(3, 3)
    with pytest.raises(ValueError, match="leaf_size"):
        build_implicit_bvh(x, x, torch.zeros(3, dtype=torch.long), torch.tensor([0, 3]), 0)


# ----------------------------------------------------------------------------------------------- closest face


@interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_random_meshes_same_faces_bit_identical(interpret, dtype):
    g = torch.Generator().manual_seed(1)
    verts, faces = _local_soup(g, 150, dtype)
    soup_v = torch.randn(40, 3, generator=g, dtype=dtype)  # plus large random triangles crossing everything
    verts = torch.cat([verts, soup_v])
    faces = torch.cat([faces, torch.randint(450, 490, (40, 3), generator=g)])
    points = torch.randn(300, 3, generator=g, dtype=dtype) * 2
    same_faces(points, verts, faces)


@interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_degenerate_faces_vertices_edges_and_ties(interpret, dtype, gpu_config):
    verts, faces = _degenerate_mesh(dtype)
    g = torch.Generator().manual_seed(3)
    pts = [verts, 0.5 * (verts[faces[:, 0]] + verts[faces[:, 1]]), verts[faces].mean(1)]
    pts.append(torch.rand(200, 3, generator=g, dtype=dtype) * 4 - 1)
    same_faces(torch.cat(pts), verts, faces)  # exact ties resolve to the lowest index, as the brute force


@interpreted
def test_lattice_ties_and_one_face(interpret):
    g = torch.Generator().manual_seed(4)
    verts = torch.randn(30, 3, generator=g, dtype=torch.float64).mul(2).round()
    faces = torch.randint(0, 30, (60, 3), generator=g)
    points = torch.randn(150, 3, generator=g, dtype=torch.float64).mul(2).round()
    same_faces(points, verts, faces)  # integer lattice: many exact ties and degenerate faces
    same_faces(points, verts, faces[:1])  # a single face: the root is a leaf


@interpreted
def test_torus_near_far_on_vertices_and_far_outside(interpret):
    mesh = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=24, minor_sections=12)
    rng = np.random.default_rng(5)
    verts, faces = torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)
    near = mesh.sample(250, seed=5) + rng.normal(scale=0.01, size=(250, 3))
    far = rng.normal(size=(60, 3)) * 5
    outside = rng.normal(size=(20, 3)) * 1e4  # far outside the bounding box
    pts = torch.tensor(np.concatenate([near, far, outside]), dtype=torch.float32)
    same_faces(torch.cat([pts, verts[:80]]), verts, faces)


@interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_far_from_origin(interpret, dtype):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    offset = torch.tensor([1e6, -2e6, 3e6], dtype=torch.float64)
    verts = (torch.tensor(mesh.vertices) + offset).to(dtype)
    g = torch.Generator().manual_seed(6)
    points = (torch.randn(120, 3, generator=g, dtype=torch.float64) * 1.2 + offset).to(dtype)
    same_faces(torch.cat([points, verts[:30]]), verts, torch.tensor(mesh.faces))


@interpreted
@pytest.mark.parametrize(("dtype", "far"), [(torch.float32, 1e4), (torch.float32, 1e9), (torch.float64, 1e15)])
def test_a_stray_unreferenced_vertex_changes_no_distance(interpret, dtype, far):
    # Review I #1: the centre came from every vertex, so one unreferenced vertex far away took it off the surface
    # (float32, stray at 1e9: a point 0.29 from the sphere measured 3e-8). Now the answer is the clean mesh's.
    mesh = trimesh.creation.icosphere(subdivisions=2)
    verts, faces = torch.tensor(mesh.vertices, dtype=dtype), torch.tensor(mesh.faces)
    g = torch.Generator().manual_seed(8)
    points = torch.cat([torch.tensor([[0.3, 0.4, 0.5]], dtype=dtype), torch.randn(120, 3, generator=g, dtype=dtype)])
    stray = torch.cat([verts, torch.tensor([[far, 0.0, 0.0]], dtype=dtype)])
    clean = point_mesh_distance(points, verts, faces, backend="triton")
    _, got = same_faces(points, stray, faces)
    for name, a, b in zip(got._fields, got, clean, strict=True):
        assert torch.equal(a, b), name
    exact = point_mesh_distance(points.double(), verts.double(), faces, backend="bruteforce").dists
    torch.testing.assert_close(got.dists.double(), exact, rtol=0, atol=8 * torch.finfo(dtype).eps)
    index = MeshIndex(stray, faces, backend="triton")
    assert torch.equal(index.point_mesh_distance(points).dists, clean.dists)  # built here, refitted below
    index.refit(stray + 0.25)
    moved = point_mesh_distance(points, verts + 0.25, faces, backend="triton")
    for name, a, b in zip(moved._fields, index.point_mesh_distance(points), moved, strict=True):
        assert torch.equal(a, b), f"refitted {name}"


@interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_one_far_query_point_leaves_the_others_in_the_meshs_frame(interpret, dtype):
    # One frame scaled for the farthest point made float32 distances of the others to a unit sphere 0 (point at
    # 1e30; float64: 1e300); the near points are now measured in the mesh's frame, as without the far point.
    mesh = trimesh.creation.icosphere(subdivisions=2)
    verts, faces = torch.tensor(mesh.vertices, dtype=dtype), torch.tensor(mesh.faces)
    near = torch.randn(100, 3, generator=torch.Generator().manual_seed(9), dtype=dtype)
    far = 1e30 if dtype == torch.float32 else 1e300
    _, got = same_faces(torch.cat([near, torch.tensor([[far, 0.0, 0.0]], dtype=dtype)]), verts, faces)
    alone = point_mesh_distance(near, verts, faces, backend="triton")
    for name, a, b in zip(got._fields, got, alone, strict=True):
        assert torch.equal(a[:-1], b), name
    assert float(got.dists[-1]) == pytest.approx(far - 1, rel=1e-6)
    pts = torch.cat([near, torch.tensor([[far, 0.0, 0.0]], dtype=dtype)])
    _, nearest = same_nearest(pts, verts)
    assert torch.equal(nearest.dists[:-1], nearest_vertex_distance(near, verts, backend="triton").dists)


@interpreted
def test_ragged_batch(interpret):
    g = torch.Generator().manual_seed(7)
    meshes, clouds = [], []
    # Items: regular, one face and one point, no query points, tiny random, two faces.
    for i, (nf, npt) in enumerate([(60, 120), (1, 1), (30, 0), (20, 50), (2, 40)]):
        v, f = _local_soup(g, nf, torch.float64)
        meshes.append((v + 10.0 * i, f))
        clouds.append(torch.randn(npt, 3, generator=g, dtype=torch.float64) * 2 + 10.0 * i)
    kw = {
        "points_lengths": torch.tensor([len(c) for c in clouds]),
        "verts_lengths": torch.tensor([len(v) for v, _ in meshes]),
        "faces_lengths": torch.tensor([len(f) for _, f in meshes]),
    }
    args = (torch.cat(clouds), torch.cat([v for v, _ in meshes]), torch.cat([f for _, f in meshes]))
    same_faces(*args, **kw)


@interpreted
def test_gradients_equal_bruteforce(interpret):
    g = torch.Generator().manual_seed(8)
    v0, faces = _local_soup(g, 40, torch.float64)
    p0 = torch.randn(100, 3, generator=g, dtype=torch.float64)
    grads = []
    for b in ("bruteforce", "triton"):
        v, p = v0.clone().requires_grad_(), p0.clone().requires_grad_()
        point_mesh_distance(p, v, faces, backend=b).dists.square().sum().backward()
        grads.append((p.grad, v.grad))
    assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])


@interpreted
def test_gpu_launch_configuration_random_and_torus(interpret, gpu_config):
    # Several 32-lane programs, a partial last block, leaf faces one by one: what a GPU runs.
    g = torch.Generator().manual_seed(9)
    verts, faces = _local_soup(g, 50, torch.float32)
    same_faces(torch.randn(40, 3, generator=g) * 2, verts, faces)
    same_nearest(torch.randn(40, 3, generator=g), torch.randn(90, 3, generator=g))
    mesh = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=16, minor_sections=8)
    verts, faces = torch.tensor(mesh.vertices, dtype=torch.float64), torch.tensor(mesh.faces)
    near = torch.tensor(mesh.sample(40, seed=9)) + 0.01 * torch.randn(40, 3, generator=g, dtype=torch.float64)
    same_faces(torch.cat([near, verts[:10], 3 * torch.randn(10, 3, generator=g, dtype=torch.float64)]), verts, faces)
    lattice = torch.stack(torch.meshgrid(*[torch.arange(4.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    same_nearest(torch.randint(0, 8, (40, 3), generator=g).float() / 2, lattice)  # exact ties on midpoints


@interpreted
@settings(max_examples=12, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 2**31 - 1),
    nv=st.integers(3, 30),
    nf=st.integers(1, 40),
    grid=st.booleans(),
    dtype=st.sampled_from(DTYPES),
)
def test_property_matches_bruteforce(seed, nv, nf, grid, dtype):
    g = torch.Generator().manual_seed(seed)
    verts = torch.randn(nv, 3, generator=g, dtype=dtype)
    points = torch.randn(40, 3, generator=g, dtype=dtype)
    if grid:  # integer lattice: many exact ties and degenerate faces
        verts, points = verts.mul(2).round(), points.mul(2).round()
    same_faces(points, verts, torch.randint(0, nv, (nf, 3), generator=g))
    same_nearest(points, verts)


# ----------------------------------------------------------------------------------------------- nearest point


@interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_nearest_random_and_duplicates(interpret, dtype):
    g = torch.Generator().manual_seed(10)
    ref_points = torch.randn(800, 3, generator=g, dtype=dtype)
    ref_points[100:200] = ref_points[:100]  # exact duplicates: the lowest index must win
    points = torch.cat([torch.randn(300, 3, generator=g, dtype=dtype) * 1.5, ref_points[:200]])
    _, got = same_nearest(points, ref_points)
    assert bool((got.idx[-100:] < 100).all())


@interpreted
def test_nearest_lattice_ties_far_from_origin_ragged_and_single_points(interpret):
    g = torch.Generator().manual_seed(11)
    lattice = torch.stack(torch.meshgrid(*[torch.arange(6.0, dtype=torch.float64)] * 3, indexing="ij"), -1)
    lattice = lattice.reshape(-1, 3) + 1e6
    points = torch.randint(0, 12, (300, 3), generator=g).double() / 2 + 1e6  # on midpoints: exact ties
    same_nearest(points, lattice)
    clouds = [torch.randn(n, 3, generator=g) + i for i, n in enumerate([100, 7, 1, 0, 150])]
    refs = [torch.randn(n, 3, generator=g) + i for i, n in enumerate([400, 300, 1, 5, 1])]
    same_nearest(
        torch.cat(clouds),
        torch.cat(refs),
        points_lengths=torch.tensor([len(c) for c in clouds]),
        ref_lengths=torch.tensor([len(r) for r in refs]),
    )


@interpreted
def test_nearest_gradients_equal_bruteforce(interpret):
    g = torch.Generator().manual_seed(12)
    p0 = torch.randn(150, 3, generator=g, dtype=torch.float64)
    r0 = torch.randn(100, 3, generator=g, dtype=torch.float64)
    grads = []
    for b in ("bruteforce", "triton"):
        p, r = p0.clone().requires_grad_(), r0.clone().requires_grad_()
        nearest_vertex_distance(p, r, backend=b).dists.sum().backward()
        grads.append((p.grad, r.grad))
    assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])


# ----------------------------------------------------------------------------------------------- selection rules


@pytest.mark.skipif(INTERPRETING, reason="checks a process where triton was imported without the interpreter")
def test_cpu_without_interpreter_is_a_device_error(monkeypatch):
    verts, faces = _degenerate_mesh(torch.float32)
    with pytest.raises(DeviceError, match="TRITON_INTERPRET=1"):
        point_mesh_distance(verts, verts, faces, backend="triton")
    with pytest.raises(DeviceError, match="backend='bvh'"):
        nearest_vertex_distance(verts, verts, backend="triton")
    # Triton fixed its mode at import: setting the variable now changes nothing.
    monkeypatch.setenv("TRITON_INTERPRET", "1")
    with pytest.raises(DeviceError, match="before triton is first imported"):
        point_mesh_distance(verts, verts, faces, backend="triton")


@pytest.mark.skipif(INTERPRETING, reason="compiles for a GPU target: needs triton's compiler, not the interpreter")
@pytest.mark.parametrize("is_face", [True, False], ids=["faces", "points"])
@pytest.mark.parametrize("dtype", ["fp32", "fp64"])
def test_gpu_code_has_no_fma_and_ieee_division_and_sqrt(is_face, dtype):
    """Compile for an H100 (sm_90) without a GPU and read the PTX: the exactness promises hold in the machine code."""
    import inspect
    import re

    backend = pytest.importorskip("triton.backends.compiler")
    from triton.compiler import ASTSource

    fn = triton_traversal._selection_kernel
    sig = {}
    for name in inspect.signature(fn.fn).parameters:
        if name in ("LEAF", "BLOCK", "IS_F64", "LEAF_VECTOR", "IS_FACE"):
            sig[name] = "constexpr"
        elif name == "num_queries":
            sig[name] = "i32"
        elif name in ("pts_ptr", "nodes_ptr", "data_ptr", "slack_ptr", "factor_ptr"):
            sig[name] = f"*{dtype}"
        else:
            sig[name] = "*i64"
    leaf = triton_traversal.LEAF_FACES if is_face else triton_traversal.LEAF_POINTS
    constexprs = {"LEAF": leaf, "BLOCK": triton_traversal.BLOCK_GPU, "IS_F64": dtype == "fp64", "IS_FACE": is_face}
    constexprs["LEAF_VECTOR"] = triton_traversal.LEAF_VECTOR_GPU
    try:
        compiled = triton.compile(
            ASTSource(fn=fn, signature=sig, constexprs=constexprs),
            target=backend.GPUTarget("cuda", 90, 32),
            options={"num_warps": 1, "enable_fp_fusion": False},
        )
    except Exception as e:  # no NVIDIA backend in this triton build
        pytest.skip(f"cannot compile for sm_90 here: {e!r}")
    ptx = compiled.asm["ptx"]
    assert not re.search(r"\bfma\.", ptx), "fused multiply-add in the kernel"
    assert not re.search(r"(div|sqrt|rcp|rsqrt)\.(approx|full)", ptx), "approximate division or square root"
    width = "f64" if dtype == "fp64" else "f32"
    assert f"sqrt.rn.{width}" in ptx
    if is_face:
        assert f"div.rn.{width}" in ptx


def test_half_precision_is_a_dtype_error(interpret):
    verts, faces = _degenerate_mesh(torch.float16)
    with pytest.raises(DTypeError, match="float16"):
        point_mesh_distance(verts, verts, faces, backend="triton")


@pytest.mark.skipif(INTERPRETING, reason="this is the subprocess")
def test_interpreter_suite():
    """The interpreter tests of this file, in a fresh process with TRITON_INTERPRET=1 (about a minute)."""
    env = {**os.environ, "TRITON_INTERPRET": "1", "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", __file__, "-k", "not without_triton"]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900, cwd=ROOT)
    print(out.stdout[-3000:])
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]
    assert " passed" in out.stdout and " failed" not in out.stdout


def test_missing_triton_is_an_import_error(monkeypatch):
    from torchmeshmetric.kernels.accel import triton_backend

    monkeypatch.setattr(triton_backend, "triton_available", lambda: False)
    verts, faces = _degenerate_mesh(torch.float32)
    with pytest.raises(ImportError, match="pip install triton"):
        point_mesh_distance(verts, verts, faces, backend="triton")
    with pytest.raises(ImportError, match="pip install triton"):
        nearest_vertex_distance(verts, verts, backend="triton")


def test_auto_rules(monkeypatch):
    from torchmeshmetric import native
    from torchmeshmetric.kernels import select

    monkeypatch.setattr(native, "try_load", lambda name: None)  # no compiler
    cpu, meta, large, small = torch.device("cpu"), torch.device("meta"), 5000 * 1000, 10 * 1000
    assert select.auto_backend_name(cpu, torch.float32, large) == "pruned"  # CPU without the extension
    assert select.auto_backend_name(meta, torch.float32, large) == "pruned"  # neither CPU nor CUDA
    assert select.auto_backend_name(cpu, torch.float32, small) == "bruteforce"  # small: brute force
    monkeypatch.setattr(native, "try_load", lambda name: object())  # the extension changes nothing off the CPU
    assert select.auto_backend_name(meta, torch.float32, large) == "pruned"
    assert select.auto_backend_name(meta, torch.float32, small) == "bruteforce"


def test_library_works_without_triton():
    # A fresh interpreter where `import triton` fails: the library imports, "auto" works, "triton" says why not.
    code = (
        "import sys; sys.modules['triton'] = None\n"
        "import torch\n"
        "from torchmeshmetric import point_mesh_distance\n"
        "from torchmeshmetric.kernels.accel import triton_available\n"
        "v = torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); f = torch.tensor([[0, 1, 2]])\n"
        "assert not triton_available()\n"
        "import torchmeshmetric.kernels.accel.triton_traversal  # importable (doctest collection)\n"
        "assert point_mesh_distance(torch.tensor([[0., 0, 2]]), v, f).dists.item() == 2.0\n"
        "try:\n"
        "    point_mesh_distance(torch.tensor([[0., 0, 2]]), v, f, backend='triton')\n"
        "except ImportError as e:\n"
        "    print('ImportError:', e)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "ImportError: backend='triton' needs the optional triton package" in out.stdout


# ----------------------------------------------------------------------------------------------- CUDA (real GPU)


@CUDA
@pytest.mark.skipif(INTERPRETING, reason="the compiled kernel only")
def test_cuda_auto_picks_triton():
    from torchmeshmetric.kernels import select

    assert select.auto_backend_name(torch.device("cuda"), torch.float32, 5000 * 1000) == "triton"


@CUDA
@pytest.mark.skipif(INTERPRETING, reason="the compiled kernel only (the interpreter copies CUDA tensors to the host)")
@pytest.mark.parametrize("dtype", DTYPES)
def test_cuda_compiled_kernel_matches_bruteforce(dtype):
    mesh = trimesh.creation.icosphere(subdivisions=4)
    verts = torch.tensor(mesh.vertices, dtype=dtype, device="cuda")
    faces = torch.tensor(mesh.faces, device="cuda")
    g = torch.Generator().manual_seed(13)
    points = torch.cat([(torch.randn(20000, 3, generator=g, dtype=dtype) * 1.3).cuda(), verts[:500]])
    # Same-device brute force: the same face and the same distance bit for bit (no FMA, IEEE division and sqrt).
    same_faces(points, verts, faces)
    ref_cpu = point_mesh_distance(points.cpu(), verts.cpu(), faces.cpu(), backend="bruteforce")
    got = point_mesh_distance(points, verts, faces, backend="triton")
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    torch.testing.assert_close(got.dists.cpu(), ref_cpu.dists, rtol=0, atol=1e-6 * diag)
    # Ragged batch on the device: two items far apart.
    kw = {
        "points_lengths": torch.tensor([15000, 5500]),
        "verts_lengths": torch.tensor([len(verts)] * 2),
        "faces_lengths": torch.tensor([len(faces)] * 2),
    }
    same_faces(points, torch.cat([verts, verts + 10]), torch.cat([faces, faces]), **kw)
    # Nearest vertex: both select by the same computed squared distance, lowest index among equal ones.
    same_nearest(points, verts)
