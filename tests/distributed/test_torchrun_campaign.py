"""A campaign with the real (fast preset) registration: 2 torchrun processes write the single-process reports.

Registration results depend on the torch thread count (parallel float32 reductions inside the optimisation), so
both runs use one thread per process; with that, every report file is identical (JSON but for wall-clock timings).
"""

import sys

import pytest
import torch.distributed as dist

from tests.distributed.helpers import finish, same_report_set, torchrun
from torchmeshmetric.cli import main
from torchmeshmetric.data import demo_sequence, save_mesh
from torchmeshmetric.simplification import simplify_qem

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not dist.is_available() or sys.platform == "win32", reason="needs torch.distributed with gloo"),
]

MANIFEST = """
[options]
registration = "fast"

[[sequences]]
name = "seed0"
original = "seed0/original"
methods = { "QEM 50%" = "seed0/qem50", "QEM 90%" = "seed0/qem90" }

[[sequences]]
name = "seed1"
original = "seed1/original"
methods = { "QEM 50%" = "seed1/qem50" }
"""


def _write_campaign(root):
    for seed in (0, 1):
        frames = demo_sequence(3, resolution=24, seed=seed).frames
        for name, target in (("original", None), ("qem50", 0.5), ("qem90", 0.9)):
            folder = root / f"seed{seed}" / name
            folder.mkdir(parents=True)
            for k, frame in enumerate(frames):
                save_mesh(frame if target is None else simplify_qem(frame, target), folder / f"frame_{k}.ply")
    (root / "campaign.toml").write_text(MANIFEST)
    return root / "campaign.toml"


def test_two_processes_write_the_single_process_campaign_reports(tmp_path):
    manifest = _write_campaign(tmp_path)
    assert main(["campaign", str(manifest), "--out-dir", str(tmp_path / "single"), "--threads", "1"]) == 0
    code, _, stderr = finish(torchrun("torchmeshmetric", "campaign", str(manifest), "--out-dir", str(tmp_path / "two"),
                                      "--threads", "1"))  # fmt: skip
    assert code == 0, stderr
    assert "frame pair 6/6" in stderr  # 4 pairs of the first methods, then 2 of the second
    for stem in ("campaign", "seed0", "seed1"):
        same_report_set(tmp_path / "single" / f"{stem}.json", tmp_path / "two" / f"{stem}.json")
