"""``torchrun ... -m torchmeshmetric ctc``: frames shared by two ranks; rank 0 writes what one process writes."""

from __future__ import annotations

import json
from pathlib import Path

from tests.distributed.helpers import finish, torchrun
from tests.mpeg.test_cli_ctc import _sequence
from torchmeshmetric.cli import main


def test_ctc_under_torchrun_equals_one_process(tmp_path: Path) -> None:
    args = [*_sequence(tmp_path, 3), "--ibsm-resolution", "64"]
    assert main([*args, "--out", str(tmp_path / "one")]) == 0
    code, out, err = finish(torchrun("torchmeshmetric", *args, "--out", str(tmp_path / "two"), "--json"))
    assert code == 0, err
    d = json.loads(out)  # printed once, by rank 0
    one = json.loads((tmp_path / "one.json").read_text())
    two = json.loads((tmp_path / "two.json").read_text())
    assert two == one and d["mean"] == one["mean"] and [r["frame"] for r in d["frames"]] == [0, 1, 2]
    assert (tmp_path / "two.csv").read_text() == (tmp_path / "one.csv").read_text()
    assert sorted(line.split(":")[1] for line in err.splitlines() if line.startswith("ctc: frame")) == [
        " frame 0",
        " frame 1",
        " frame 2",
    ]  # each frame computed once, on one of the ranks
