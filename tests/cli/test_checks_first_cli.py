"""``compare`` / ``evaluate`` / ``campaign`` refuse a method with the wrong frame count before any work (issue 23)."""

from __future__ import annotations

import pytest

from tests.cli.cli_helpers import write_frames
from torchmeshmetric.cli import main


@pytest.fixture
def pair_calls(monkeypatch):
    """Counts the frame pairs evaluated (the work that must not start before the checks)."""
    import torchmeshmetric.evaluation.pipeline as pipeline

    calls = []
    real = pipeline.evaluate_pair

    def counting(*args, **kwargs):
        calls.append(kwargs.get("frame"))
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "evaluate_pair", counting)
    return calls


@pytest.mark.parametrize("bad", [0, 1, 2])  # the short method first, in the middle, last
@pytest.mark.parametrize("mpeg", [False, True])
def test_compare_checks_every_method_before_the_first_is_evaluated(
    capsys, tmp_path, sequence, known_registration, pair_calls, bad, mpeg
):
    orig, simp = sequence
    short = write_frames(tmp_path / "short", 0, n=2)
    specs = [f"M{i}={short if i == bad else simp}" for i in range(3)]
    argv = ["compare", "--original", str(orig), *[a for s in specs for a in ("--method", s)]]
    code = main(argv + (["--mpeg"] if mpeg else []))
    err = capsys.readouterr().err
    assert code == 1
    # the folders number their frames: the message names the frame the short one lacks (review O)
    assert (
        f"torchmeshmetric compare: error: --method M{bad} {str(short)!r}: 2 frames but --original {str(orig)!r} has 3 "
        "(must match; the original frames run from 0 to 2, these from 0 to 1): frame 2 of the original frames "
        "('frame_02.ply') is missing here"
    ) in err
    assert known_registration.calls == 0 and pair_calls == []  # nothing was registered or measured


def test_campaign_checks_every_sequence_before_any_work(capsys, tmp_path, known_registration, pair_calls):
    a = write_frames(tmp_path / "a", 1)
    short = write_frames(tmp_path / "short", 0, n=2)
    manifest = tmp_path / "c.toml"
    manifest.write_text(
        f'[[sequences]]\nname = "first"\noriginal = "{a}"\nmethods = {{ m = "{a}" }}\n'
        f'[[sequences]]\nname = "second"\noriginal = "{a}"\nmethods = {{ m = "{a}", s = "{short}" }}\n'
    )
    assert main(["campaign", str(manifest)]) == 1
    err = capsys.readouterr().err
    assert (
        f"sequence 'second': method 's' {str(short)!r}: 2 frames but sequence 'second': original {str(a)!r} has 3 "
        "(must match; the original frames run from 0 to 2, these from 0 to 1): frame 2 of the original frames "
        "('frame_02.ply') is missing here"
    ) in err
    assert known_registration.calls == 0 and pair_calls == []
