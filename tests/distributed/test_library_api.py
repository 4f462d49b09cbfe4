"""evaluate_sequence(distributed=True) inside a 2-process gloo group equals one process; failures name the rank."""

import os
import sys

import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from tests.distributed.helpers import free_port
from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import evaluate_sequence
from torchmeshmetric.registration import RegistrationCache
from torchmeshmetric.tasks import RankFailedError, run_tasks

pytestmark = pytest.mark.skipif(
    not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo"
)


def _frames():
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(5)]
    simplified = [sphere(1, radius=1.0 + 0.01 * k, offset=(0.1 * k, 0, 0)) for k in range(5)]
    return original, simplified


def _failing_task(x):
    if x == 3:
        raise ValueError("bad input 3")
    return x


def _worker(rank, port, out_dir):
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=2)
    try:
        original, simplified = _frames()
        register = TranslationRegister()
        seen = []
        result = evaluate_sequence(
            original,
            simplified,
            registration_fn=register,
            registration_cache=RegistrationCache(),
            distributed=True,
            progress=lambda done, total: seen.append((done, total)),
        )
        try:
            run_tasks(_failing_task, list(range(6)), describe=lambda x: f"item {x}")
            failure = None
        except RankFailedError as exc:
            failure = (exc.rank, exc.task, str(exc))
        torch.save(
            {"result": result, "calls": register.calls, "seen": seen, "failure": failure}, f"{out_dir}/{rank}.pt"
        )
    finally:
        dist.destroy_process_group()


def test_distributed_evaluate_sequence_equals_one_process_on_every_rank(tmp_path):
    mp.spawn(_worker, args=(free_port(), str(tmp_path)), nprocs=2, join=True)
    torch.set_num_threads(1)
    original, simplified = _frames()
    register = TranslationRegister()
    expected = evaluate_sequence(original, simplified, registration_fn=register)
    ranks = [torch.load(tmp_path / f"{r}.pt", weights_only=False) for r in (0, 1)]
    # the 4 registrations were shared: 2 per rank, none repeated
    assert [r["calls"] for r in ranks] == [2, 2]
    for got in ranks:
        assert [p.frame for p in got["result"].pairs] == [1, 2, 3, 4]
        for p, e in zip(got["result"].pairs, expected.pairs, strict=True):
            assert p.statistics == e.statistics and p.reverse_statistics == e.reverse_statistics
            assert p.registration_statistics == e.registration_statistics
            assert (p.motion, p.peak, p.registration_cached) == (e.motion, e.peak, e.registration_cached)
            for name, d in e.distances.items():
                assert torch.equal(p.distances[name], d)
        assert got["result"].aggregate() == expected.aggregate()
    # progress: rank 0 only, ending at all pairs done across ranks
    assert ranks[1]["seen"] == [] and ranks[0]["seen"][-1] == (4, 4)
    # item 3 runs on rank 1 (round robin); both ranks raise the same failure naming it
    for r in ranks:
        rank, task, message = r["failure"]
        assert (rank, task) == (1, "item 3") and message == "rank 1 failed on item 3: ValueError: bad input 3"


def test_distributed_without_a_process_group_runs_here():
    original, simplified = _frames()
    a = evaluate_sequence(original, simplified, registration_fn=TranslationRegister(), distributed=True)
    b = evaluate_sequence(original, simplified, registration_fn=TranslationRegister())
    assert [p.statistics for p in a.pairs] == [p.statistics for p in b.pairs]
    assert [p.frame for p in a.pairs] == [1, 2, 3, 4]
