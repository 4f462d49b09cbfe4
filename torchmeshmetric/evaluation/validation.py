"""Validation study: which distance sets respond to which controlled distortion (``torchmeshmetric validate``).

On the built-in sequence, whose true motion is known, a **tracked simplification** (frame 0 simplified once and
carried through the sequence by the true motion, see :mod:`~torchmeshmetric.evaluation.distortions`) is evaluated
with the true registration, then distorted at increasing strengths:

=====================  ======================================================================  ==================
distortion             what is injected (strength ``s``)                                       kind
=====================  ======================================================================  ==================
``noise``              Gaussian noise along the normal, std ``s``, new draw every frame        frame-k error
``simplification``     the tracked simplification keeps a fraction ``1 - s`` of its faces      frame-k error
``constant_offset``    every vertex moved by ``s`` along the normal, every frame               frame-k error
``alternating_offset`` every vertex moved by ``(-1)^k s`` along the normal                     flicker
``sliding``            vertices slid by ``s`` along the surface (random tangent, re-projected)  flicker (tangent)
``resimplification``   each frame re-simplified on its own to ``1 - s`` of the faces           flicker
``registration``       the true registration perturbed by a smooth random field of size ``s``  registration error
=====================  ======================================================================  ==================

For every distortion, set and statistic the study reports the values at each strength, their **Spearman rank
correlation** with the strength (does the set respond monotonically?) and the relative change from strength 0 to
the largest. ``docs/validation.md`` holds the measured tables and what each set measures and misses.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag, check_int
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.evaluation._validation_names import DISTORTIONS
from torchmeshmetric.evaluation.distortions import (
    ground_truth_registrations,
    normal_offset,
    surface_noise,
    tangential_slide,
    tracked_simplification,
)
from torchmeshmetric.evaluation.pipeline import evaluate_sequence
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.kernels import point_mesh_distance
from torchmeshmetric.registration.cache import CachedRegistration
from torchmeshmetric.simplification import simplify_qem
from torchmeshmetric.structures import Mesh

__all__ = [
    "DISTORTIONS",
    "REDUCED",
    "FULL",
    "MAX_FRAMES",
    "STRENGTHS",
    "ValidationResult",
    "check_validation_arguments",
    "run_validation",
    "spearman",
]

#: Strengths of the geometric distortions as fractions of the bounding-box diagonal; simplification levels as
#: fractions of faces removed.
_GEOMETRIC = (0.0, 0.125e-3, 0.25e-3, 0.5e-3, 1e-3, 2e-3)
_LEVELS = (0.0, 0.2, 0.4, 0.6, 0.8, 0.9)

#: The reduced study (tests, ``validate`` default): seconds on 2 cores.
REDUCED: dict[str, Any] = {"frames": 4, "resolution": 48, "keep": 0.5, "two_sided": True}
#: The full study (``validate --full``): the paper's frame size.
FULL: dict[str, Any] = {"frames": 6, "resolution": 160, "keep": 0.5, "two_sided": True}

#: Strengths at which each distortion is evaluated (one sequence evaluation each).
STRENGTHS = len(_LEVELS)
#: Most frames of the study: one motion cycle of the built-in sequence (``demo_sequence``'s ``frames_per_cycle``,
#: 24); more frames repeat its poses, so they add time (linear in the frames) but no new motion to respond to.
MAX_FRAMES = 24
# demo_sequence's lowest resolution, checked here with the other arguments before any work.
_MIN_RESOLUTION = 16

_STATISTICS = ("ave", "rmse", "p95", "max")


def check_validation_arguments(
    *, frames: int, resolution: int, keep: float, distortions: Sequence[str] | None = None
) -> list[str]:
    """Check :func:`run_validation`'s sizes before any work; the distortions to run.

    Args:
        frames: frames of the built-in sequence, 3 (two frame pairs) to :data:`MAX_FRAMES`.
        resolution: its mesh resolution, >= 16.
        keep: fraction of faces the tracked simplification keeps, in (0, 1].
        distortions: names from :data:`DISTORTIONS` (default: all); at least one.

    Returns:
        The names of the distortions to run, in the order given.

    Raises:
        ValueError: an argument out of range, named (``frames: ...``), or an empty or unknown distortion name.

    Example:
        >>> check_validation_arguments(frames=3, resolution=24, keep=0.5, distortions=["noise"])
        ['noise']
    """
    names = list(DISTORTIONS) if distortions is None else list(distortions)
    if not names:  # the study ran nothing and died on its empty tables (found by review)
        raise ValueError(f"distortions: expected at least one name from {list(DISTORTIONS)}, found none")
    unknown = [n for n in names if n not in DISTORTIONS]
    if unknown:
        raise ValueError(f"distortions: unknown {unknown}, expected names from {list(DISTORTIONS)}")
    if not 3 <= check_int(frames, "frames") <= MAX_FRAMES:
        raise ValueError(
            f"frames: expected 3 (two frame pairs) to {MAX_FRAMES} frames (one motion cycle of the built-in "
            f"sequence; more repeat its poses), found {frames!r}"
        )
    check_int(resolution, "resolution", _MIN_RESOLUTION)
    if not (isinstance(keep, (int, float)) and 0 < keep <= 1):  # NaN too
        raise ValueError(f"keep: expected a ratio of faces to keep in (0, 1], found {keep!r}")
    return names


def spearman(x: Sequence[float], y: Sequence[float]) -> float:
    """Spearman rank correlation (Pearson correlation of the ranks, ties sharing their mean rank).

    Returns NaN when either sequence is constant (no ranking to correlate).

    Example:
        >>> spearman([0, 1, 2, 3], [1.0, 1.5, 9.0, 10.0]), spearman([0, 1, 2], [3.0, 2.0, 1.0])
        (1.0, -1.0)
    """
    if len(x) != len(y) or len(x) < 2:
        raise ValueError(f"x, y: expected two sequences of the same length >= 2, found {len(x)} and {len(y)}")

    def ranks(v: Sequence[float]) -> np.ndarray:
        a = np.asarray(v, dtype=np.float64)
        order = np.argsort(a, kind="stable")
        r = np.empty(a.size)
        r[order] = np.arange(a.size, dtype=np.float64)
        for value in np.unique(a):  # ties: mean rank
            tie = a == value
            r[tie] = r[tie].mean()
        return r

    rx, ry = ranks(x), ranks(y)
    rx, ry = rx - rx.mean(), ry - ry.mean()
    denom = math.sqrt(float((rx * rx).sum() * (ry * ry).sum()))
    return float((rx * ry).sum() / denom) if denom > 0 else math.nan


class ValidationResult(NamedTuple):
    """Result of :func:`run_validation`.

    Attributes:
        settings: sizes and seeds of the run.
        distortions: per distortion: ``description``, ``strengths``, ``values`` (set → statistic → one value per
            strength, the mean over frame pairs), ``spearman`` and ``relative_change`` (set → statistic → number).
        registration: the true registration's residual statistics (mean over pairs) at strength 0.
        seconds: wall time of the study.
    """

    settings: dict[str, Any]
    distortions: dict[str, dict[str, Any]]
    registration: dict[str, float]
    seconds: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (non-finite numbers as strings is left to the writer)."""
        return {
            "settings": self.settings,
            "registration": self.registration,
            "distortions": self.distortions,
            "seconds": self.seconds,
        }

    def markdown(self, statistic: str = "ave") -> str:
        """Two Markdown tables: Spearman's rho and the relative change of ``statistic``, distortion x set."""
        sets = [s for s in next(iter(self.distortions.values()))["spearman"] if not s.startswith("registration:")]
        head = "| distortion | " + " | ".join(sets) + " |"
        rule = "|---|" + "---|" * len(sets)
        out = [f"### Spearman rank correlation of {statistic} with the strength", "", head, rule]
        for name, d in self.distortions.items():
            out.append(f"| {name} | " + " | ".join(_num(d["spearman"][s][statistic], 2) for s in sets) + " |")
        out += ["", f"### Relative change of {statistic} from strength 0 to the largest", "", head, rule]
        for name, d in self.distortions.items():
            cells = [_pct(d["relative_change"][s][statistic]) for s in sets]
            out.append(f"| {name} | " + " | ".join(cells) + " |")
        out += ["", "### Strengths", ""]
        for name, d in self.distortions.items():
            out.append(f"- `{name}` ({d['description']}): " + ", ".join(f"{s:.3g}" for s in d["strengths"]))
        return "\n".join(out) + "\n"


