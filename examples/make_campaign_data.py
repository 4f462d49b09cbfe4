"""Write the folders of ``examples/campaign.toml``: two built-in sequences, each simplified two ways.

    PYTHONPATH=. python examples/make_campaign_data.py examples/campaign-data [--frames 4] [--resolution 48]

Each ``seed<S>/`` gets ``original/`` (the built-in performer with seed ``S``) and two QEM simplifications of it:
``qem90/`` (keep 90 % of the faces) and ``qem50/`` (keep 50 %). Takes a few seconds at the default sizes.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
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


def _at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an int >= ``low``, refused when parsed, before any folder is made."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an int >= {low}, found {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected an int >= {low}, found {value}")
        return value

    return parse


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="folder for seed0/ and seed1/ (created)")
    # A campaign evaluates frame pairs: 2 frames at least (0 made seed0/ and then died in demo_sequence).
    parser.add_argument("--frames", type=_at_least(2), default=4, help="frames per sequence (>= 2; default 4)")
    parser.add_argument(
        "--resolution", type=_at_least(16), default=48, help="demo_sequence resolution (>= 16; default 48)"
    )
    args = parser.parse_args()
    make(args.out, args.frames, args.resolution)
