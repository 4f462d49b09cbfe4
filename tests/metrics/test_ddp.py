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
