"""``torchrun -m torchmeshmetric ...`` with 2 processes: the single-process report exactly; faults; shared cache.

The CLI runs with the exact registration of the test frames (tests/distributed/known_cli.py), so these tests test
the distribution, fast; test_torchrun_campaign.py runs the real registration.
"""

import json
import os
import subprocess
import sys

import pytest
import torch.distributed as dist

import tests.distributed.helpers as known
from tests.cli.cli_helpers import write_frames
from tests.distributed.helpers import ROOT, finish, same_report_set, torchrun, without_timings
from torchmeshmetric.cli import main

pytestmark = pytest.mark.skipif(
    not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo"
)

MODULE = "tests.distributed.known_cli"


@pytest.fixture
def frames(tmp_path):
    """5 original frames (4 pairs) and two methods."""
    return (
        write_frames(tmp_path / "orig", 2, n=5),
        write_frames(tmp_path / "a", 1, n=5),
        write_frames(tmp_path / "b", 0, n=5),
    )


def _compare_args(frames, out, *extra):
    orig, a, b = frames
    return ["compare", "--original", str(orig), "--method", f"A={a}", "--method", f"B={b}", "--out", str(out), *extra]


@pytest.fixture
def exact_registration(monkeypatch, tmp_path):
    """The same registration in this process, recording the frame k of every pair it registers."""
    calls = tmp_path / "calls-here"
    calls.mkdir()
    monkeypatch.setenv("TMM_TEST_CALLS", str(calls))
    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", known.register)
    return lambda: sorted(int(p.name.split("-")[0]) for p in calls.iterdir())


def _report_folders(tmp_path):
    """Two folders for reports of one name (the note under the tables names its JSON)."""
    (tmp_path / "single").mkdir(), (tmp_path / "dist").mkdir()
    return tmp_path / "single" / "r.json", tmp_path / "dist" / "r.json"


def test_two_processes_write_the_single_process_report(tmp_path, frames, exact_registration, capsys):
    single, dist = _report_folders(tmp_path)
    assert main(_compare_args(frames, single, "--threads", "1")) == 0
    capsys.readouterr()
    code, stdout, stderr = finish(torchrun(MODULE, *_compare_args(frames, dist)))
    assert code == 0, stderr
    same_report_set(single, dist)
    assert stdout.count("Table I:") == 1  # rank 0 alone prints the tables
    assert "frame pair 8/8" in stderr  # one display counting both methods' pairs on both ranks
    assert sorted(p.name for p in dist.parent.iterdir()) == ["r.csv", "r.json", "r.md"]


def test_determinacy_under_torchrun_is_the_single_process_one(tmp_path, frames, exact_registration, capsys):
    extra = ("--determinacy", "float32")
    single, dist = _report_folders(tmp_path)
    assert main(_compare_args(frames, single, "--threads", "1", *extra)) == 0
    capsys.readouterr()
    code, stdout, stderr = finish(torchrun(MODULE, *_compare_args(frames, dist, *extra)))
    assert code == 0, stderr
    same_report_set(single, dist)  # the nudged run too: the same draws
    assert "determinacy" in json.loads(dist.read_text())
    assert stdout.count("Table I:") == 1 and "this run's input determines" in stdout


def test_campaign_determinacy_under_torchrun_is_the_single_process_one(tmp_path, frames, exact_registration, capsys):
    orig, a, b = frames
    manifest = tmp_path / "campaign.toml"
    manifest.write_text(
        f'[[sequences]]\nname = "one"\noriginal = "{orig.name}"\nmethods = {{ A = "{a.name}", B = "{b.name}" }}\n'
        f'[[sequences]]\nname = "two"\noriginal = "{orig.name}"\nmethods = {{ B = "{b.name}" }}\n'
    )
    argv = ["campaign", str(manifest), "--determinacy", "1", "--out-dir"]
    assert main([*argv, str(tmp_path / "single"), "--threads", "1"]) == 0
    capsys.readouterr()
    (tmp_path / "dist").mkdir()
    code, stdout, stderr = finish(torchrun(MODULE, *argv, str(tmp_path / "dist")))
    assert code == 0, stderr
    for stem in ("campaign", "one", "two"):  # the nudged run is sharded like the first, with the same draws
        same_report_set(tmp_path / "single" / f"{stem}.json", tmp_path / "dist" / f"{stem}.json")
    assert "determinacy" in json.loads((tmp_path / "dist" / "campaign.json").read_text())
    assert stdout.count("(Table III)") == 1 and "this run's input determines" in stdout


