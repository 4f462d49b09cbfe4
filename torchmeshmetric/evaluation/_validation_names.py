"""The distortions of the validation study by name: a table without torch, which the command line's parser reads."""

from __future__ import annotations

__all__ = ["DISTORTIONS"]

#: Distortions of the study, in report order, with the kind of defect each one injects.
DISTORTIONS: dict[str, str] = {
    "noise": "frame-k error: Gaussian noise along the normal (std s), new every frame",
    "simplification": "frame-k error: the tracked simplification keeps a fraction 1 - s of its faces",
    "constant_offset": "frame-k error: every vertex moved by s along the normal, every frame",
    "alternating_offset": "flicker: every vertex moved by (-1)^k s along the normal",
    "sliding": "flicker along the surface: vertices slid by s in a random tangent direction, re-projected",
    "resimplification": "flicker: every frame re-simplified on its own to 1 - s of the faces",
    "registration": "registration error: the true registration plus a smooth random field of size s",
}
