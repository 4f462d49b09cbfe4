"""Exact distance kernels against peers, build + query, same inputs, same run.

Run: ``python -m pytest tests/benchmarks/compare_peers.py --benchmark-only -s`` (peers: ``pip install .[bench]``;
Open3D needs ``apt-get install -y libusb-1.0-0``). Sizes: ``TMM_BENCH_SIZES=40k,200k,1m`` (default ``40k``).
The terminal summary prints one table of ratios (ours / peer) per size and query set.

Meshes are closed tori (``trimesh.creation.torus``) with ~F faces; query sets per size: the vertices of a 50%
simplified copy (fast_simplification, ~F/4 points, "simplified") and F/2 points sampled on the surface with
Gaussian noise of 1% of the minor radius... ("near"); plus, for nearest vertex, the simplified vertices against
the full vertex set.

With a CUDA device, "CUDA ..." groups time the same cases on the GPU, inputs already on the device, synchronised:
ours = the "triton" backend (build + query), against Warp's BVH (``wp.Mesh`` build + ``mesh_query_point_no_sign``)
and our chunked brute force; nearest vertex against the chunked ``torch.cdist`` + min brute force. They skip
without a GPU (not measured yet: no GPU was lent to the session that wrote them).
"""

from __future__ import annotations

import os
from functools import cache

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import point_mesh_distance

OURS = "ours"
SECTIONS = {"40k": (200, 100), "200k": (500, 200), "1m": (1000, 500)}  # torus (major, minor) sections
SIZES = [s for s in os.environ.get("TMM_BENCH_SIZES", "40k").split(",") if s]
QUERIES = ["simplified", "near"]


@cache
def case(size: str) -> dict[str, np.ndarray]:
    fs = pytest.importorskip("fast_simplification")
    major, minor = SECTIONS[size]
    mesh = trimesh.creation.torus(1.0, 0.3, major_sections=major, minor_sections=minor)
    verts, faces = mesh.vertices.astype(np.float32), mesh.faces.astype(np.int64)
    sv, _ = fs.simplify(mesh.vertices, mesh.faces, target_reduction=0.5)
    rng = np.random.default_rng(0)
    near = mesh.sample(len(faces) // 2, seed=0) + rng.normal(scale=0.003, size=(len(faces) // 2, 3))
    return {
        "verts": verts,
        "faces": faces,
        "simplified": np.ascontiguousarray(sv, dtype=np.float32),
        "near": near.astype(np.float32),
    }


@pytest.fixture
def timed(benchmark, record):
    """``timed(group, name, fn, rounds)``: benchmark ``fn`` and record its best time for the ratio table."""

    def go(group, name, fn, rounds=5):
        run(benchmark, record, group, name, fn, rounds)

    return go


def run(benchmark, record, group: str, name: str, fn, rounds: int = 5) -> None:
    benchmark.group = group
    benchmark.name = name
    benchmark.pedantic(fn, rounds=rounds, iterations=1, warmup_rounds=1)
    record(group, name, benchmark.stats.stats.min)


def _group(size: str, query: str) -> str:
    c = case(size)
    return f"point->mesh {size} ({len(c['faces'])} faces), {query} ({len(c[query])} points)"


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_ours_bvh(timed, size, query):
    c = case(size)
    p, v, f = torch.from_numpy(c[query]), torch.from_numpy(c["verts"]), torch.from_numpy(c["faces"])
    timed(_group(size, query), OURS, lambda: point_mesh_distance(p, v, f, backend="bvh"))


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_ours_pruned_torch(timed, size, query):
    if size != "40k":
        pytest.skip("pure-torch pruned path: 40k only on the CPU")
    c = case(size)
    p, v, f = torch.from_numpy(c[query]), torch.from_numpy(c["verts"]), torch.from_numpy(c["faces"])
    timed(_group(size, query), "ours pruned (torch)", lambda: point_mesh_distance(p, v, f, backend="pruned"), 1)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", ["40k"])
def test_ours_bruteforce(timed, size, query):
    if size not in SIZES or query != "simplified":
        pytest.skip("brute force: 40k simplified only (seconds per call)")
    c = case(size)
    p, v, f = torch.from_numpy(c[query]), torch.from_numpy(c["verts"]), torch.from_numpy(c["faces"])
    timed(_group(size, query), "ours bruteforce", lambda: point_mesh_distance(p, v, f, backend="bruteforce"), 1)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_open3d(timed, size, query):
    o3d = pytest.importorskip("open3d")
    c = case(size)

    def go():
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(c["verts"]), o3d.core.Tensor(c["faces"].astype(np.uint32)))
        return scene.compute_distance(o3d.core.Tensor(c[query])).numpy()

    timed(_group(size, query), "open3d (embree)", go)


