"""Write the folders of ``examples/campaign.toml``: two built-in sequences, each simplified two ways.

    PYTHONPATH=. python examples/make_campaign_data.py examples/campaign-data [--frames 4] [--resolution 48]

Each ``seed<S>/`` gets ``original/`` (the built-in performer with seed ``S``) and two QEM simplifications of it:
``qem90/`` (keep 90 % of the faces) and ``qem50/`` (keep 50 %). Takes a few seconds at the default sizes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from torchmeshmetric.cli import main as cli
from torchmeshmetric.data import demo_sequence, save_mesh


def make(out: Path, frames: int, resolution: int, seeds: tuple[int, ...] = (0, 1)) -> None:
    for seed in seeds:
        folder = out / f"seed{seed}"
        (folder / "original").mkdir(parents=True, exist_ok=True)
        for k, frame in enumerate(demo_sequence(frames, resolution=resolution, seed=seed).frames):
            save_mesh(frame, folder / "original" / f"frame_{k:03d}.ply", overwrite=True)
        for name, target in (("qem90", "0.9"), ("qem50", "0.5")):
            argv = ["simplify", "--input", str(folder / "original"), "--output", str(folder / name)]
            code = cli([*argv, "--method", "qem", "--target", target, "--overwrite"])
            if code != 0:
                raise SystemExit(code)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="folder for seed0/ and seed1/ (created)")
    parser.add_argument("--frames", type=int, default=4, help="frames per sequence (default 4)")
    parser.add_argument("--resolution", type=int, default=48, help="demo_sequence resolution (default 48)")
    args = parser.parse_args()
    make(args.out, args.frames, args.resolution)
