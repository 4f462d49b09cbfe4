"""The CLI's torchrun glue: the environment, threads, refusals (no process group is started here)."""

import pytest
import torch

from torchmeshmetric.cli import main
from torchmeshmetric.launch import Launch, _cuda_device, launch_from_environment, thread_count


def test_environment_and_threads():
    env = {"RANK": "3", "WORLD_SIZE": "4", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "2"}
    job = launch_from_environment(env)
    assert job == Launch(rank=3, world_size=4, local_rank=1, local_world_size=2)
    assert launch_from_environment({"WORLD_SIZE": "1", "RANK": "0"}) is None
    assert thread_count(None, job, {}, cores=7) == 3  # unset: cores // local processes
    assert thread_count(None, job, {"OMP_NUM_THREADS": "1"}, cores=7) == 3  # torchrun's default
    assert thread_count(None, job, {"OMP_NUM_THREADS": "2"}, cores=7) is None  # the user's: torch honours it
    assert thread_count(None, Launch(0, 8, 0, 8), {}, cores=2) == 1
    assert thread_count(5, job, {"OMP_NUM_THREADS": "2"}, cores=7) == 5
    assert thread_count(None, None, {}, cores=7) is None  # one process: torch's own choice


@pytest.mark.parametrize(
    "command", [["demo", "--frames", "2"], ["register", "--source", "a", "--target", "b", "--out", "c"]]
)
def test_single_process_commands_refuse_torchrun(monkeypatch, capsys, command):
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("RANK", "0")
    assert main(command) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"torchmeshmetric {command[0]}: error: {command[0]} runs in one process; under torchrun use "
                   "evaluate, compare, campaign, ctc, ctc-campaign (WORLD_SIZE is 2)")  # fmt: skip


def test_threads_option(capsys, tmp_path):
    argv = ["register", "--source", str(tmp_path / "a.ply"), "--target", "b", "--out", "c", "--threads", "1"]
    assert main(argv) == 1
    assert torch.get_num_threads() == 1  # restored after the test (conftest)
    with pytest.raises(SystemExit):
        main(["register", "--source", "a", "--target", "b", "--out", "c", "--threads", "0"])
    from torchmeshmetric.cli.options import max_threads

    # the upper bound's reason is in the message since review X (F6: --threads 100000 segfaulted)
    assert f"expected an integer from 1 to {max_threads()} (4 per CPU core" in capsys.readouterr().err


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the message without a GPU")
def test_cuda_without_a_gpu_is_a_clear_error():
    with pytest.raises(RuntimeError, match="--device cuda: no CUDA device is available"):
        _cuda_device(Launch(0, 2, 0, 2))


def _failed_join(*args, **kwargs):
    raise RuntimeError("Gloo connectFullMesh failed with ... Connection closed by peer [127.0.0.1]:28810")


def test_a_rank_that_cannot_join_because_the_others_exited_stays_silent(monkeypatch, capsys, tmp_path):
    """The CI failure of 2026-12-06: a slow rank's join broke when the others, failing alike, had exited."""
    import os
    import signal
    import threading

    import torchmeshmetric.launch as launch

    for key, value in {"WORLD_SIZE": "3", "RANK": "1", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "3"}.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setattr(launch.dist, "init_process_group", _failed_join)
    argv = ["compare", "--original", str(tmp_path / "nope"), "--method", f"A={tmp_path / 'nope'}"]
    # torchrun stops the remaining ranks (SIGTERM) once one exits with its error: here 0.2 s after the failure.
    timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGTERM))
    timer.start()
    try:
        assert main(argv) == 1
    finally:
        timer.cancel()
    assert capsys.readouterr().err == ""
    assert signal.getsignal(signal.SIGTERM) is not launch._stop  # the handler is restored


def test_a_rank_that_cannot_join_and_is_not_stopped_says_why_with_its_rank(monkeypatch, capsys, tmp_path):
    import datetime

    import torchmeshmetric.launch as launch

    for key, value in {"WORLD_SIZE": "2", "RANK": "1", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "2"}.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setattr(launch.dist, "init_process_group", _failed_join)
    monkeypatch.setattr(launch, "ERROR_WAIT", datetime.timedelta(seconds=0.1))
    argv = ["compare", "--original", str(tmp_path / "nope"), "--method", f"A={tmp_path / 'nope'}"]
    assert main(argv) == 1
    assert capsys.readouterr().err.strip() == (
        "torchmeshmetric compare: error: rank 1: could not join the job's process group: Gloo connectFullMesh failed "
        "with ... Connection closed by peer [127.0.0.1]:28810"
    )


@pytest.mark.parametrize("rank", ["0", "1"])
def test_a_usage_error_or_help_is_printed_by_rank_0_alone(monkeypatch, capsys, rank):
    # Every rank reads the same command line: one message for the job, every rank exiting with argparse's code.
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("RANK", rank)
    with pytest.raises(SystemExit) as info:
        main(["compare", "--original", "o", "--method", "A=a", "--method", "B=b", "--determinacy", "400"])
    out, err = capsys.readouterr()
    assert info.value.code == 2 and out == ""
    assert ("argument --determinacy: expected 'float32' or a number of decimals 0..15, found '400'" in err) == (
        rank == "0"
    )
    assert (err == "") == (rank == "1")
    with pytest.raises(SystemExit) as info:
        main(["evaluate", "--help"])
    out, err = capsys.readouterr()
    assert info.value.code == 0 and err == "" and ("--determinacy" in out) == (rank == "0")
    assert (out == "") == (rank == "1")