@cache
@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_fcpw(timed, size, query):
    fcpw = pytest.importorskip("fcpw")
    c = case(size)
    verts, faces = np.asfortranarray(c["verts"]), np.asfortranarray(c["faces"].astype(np.int32))
    q = np.asfortranarray(c[query])
    radii = np.full(len(q), np.inf, dtype=np.float32)

    def go():
        scene = fcpw.scene_3D()
        scene.set_object_count(1)
        scene.set_object_vertices(verts, 0)
        scene.set_object_triangles(faces, 0)
        scene.build(fcpw.aggregate_type.bvh_surface_area, True)  # vectorised BVH
        hits = fcpw.interaction_3D_list()
        scene.find_closest_points(q, radii, hits)
        return hits

    timed(_group(size, query), "fcpw (vectorised bvh)", go)


def _warp_kernel():
    pytest.importorskip("warp")
    from tests.benchmarks.warp_kernels import kernels  # Warp 1.2 cannot parse kernels of this module (annotations)

    k = kernels()
    return k.wp, k.query_distance


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_warp_cpu(timed, size, query):
    wp, kernel = _warp_kernel()
    c = case(size)

    def go():
        mesh = wp.Mesh(
            points=wp.array(c["verts"], dtype=wp.vec3, device="cpu"),
            indices=wp.array(c["faces"].astype(np.int32).ravel(), dtype=int, device="cpu"),
        )
        pts = wp.array(c[query], dtype=wp.vec3, device="cpu")
        out = wp.zeros(len(c[query]), dtype=float, device="cpu")
        wp.launch(kernel, dim=len(c[query]), inputs=[mesh.id, pts, out], device="cpu")
        return out.numpy()

    timed(_group(size, query), "warp (cpu)", go)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_libigl_aabb(timed, size, query):
    igl = pytest.importorskip("igl")
    c = case(size)
    v64, p64 = c["verts"].astype(np.float64), c[query].astype(np.float64)
    timed(_group(size, query), "libigl AABB", lambda: igl.point_mesh_squared_distance(p64, v64, c["faces"]))


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_trimesh(timed, size, query):
    pytest.importorskip("rtree")
    if size != "40k":
        pytest.skip("trimesh: 40k only (slow)")
    c = case(size)
    mesh = trimesh.Trimesh(c["verts"], c["faces"], process=False)
    timed(_group(size, query), "trimesh", lambda: trimesh.proximity.closest_point(mesh, c[query]), 1)


# ----------------------------------------------------------------------------- nearest vertex


def _ngroup(size: str) -> str:
    c = case(size)
    return f"nearest vertex {size}: {len(c['simplified'])} points -> {len(c['verts'])} vertices"


@pytest.mark.parametrize("size", SIZES)
def test_nearest_ours_bvh(timed, size):
    c = case(size)
    p, r = torch.from_numpy(c["simplified"]), torch.from_numpy(c["verts"])
    timed(_ngroup(size), OURS, lambda: nearest_vertex_distance(p, r, backend="bvh"), 10)


@pytest.mark.parametrize("size", SIZES)
def test_nearest_ours_pruned_torch(timed, size):
    c = case(size)
    p, r = torch.from_numpy(c["simplified"]), torch.from_numpy(c["verts"])
    timed(_ngroup(size), "ours pruned (torch)", lambda: nearest_vertex_distance(p, r, backend="pruned"), 1)


@pytest.mark.parametrize("size", SIZES)
def test_nearest_pykdtree(timed, size):
    kd = pytest.importorskip("pykdtree.kdtree")
    c = case(size)
    timed(_ngroup(size), "pykdtree", lambda: kd.KDTree(c["verts"]).query(c["simplified"]), 10)