@pytest.mark.parametrize("fault", ["kill", "raise"])
def test_a_failing_rank_fails_the_run_names_rank_and_pair_writes_nothing_and_rerun_resumes(
    tmp_path, frames, exact_registration, fault
):
    out = tmp_path / "report.json"
    out.write_text("previous report")
    cache = tmp_path / "cache"
    calls = tmp_path / "calls"
    calls.mkdir()
    env = {"TMM_TEST_FAULT": f"{fault}@2", "TMM_TEST_CALLS": str(calls)}
    code, _, stderr = finish(
        torchrun(MODULE, *_compare_args(frames, out, "--overwrite", "--cache-dir", str(cache)), env=env)
    )
    assert code != 0
    ours = [line for line in stderr.splitlines() if line.startswith("torchmeshmetric compare: error:")]
    assert len(ours) == 1, stderr
    # pair 1 -> 2 is task 1 of the first method: rank 1's (round robin)
    assert "rank 1 failed on method 'A' frame pair 1 -> 2" in ours[0]
    if fault == "raise":
        assert ours[0].endswith("ValueError: registration diverged (injected at frame 2)")
    assert out.read_text() == "previous report"
    assert not out.with_suffix(".md").exists() and not out.with_suffix(".csv").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    done = sorted(int(p.name.split("-")[0]) for p in calls.iterdir())
    # rank 0 registers pairs 0->1 and 2->3; under torchrun it may be stopped before finishing them (kill)
    assert 2 not in done and set(done) <= {1, 3} and (fault == "kill" or done == [1, 3])
    cached = len(list(cache.glob("*.pt")))
    # A killed run can be stopped between a registration and the write of its entry (the marker comes first):
    # entries never outnumber registrations, and every entry is complete (the rerun trusts them all).
    assert cached == len(done) if fault == "raise" else cached <= len(done)
    # the rerun (here: one process) computes exactly the registrations the failed run left no entry for
    assert main(_compare_args(frames, out, "--overwrite", "--cache-dir", str(cache))) == 0
    rerun = exact_registration()
    assert len(rerun) == 4 - cached and set(rerun) >= {1, 2, 3, 4} - set(done)
    assert fault == "kill" or rerun == sorted({1, 2, 3, 4} - set(done))
    assert json.loads(out.read_text())["methods"].keys() == {"A", "B"}


def test_two_concurrent_runs_share_one_cache_folder(tmp_path, frames, exact_registration):
    cache = tmp_path / "cache"
    expected = tmp_path / "expected.json"
    assert main(_compare_args(frames, expected, "--threads", "1")) == 0
    slow = {"TMM_TEST_SLOW": "0.3"}  # each registration takes 0.3 s: both runs write the same entries at once
    env = {**os.environ, "PYTHONPATH": str(ROOT), **slow}
    single = subprocess.Popen(
        [sys.executable, "-m", MODULE, *_compare_args(frames, tmp_path / "one.json", "--cache-dir", str(cache))],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    two = torchrun(MODULE, *_compare_args(frames, tmp_path / "two.json", "--cache-dir", str(cache)), env=slow)
    for proc in (single, two):
        code, _, stderr = finish(proc)
        assert code == 0, stderr
    for got in ("one.json", "two.json"):
        report = without_timings(json.loads((tmp_path / got).read_text()))
        want = without_timings(json.loads(expected.read_text()))
        for method in ("A", "B"):
            for pair, want_pair in zip(
                report["methods"][method]["pairs"], want["methods"][method]["pairs"], strict=True
            ):
                pair["registration"].pop("cached")
                want_pair["registration"].pop("cached")
        assert report["methods"] == want["methods"]
    # every entry is complete and trusted: a third run registers nothing
    assert len(list(cache.glob("*.pt"))) == 4 and not list(cache.glob(".*"))
    before = exact_registration()  # the subprocesses inherit TMM_TEST_CALLS: each run registers a pair at most once
    assert len(before) <= 4 + 2 * 4 and set(before) == {1, 2, 3, 4}
    assert main(_compare_args(frames, tmp_path / "third.json", "--cache-dir", str(cache))) == 0
    assert exact_registration() == before
