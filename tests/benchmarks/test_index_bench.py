"""MeshIndex query-only against peers whose structure is also built once (FCPW, Open3D); refit against a build.

Run: ``python -m pytest tests/benchmarks/test_index_bench.py --benchmark-only -s`` (peers: ``pip install .[bench]``;
Open3D needs ``apt-get install -y libusb-1.0-0``). Add ``--benchmark-timer time.process_time`` for CPU time of the
whole process (all threads; what to quote on a shared machine), default is wall-clock.
``TMM_BENCH_INDEX_SIZES=40k,600k`` (default both).

Mesh: frame 0 of the built-in sequence (``demo_sequence(resolution=160)``, a captured-like frame of ~40k faces) and
its 4x midpoint subdivision twice (~640k faces, ``trimesh.remesh.subdivide``). Query sets: the vertices of a 50 %
QEM-simplified copy (``fast_simplification``, "simplified") and F/2 points on the surface with Gaussian noise of
0.2 % of the diagonal ("near"). Every contender's structure is built before timing; only queries are timed, and
each returns distances for all points. The ratio table compares ``ours`` with every peer (< 1: ours faster).
"""

from __future__ import annotations

import os
from functools import cache

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import MeshIndex
from torchmeshmetric.kernels.select import BVH

SIZES = [s for s in os.environ.get("TMM_BENCH_INDEX_SIZES", "40k,600k").split(",") if s]
QUERIES = ["simplified", "near"]
ROUNDS = 10


@cache
def case(size: str) -> dict[str, np.ndarray]:
    from torchmeshmetric.data import demo_sequence

    fs = pytest.importorskip("fast_simplification")
    frame = demo_sequence(1, resolution=160).frames[0]
    verts, faces = frame.verts.double().numpy(), frame.faces.numpy()
    if size == "600k":
        for _ in range(2):
            verts, faces = trimesh.remesh.subdivide(verts, faces)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    sv, _ = fs.simplify(verts, faces, target_reduction=0.5)
    rng = np.random.default_rng(0)
    diag = float(np.linalg.norm(verts.max(0) - verts.min(0)))
    near = mesh.sample(len(faces) // 2, seed=0) + rng.normal(scale=0.002 * diag, size=(len(faces) // 2, 3))
    return {
        "verts": np.ascontiguousarray(verts, dtype=np.float32),
        "faces": np.ascontiguousarray(faces, dtype=np.int64),
        "simplified": np.ascontiguousarray(sv, dtype=np.float32),
        "near": np.ascontiguousarray(near, dtype=np.float32),
    }


def _group(size: str, query: str) -> str:
    c = case(size)
    return f"query-only {size} ({len(c['faces'])} faces), {query} ({len(c[query])} points)"


def _run(benchmark, record, group: str, name: str, fn) -> None:
    benchmark.group = group
    benchmark.name = name
    benchmark.pedantic(fn, rounds=ROUNDS, iterations=1, warmup_rounds=1)
    record(group, name, benchmark.stats.stats.min)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_index_ours(benchmark, record, size, query):
    c = case(size)
    index = MeshIndex(torch.from_numpy(c["verts"]), torch.from_numpy(c["faces"]), backend="bvh")
    p = torch.from_numpy(c[query])
    index.point_mesh_distance(p[:1])  # builds the structure
    _run(benchmark, record, _group(size, query), "ours", lambda: index.point_mesh_distance(p).dists)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_index_fcpw(benchmark, record, size, query):
    fcpw = pytest.importorskip("fcpw")
    c = case(size)
    scene = fcpw.scene_3D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(c["verts"]), 0)
    scene.set_object_triangles(np.asfortranarray(c["faces"].astype(np.int32)), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True)  # vectorised BVH, built once
    q = np.asfortranarray(c[query])
    radii = np.full(len(q), np.inf, dtype=np.float32)

    def go():
        hits = fcpw.interaction_3D_list()
        scene.find_closest_points(q, radii, hits)
        return hits

    _run(benchmark, record, _group(size, query), "fcpw (vectorised bvh)", go)


@pytest.mark.parametrize("query", QUERIES)
@pytest.mark.parametrize("size", SIZES)
def test_index_open3d(benchmark, record, size, query):
    o3d = pytest.importorskip("open3d")
    c = case(size)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(c["verts"]), o3d.core.Tensor(c["faces"].astype(np.uint32)))
    q = o3d.core.Tensor(c[query])
    scene.compute_distance(q[:1])  # builds the scene
    _run(benchmark, record, _group(size, query), "open3d (embree)", lambda: scene.compute_distance(q))


@pytest.mark.parametrize("size", SIZES)
def test_refit_vs_build(benchmark, record, size):
    """``refit`` (bounds and face records of moved vertices, same tree) against a fresh build of the structure."""
    c = case(size)
    verts = torch.from_numpy(c["verts"])
    index = MeshIndex(verts, torch.from_numpy(c["faces"]), backend="bvh")
    index.point_mesh_distance(verts[:1])
    moved = verts + 0.01 * torch.sin(7 * verts[:, [1, 2, 0]])
    index.refit(moved)
    faceset, structure = index._faceset, index._faces.structure
    group = f"refit vs build {size} ({len(c['faces'])} faces)"
    _run(benchmark, record, group, "ours", lambda: BVH.refit_faces(structure, faceset))


@pytest.mark.parametrize("tree", ["sah", "morton"])
@pytest.mark.parametrize("size", SIZES)
def test_build(benchmark, record, size, tree):
    """A fresh build of the structure: the kept index's SAH tree, and the Morton tree of the one-off functions."""
    c = case(size)
    index = MeshIndex(torch.from_numpy(c["verts"]), torch.from_numpy(c["faces"]), backend="bvh")
    faceset = index._faceset
    group = f"refit vs build {size} ({len(c['faces'])} faces)"
    _run(benchmark, record, group, f"build ({tree})", lambda: BVH.build_faces(faceset, tree))
