"""Under torchrun an error is printed once for the job, not once per rank (issue 23).

Before: every rank printed the same ``torchmeshmetric compare: error: ...`` line. Now rank 0 prints it and the other
ranks exit with the same code silently; an error that only a rank other than 0 saw is still printed, by that rank,
prefixed with its rank; the ranks torchrun then stops add no line of their own.
"""

import sys

import pytest
import torch.distributed as dist

from tests.cli.cli_helpers import write_frames
from tests.distributed.helpers import finish, torchrun

pytestmark = pytest.mark.skipif(
    not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo"
)

MODULE = "tests.distributed.known_cli"
PREFIX = "torchmeshmetric compare: error: "


@pytest.fixture
def frames(tmp_path):
    return write_frames(tmp_path / "orig", 1, n=3), write_frames(tmp_path / "a", 0, n=3)


def _ours(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith(PREFIX)]


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("count", "has 3 (must match; the original frames run from 0 to 2, these from 0 to 1): frame 2 of the"),
        ("missing", "no such directory"),
        # refused when parsed since 2026-12-07 (it was after the evaluation): a usage error, printed once too
        ("margin", "argument --relative-margin: expected a finite fraction >= 0, found '-1'"),
    ],
)
@pytest.mark.parametrize("nproc", [2, 3])
def test_an_error_of_every_rank_is_printed_once_by_rank_0(tmp_path, frames, case, message, nproc):
    orig, a = frames
    short = write_frames(tmp_path / "short", 0, n=2)
    method_b = {"count": short, "missing": tmp_path / "nope", "margin": a}[case]
    argv = ["compare", "--original", str(orig), "--method", f"A={a}", "--method", f"B={method_b}"]
    if case == "margin":
        argv += ["--relative-margin", "-1"]
    code, _, stderr = finish(torchrun(MODULE, *argv, nproc=nproc))
    assert code != 0
    ours = _ours(stderr)
    assert len(ours) == 1, stderr
    assert message.format(orig=str(orig)) in ours[0] and "rank " not in ours[0]


@pytest.mark.parametrize("rank", [0, 1])
def test_an_error_of_one_rank_alone_is_printed_by_it_once(tmp_path, frames, rank):
    orig, a = frames
    argv = ["compare", "--original", str(orig), "--method", f"A={a}"]
    code, _, stderr = finish(torchrun(MODULE, *argv, env={"TMM_TEST_RANK_ERROR": str(rank)}))
    assert code != 0
    ours = _ours(stderr)
    assert len(ours) == 1, stderr  # the stopped rank adds no "stopped by torchrun" line
    where = "" if rank == 0 else f"rank {rank}: "
    assert ours[0] == f"{PREFIX}{where}injected on rank {rank} only"
