"""Stability of the registration-based measurements: perturb the inputs, rerun, report the relative changes.

A measurement must be a continuous function of its input (issue 25): frame k-1's vertices moved by one ulp, scaled
by ``1 + 1e-9`` or ``1 + 1e-6``, or the registration run on another thread count must move the statistics of the
sets built on the registration (``surface_k_minus_1``, ``vertex_k_minus_1`` and ``flicker``) by about as much as
the input moved, not by percents. Shared by ``test_stability.py`` (small frames) and
``tests/benchmarks/test_registration_stability.py`` (~17k-vertex frames).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from torchmeshmetric.evaluation import evaluate_pair
from torchmeshmetric.registration import register_nonrigid
from torchmeshmetric.simplification import simplify_qem

STATISTICS = ("ave", "var", "std", "mse", "rmse", "max", "median", "p95")
"""The statistics compared (min and p99 follow from the same sets; count never changes)."""

PERTURBATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "ulp+": lambda v: np.nextafter(v, np.inf),
    "ulp-": lambda v: np.nextafter(v, -np.inf),
    "rel1e-9": lambda v: v * (1 + 1e-9),
    "rel1e-6": lambda v: v * (1 + 1e-6),
}
"""Perturbations of frame k-1's vertices (float64)."""


def _evaluate(
    simplified: tuple[Any, Any], k: tuple[Any, Any], km1: tuple[Any, Any], threads: int, seed: int, sampling: str
) -> dict[str, Any]:
    km1_t = (torch.as_tensor(km1[0]), torch.as_tensor(km1[1]))
    k_t = (torch.as_tensor(k[0]), torch.as_tensor(k[1]))
    generator = torch.Generator().manual_seed(seed)
    reg = register_nonrigid(km1_t, k_t, num_threads=threads, generator=generator, sampling=sampling)
    result = evaluate_pair(simplified[0], k_t, km1_t, precomputed_registration=reg, simplified_k_minus_1=simplified[1])
    stats = {name: {s: float(getattr(st, s)) for s in STATISTICS} for name, st in result.statistics.items()}
    return {"verts": reg.verts, "stats": stats, "converged": reg.converged}


def stability(
    original_k: tuple[np.ndarray, np.ndarray],
    original_k_minus_1: tuple[np.ndarray, np.ndarray],
    *,
    target: float = 0.5,
    perturbations: tuple[str, ...] = tuple(PERTURBATIONS),
    threads: tuple[int, ...] = (2,),
    seed: int = 0,
    sampling: str = "index",
) -> dict[str, dict[str, Any]]:
    """Per perturbation: the registered vertices' largest movement (fraction of frame k's diagonal) and, per set, the
    largest relative change among :data:`STATISTICS`.

    The simplified frames (QEM at ``target`` of the faces) are made once from the unperturbed frames; only frame
    k-1, the registration's source, is perturbed. ``threads``: the unperturbed pair registered on these thread
    counts too (the reference runs on one). ``seed``: the registration's generator seed (its random draws: data
    points, target samples, ICP points), the same for every run compared. ``sampling``: ``NonRigidOptions.sampling``
    (``"index"``, ``register_nonrigid``'s default, or ``"canonical"``, the evaluation's: ``REGISTRATION_SAMPLING``).
    """
    k_v, k_f = original_k
    km1_v, km1_f = original_k_minus_1
    simp_k = simplify_qem((torch.tensor(k_v), torch.tensor(k_f)), target)
    simp_km1 = simplify_qem((torch.tensor(km1_v), torch.tensor(km1_f)), target)
    diag = float(np.linalg.norm(k_v.max(0) - k_v.min(0)))
    base = _evaluate((simp_k, simp_km1), original_k, original_k_minus_1, 1, seed, sampling)
    cases = {name: (PERTURBATIONS[name](km1_v), 1) for name in perturbations}
    cases.update({f"threads={n}": (km1_v, n) for n in threads})
    out: dict[str, dict[str, Any]] = {}
    for name, (verts, n) in cases.items():
        run = _evaluate((simp_k, simp_km1), original_k, (verts, km1_f), n, seed, sampling)
        moved = float((run["verts"] - base["verts"]).norm(dim=1).max()) / diag
        sets = {}
        for set_name, stats in base["stats"].items():
            sets[set_name] = max(
                abs(run["stats"][set_name][s] - v) / abs(v) if v else abs(run["stats"][set_name][s])
                for s, v in stats.items()
            )
        out[name] = {"verts": moved, "sets": sets, "converged": run["converged"]}
    return out


def stability_table(results: dict[str, dict[str, Any]]) -> str:
    """A plain-text table: one row per perturbation, the vertex movement and each set's largest relative change."""
    names = sorted(next(iter(results.values()))["sets"])
    head = f"{'perturbation':14s} {'verts/diag':>10s} " + " ".join(f"{n:>18s}" for n in names)
    rows = [head]
    for case, r in results.items():
        rows.append(f"{case:14s} {r['verts']:10.1e} " + " ".join(f"{r['sets'][n]:18.1e}" for n in names))
    return "\n".join(rows)