def _num(x: float, digits: int) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def _pct(x: float) -> str:
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "from 0"
    return f"{100 * x:+.0f} %"


def _smooth_field(points: Tensor, size: float, seed: int) -> Tensor:
    """A smooth random vector field of RMS ``size`` over the body (8 random sine waves of wavelength ~0.5)."""
    gen = torch.Generator().manual_seed(seed)
    freq = torch.randn(8, 3, generator=gen, dtype=torch.float64) * 4.0
    phase = torch.rand(8, generator=gen, dtype=torch.float64) * 2 * math.pi
    amp = torch.randn(8, 3, generator=gen, dtype=torch.float64)
    p = points.to(torch.float64)
    field = torch.sin(p @ freq.T + phase) @ amp / math.sqrt(8 * 3 / 2)  # unit RMS per component on average
    return (size * field / math.sqrt(3)).to(points)


class _PerturbedWarp:
    def __init__(self, warp: Any, size: float, seed: int) -> None:
        self.warp, self.size, self.seed = warp, size, seed

    def __call__(self, points: Tensor, /) -> Tensor:
        moved = self.warp(points)
        return moved + _smooth_field(moved, self.size, self.seed)


def _perturbed(regs: list[CachedRegistration], frames: list[Mesh], size: float, seed: int) -> list[CachedRegistration]:
    out = []
    for k, reg in enumerate(regs, start=1):
        warp = _PerturbedWarp(reg.warp, size, seed + k)
        verts = warp(frames[k - 1].verts)
        with torch.no_grad():
            residual = point_mesh_distance(verts, frames[k]).dists
        out.append(CachedRegistration(verts, residual, True, 0.0, warp))
    return out


