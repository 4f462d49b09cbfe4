"""``torchrun ... -m torchmeshmetric ctc-campaign``: frames shared by two ranks; rank 0 writes what one process does."""

from __future__ import annotations

from pathlib import Path

from tests.distributed.helpers import finish, torchrun
from tests.mpeg.test_ctc_campaign import _make
from torchmeshmetric.cli import main


def test_ctc_campaign_under_torchrun_equals_one_process(tmp_path: Path) -> None:
    """2 sequences x 2 codecs x 2 rates x 2 frames: each frame computed once by one of the ranks; same files."""
    manifest = _make(tmp_path)
    manifest.write_text(manifest.read_text().replace("frame_count = 5", "frame_count = 2"))
    args = ["ctc-campaign", str(manifest), "--no-plots"]
    assert main([*args, "--out-dir", str(tmp_path / "one"), "--cache-dir", str(tmp_path / "c1")]) == 0
    code, out, err = finish(
        torchrun("torchmeshmetric", *args, "--out-dir", str(tmp_path / "two"), "--cache-dir", str(tmp_path / "c2"))
    )
    assert code == 0, err
    assert out.count("# V-DMC CTC summary") == 1  # printed once, by rank 0
    computed = [
        line.split(":")[1]
        for line in err.splitlines()
        if line.startswith(("ctc-campaign: anchor", "ctc-campaign: test"))
    ]
    assert len(computed) == len(set(computed)) == 16  # each frame once, on one of the ranks
    for name in ("anchor.csv", "test.csv", "frames.csv", "summary.csv", "summary.md", "summary.json"):
        assert (tmp_path / "two" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name
    assert sorted(p.name for p in (tmp_path / "c2").rglob("*.json")) == sorted(
        p.name for p in (tmp_path / "c1").rglob("*.json")
    )
