"""DDP: two gloo processes on the CPU; the synced compute must equal one process on the union of the data."""

import os
import socket
import sys

import numpy as np
import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp
import trimesh

from torchmeshmetric.metrics import MeshSurfaceDistance, NearestVertexDistance


def _items():
    out = []
    for i, sub in enumerate([0, 1, 1, 2, 0]):
        ref = trimesh.creation.icosphere(subdivisions=sub + 1, radius=1.0 + 0.1 * i)
        rng = np.random.default_rng(i)
        simp = trimesh.creation.icosphere(subdivisions=sub, radius=1.0 + 0.1 * i)
        v = torch.from_numpy(simp.vertices + rng.normal(0, 0.02, simp.vertices.shape)).float()
        out.append(((v, torch.from_numpy(simp.faces)), ref))
    return out


# Uneven split: rank 0 gets 3 items in batches of 2 and 1, rank 1 gets 2 items in one batch.
_SPLIT = {0: [[0, 1], [2]], 1: [[3, 4]]}


def _metrics():
    return [
        MeshSurfaceDistance(two_sided=True),
        NearestVertexDistance(two_sided=True, exact_quantiles=False, relative_accuracy=0.01),
        # sampled mode: each mesh's samples its own (one stream per batch gave other samples by split, review Q)
        MeshSurfaceDistance(two_sided=True, surface_samples=300, seed=5),
    ]


def _worker(rank, port, out_dir):
    os.environ["MASTER_ADDR"] = "127.0.0.1"
    os.environ["MASTER_PORT"] = str(port)
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=2)
    items = _items()
    results = []
    for m in _metrics():
        for batch in _SPLIT[rank]:
            m.update([items[i][0] for i in batch], [items[i][1] for i in batch])
        results.append({k: float(v) for k, v in m.compute().items()})
    torch.save(results, os.path.join(out_dir, f"rank{rank}.pt"))
    dist.barrier()
    dist.destroy_process_group()


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.skipif(not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo")
def test_ddp_sync_equals_single_process_on_union(tmp_path):
    mp.spawn(_worker, args=(_free_port(), str(tmp_path)), nprocs=2, join=True)
    items = _items()
    expected = []
    for m in _metrics():
        m.update([it[0] for it in items], [it[1] for it in items])
        expected.append({k: float(v) for k, v in m.compute().items()})
    for rank in (0, 1):
        got = torch.load(tmp_path / f"rank{rank}.pt")
        for g, e in zip(got, expected, strict=True):
            assert g.keys() == e.keys()
            for k in e:
                assert g[k] == pytest.approx(e[k], rel=1e-12), k


# A rank that saw no distance, and ranks whose forward() calls differ in number (found by review): the moments rows
# were a "cat" state, one row per forward() call, which torchmetrics stacks after the gather ([2, 6] against [1, 6]
# stopped the sync), and an empty list of values went out as float32 beside float64 (gloo aborted the process).
_UNEVEN = {0: [[0, 1], [2], [3, 4]], 1: []}


def _uneven_worker(rank, port, out_dir, exact):
    from torchmeshmetric.metrics import DistanceStatisticsMetric

    os.environ["MASTER_ADDR"] = "127.0.0.1"
    os.environ["MASTER_PORT"] = str(port)
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=2)
    values = torch.arange(1.0, 6.0, dtype=torch.float64) ** 1.5
    m = DistanceStatisticsMetric(exact_quantiles=exact, relative_accuracy=0.01)
    for batch in _UNEVEN[rank]:
        m(values[batch])  # forward(): one call per batch, three on rank 0, none on rank 1
    torch.save({k: float(v) for k, v in m.compute().items()}, os.path.join(out_dir, f"uneven{rank}.pt"))
    dist.barrier()
    dist.destroy_process_group()


@pytest.mark.skipif(not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo")
@pytest.mark.parametrize("exact", [True, False])
def test_ddp_sync_with_a_rank_that_saw_nothing(tmp_path, exact):
    from torchmeshmetric.metrics import DistanceStatisticsMetric

    mp.spawn(_uneven_worker, args=(_free_port(), str(tmp_path), exact), nprocs=2, join=True)
    one = DistanceStatisticsMetric(exact_quantiles=exact, relative_accuracy=0.01)
    one.update(torch.arange(1.0, 6.0, dtype=torch.float64) ** 1.5)
    expected = {k: float(v) for k, v in one.compute().items()}
    for rank in (0, 1):
        got = torch.load(tmp_path / f"uneven{rank}.pt")
        assert got.keys() == expected.keys()
        for k in expected:
            assert got[k] == pytest.approx(expected[k], rel=1e-12), k