def run_validation(
    *,
    frames: int = REDUCED["frames"],
    resolution: int = REDUCED["resolution"],
    keep: float = REDUCED["keep"],
    two_sided: bool = REDUCED["two_sided"],
    seed: int = 0,
    distortions: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> ValidationResult:
    """Run the validation study on the built-in sequence (see the module docstring).

    Args:
        frames: frames of the built-in sequence, 3 (two frame pairs) to :data:`MAX_FRAMES` (one motion cycle).
        resolution: its mesh resolution, >= 16 (48: ~3.5k faces per frame; 160: the paper's ~40k).
        keep: fraction of faces the tracked simplification keeps, in (0, 1].
        two_sided: also evaluate the reverse sets.
        seed: seed of the sequence and of the random distortions.
        distortions: names from :data:`DISTORTIONS` (default: all).
        progress: called with each distortion's name when it is done.

    Returns:
        :class:`ValidationResult`.

    Example:
        >>> r = run_validation(frames=3, resolution=24, distortions=["alternating_offset"])
        >>> d = r.distortions["alternating_offset"]
        >>> rho = d["spearman"]
        >>> flicker = rho["flicker"]
        >>> round(flicker["ave"], 2), len(d["strengths"])
        (1.0, 6)
    """
    two_sided = check_flag(two_sided, "two_sided")
    names = check_validation_arguments(frames=frames, resolution=resolution, keep=keep, distortions=distortions)
    start = time.perf_counter()
    seq = demo_sequence(frames, resolution=resolution, seed=seed)
    originals = [f.to(dtype=torch.float64) for f in seq.frames]
    diag = float(originals[0].bbox_diagonal())
    regs = ground_truth_registrations(originals, seq.transfer)
    base = tracked_simplification(originals, simplify_qem(originals[0], keep), seq.transfer)
    n = len(originals)

    def evaluate(simplified: list[Mesh], registrations: list[CachedRegistration] | None = None) -> SequenceEvaluation:
        return evaluate_sequence(
            originals,
            simplified,
            precomputed_registrations=regs if registrations is None else registrations,
            two_sided=two_sided,
            ground_truth=seq.transfer,
        )

    def resimplified(level: float) -> list[Mesh]:
        if level == 0:
            return base
        # a tiny random slide first (1e-5 of the diagonal) so that each frame's collapse order is its own draw
        jittered = tangential_slide(base, originals, 1e-5 * diag, seed=seed + 7)
        return [simplify_qem(m, 1.0 - level) for m in jittered]

    def tracked_at(level: float) -> list[Mesh]:
        if level == 0:
            return base
        return tracked_simplification(originals, simplify_qem(originals[0], keep * (1.0 - level)), seq.transfer)

    makers: dict[str, Callable[[float], SequenceEvaluation]] = {
        "noise": lambda s: evaluate(surface_noise(base, originals, s, seed=seed + 1)),
        "simplification": lambda s: evaluate(tracked_at(s)),
        "constant_offset": lambda s: evaluate(normal_offset(base, originals, [s] * n)),
        "alternating_offset": lambda s: evaluate(normal_offset(base, originals, [s * (-1) ** k for k in range(n)])),
        "sliding": lambda s: evaluate(tangential_slide(base, originals, s, seed=seed + 2)),
        "resimplification": lambda s: evaluate(resimplified(s)),
        "registration": lambda s: evaluate(base, _perturbed(regs, originals, s, seed + 3)),
    }
    results: dict[str, dict[str, Any]] = {}
    registration: dict[str, float] = {}
    for name in names:
        levels = _LEVELS if name in ("simplification", "resimplification") else tuple(f * diag for f in _GEOMETRIC)
        evaluations = [makers[name](s) for s in levels]
        if not registration:
            registration = evaluations[0].aggregate_registration()["residual"]
        results[name] = _summarise(DISTORTIONS[name], levels, evaluations, 1e-9 * diag)
        if progress is not None:
            progress(name)
    settings = {"frames": frames, "resolution": resolution, "keep": keep, "two_sided": two_sided, "seed": seed}
    settings["faces_per_frame"] = int(np.mean([f.num_faces for f in originals]))
    settings["diagonal"] = diag
    return ValidationResult(settings, results, registration, time.perf_counter() - start)


def _summarise(
    description: str, strengths: Sequence[float], evaluations: list[SequenceEvaluation], zero: float
) -> dict[str, Any]:
    """Values (mean over pairs), Spearman's rho and relative change; values at most ``zero`` count as 0."""
    aggregates = [e.aggregate() for e in evaluations]
    for agg, e in zip(aggregates, evaluations, strict=True):
        agg.update({f"reverse:{k}": v for k, v in e.aggregate_reverse().items()})
        agg.update({f"registration:{k}": v for k, v in e.aggregate_registration().items()})
    values = {s: {st: [float(a[s][st]) for a in aggregates] for st in _STATISTICS} for s in aggregates[0]}
    rho = {s: {st: spearman(strengths, v) for st, v in stats.items()} for s, stats in values.items()}
    change: dict[str, dict[str, float]] = {}
    for s, stats in values.items():
        change[s] = {}
        for st, v in stats.items():
            if abs(v[0]) <= zero:  # exactly on the surface up to rounding
                change[s][st] = 0.0 if abs(v[-1]) <= zero else math.inf
            else:
                change[s][st] = v[-1] / v[0] - 1.0
    return {
        "description": description,
        "strengths": list(strengths),
        "values": values,
        "spearman": rho,
        "relative_change": change,
    }