@pytest.mark.parametrize("size", SIZES)
def test_nearest_scipy(timed, size):
    spatial = pytest.importorskip("scipy.spatial")
    c = case(size)
    timed(
        _ngroup(size),
        "scipy cKDTree",
        lambda: spatial.cKDTree(c["verts"]).query(c["simplified"], workers=-1),
        10,
    )


@pytest.mark.parametrize("size", ["40k"])
def test_nearest_bruteforce(timed, size):
    if size not in SIZES:
        pytest.skip("brute force: 40k only")
    c = case(size)
    p, r = torch.from_numpy(c["simplified"]), torch.from_numpy(c["verts"])
    timed(_ngroup(size), "ours bruteforce", lambda: nearest_vertex_distance(p, r, backend="bruteforce"), 1)


# ----------------------------------------------------------------------------------------------- CUDA (skip without)

CUDA_ONLY = pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA rows need a CUDA device")


def _cgroup(size: str, query: str) -> str:
    return f"CUDA {_group(size, query)}"


def _cuda_case(size: str, query: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    c = case(size)
    return torch.from_numpy(c[query]).cuda(), torch.from_numpy(c["verts"]).cuda(), torch.from_numpy(c["faces"]).cuda()


def _synced(fn):
    def go():
        out = fn()
        torch.cuda.synchronize()
        return out

    return go


@CUDA_ONLY
@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_cuda_ours_triton(timed, size, query):
    pytest.importorskip("triton")
    p, v, f = _cuda_case(size, query)
    timed(_cgroup(size, query), OURS, _synced(lambda: point_mesh_distance(p, v, f, backend="triton")), 10)


@CUDA_ONLY
@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_cuda_ours_pruned_torch(timed, size, query):
    if size != "40k":
        pytest.skip("pure-torch pruned path: 40k only")
    p, v, f = _cuda_case(size, query)
    timed(_cgroup(size, query), "ours pruned (torch)", _synced(lambda: point_mesh_distance(p, v, f, backend="pruned")))


@CUDA_ONLY
@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_cuda_ours_bruteforce(timed, size, query):
    if size != "40k":
        pytest.skip("brute force: 40k only")
    p, v, f = _cuda_case(size, query)
    go = _synced(lambda: point_mesh_distance(p, v, f, backend="bruteforce"))
    timed(_cgroup(size, query), "ours bruteforce", go, 3)


@CUDA_ONLY
@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_cuda_warp(timed, size, query):
    wp, kernel = _warp_kernel()
    c = case(size)
    verts = wp.array(c["verts"], dtype=wp.vec3, device="cuda")
    indices = wp.array(c["faces"].astype(np.int32).ravel(), dtype=int, device="cuda")
    pts = wp.array(c[query], dtype=wp.vec3, device="cuda")

    def go():
        mesh = wp.Mesh(points=verts, indices=indices)
        out = wp.zeros(len(c[query]), dtype=float, device="cuda")
        wp.launch(kernel, dim=len(c[query]), inputs=[mesh.id, pts, out], device="cuda")
        wp.synchronize_device("cuda")
        return out

    timed(_cgroup(size, query), "warp (cuda)", go, 10)


def _cngroup(size: str) -> str:
    return f"CUDA {_ngroup(size)}"


@CUDA_ONLY
@pytest.mark.parametrize("size", SIZES)
def test_cuda_nearest_ours_triton(timed, size):
    pytest.importorskip("triton")
    c = case(size)
    p, r = torch.from_numpy(c["simplified"]).cuda(), torch.from_numpy(c["verts"]).cuda()
    timed(_cngroup(size), OURS, _synced(lambda: nearest_vertex_distance(p, r, backend="triton")), 10)


@CUDA_ONLY
@pytest.mark.parametrize("size", SIZES)
def test_cuda_nearest_bruteforce_cdist(timed, size):
    c = case(size)
    p, r = torch.from_numpy(c["simplified"]).cuda(), torch.from_numpy(c["verts"]).cuda()
    go = _synced(lambda: nearest_vertex_distance(p, r, backend="bruteforce"))
    timed(_cngroup(size), "ours bruteforce (chunked cdist)", go, 3)
