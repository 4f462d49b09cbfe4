"""How much of the target a correct registration leaves uncovered, against a limb registered onto another limb.

Run (minutes; one thread): ``python -m tests.benchmarks.coverage_margins [--models DIR] [--only GROUP ...]
--out /tmp/coverage.json``, ``DIR`` holding CraGL/Hyperspectral-Inverse-Skinning's ``models/<name>/`` folders of
OBJ frames (horse-gallop, samba, crane, chickenCrossing, cow: use them from a scratch folder, never commit them);
without it only the built-in pairs run. Not collected by pytest (no ``test_`` prefix).

For every pair (the demo at several resolutions, the campaign example's frames, the ground-truth and captured-like
pairs, consecutive CraGL frames, QEM-simplified sources onto the next original frame, and constructed failures:
horse-gallop 3 -> 4, a far sphere, an extra part added to the target) it registers with the default options (the
campaign's ``fast`` ones where the campaign uses them) and records, in units of the target's diagonal:

* the distance of each of the fit's own target samples (those :meth:`_Fit.plausibility` judges, with its area
  weights) to the registered source, and of 20,000 denser area-uniform target samples;
* each surface vertex's residual (distance of the registered source to the target);
* the scales a threshold could be relative to: mean and median edge length of target and source, the graph's node
  spacing (median distance of a node to its nearest node);
* where the truth is known (same-connectivity frames, the demo's motion, the ground-truth pairs), the registered
  vertices' error, so that a pair is labelled a failure by what happened, not by the rule being tuned.

Then prints, for each candidate distance (fixed fractions of the diagonal, multiples of an edge length, of the node
spacing, and the max of a fixed fraction and a multiple), the fraction of target samples and of source vertices
beyond it, per pair; and the margin between the largest fraction of a correct pair and the smallest of a failure.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch

from torchmeshmetric.kernels import point_mesh_distance, sample_surface
from torchmeshmetric.registration import nonrigid as nonrigid_module
from torchmeshmetric.registration import register_nonrigid
from torchmeshmetric.registration.nonrigid import RegistrationWarning

Pair = dict[str, Any]
"""``source``/``target`` as ``(verts (V, 3) float64 ndarray, faces (F, 3) int64 ndarray)``, ``truth`` (the
source vertices' true positions in the target frame, or ``None``), ``label`` ("correct", "failure" or "unknown"),
``options`` (registration keywords)."""


def _np(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(mesh, tuple):
        return np.asarray(mesh[0], dtype=np.float64), np.asarray(mesh[1], dtype=np.int64)
    return mesh.verts.double().numpy(), mesh.faces.numpy().astype(np.int64)


def _edges(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    e = e[e[:, 0] != e[:, 1]]
    return np.linalg.norm(verts[e[:, 0]] - verts[e[:, 1]], axis=1)


def _fast() -> dict[str, Any]:
    from torchmeshmetric.cli._shared import fast_registration_options

    return fast_registration_options()


def _qem(verts: np.ndarray, faces: np.ndarray, keep: float) -> tuple[np.ndarray, np.ndarray]:
    import fast_simplification

    pts, tri = fast_simplification.simplify(verts, faces, target_reduction=1.0 - keep)
    return np.asarray(pts, dtype=np.float64), np.asarray(tri, dtype=np.int64)


def _with_extra_part(
    target: tuple[np.ndarray, np.ndarray], fraction: float, shift: float
) -> tuple[np.ndarray, np.ndarray]:
    """The target plus a copy of its faces nearest to its highest vertex (``fraction`` of its area), moved by
    ``shift`` diagonals along x: a part of the target that no part of the source can reach."""
    v, f = target
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    centroids = v[f].mean(1)
    top = v[np.argmax(v[:, 1])]
    order = np.argsort(np.linalg.norm(centroids - top, axis=1))
    a = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1) / 2
    n = int(np.searchsorted(np.cumsum(a[order]), fraction * a.sum())) + 1
    part = f[order[:n]]
    used, inv = np.unique(part, return_inverse=True)
    pv = v[used] + np.array([shift * diag, 0.0, 0.0])
    return np.concatenate([v, pv]), np.concatenate([f, inv.reshape(-1, 3) + v.shape[0]])


def pairs(models: Path | None, only: set[str] | None) -> Iterator[tuple[str, str, Callable[[], Pair]]]:
    """``(group, name, make)`` of every pair measured; ``make`` builds it (lazily: meshing takes seconds)."""
    from tests.registration.gt_pairs import make_captured_pair, make_pair
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.data.sequence import load_sequence

    def want(group: str) -> bool:
        return only is None or group in only

    @functools.lru_cache(maxsize=4)
    def sequence(frames: int, resolution: int, seed: int) -> Any:
        return demo_sequence(frames, resolution=resolution, seed=seed, dtype=torch.float64)

    def demo(resolution: int, k: int, frames: int, options: dict[str, Any], seed: int = 0) -> Pair:
        seq = sequence(frames, resolution, seed)
        s, t = seq.frames[k], seq.frames[k + 1]
        truth = seq.transfer(s.verts.double(), k, k + 1).numpy()
        return {"source": _np(s), "target": _np(t), "truth": truth, "label": "correct", "options": options}

    for res, ks in ((16, range(5)), (24, range(5)), (48, range(3)), (160, range(2))):
        if want(f"demo-{res}"):
            for k in ks:
                yield f"demo-{res}", f"demo-{res} {k}->{k + 1}", lambda r=res, k=k: demo(r, k, 6, {})
    if want("coarse-seeds"):
        # The coarsest meshes (resolution 16: ~160 vertices, edges ~0.055 of the diagonal) are where a correct fit
        # leaves the most uncovered: other seeds (proportions, grid offsets) and resolution 20.
        for res, seeds in ((16, (1, 2, 3)), (20, (0, 1))):
            for seed in seeds:
                for k in range(5):
                    yield (
                        "coarse-seeds",
                        f"demo-{res} seed{seed} {k}->{k + 1}",
                        (lambda r=res, s=seed, k=k: demo(r, k, 6, {}, seed=s)),
                    )
    if want("campaign"):
        # examples/make_campaign_data.py as tests/examples runs it (2 frames at resolution 16; the campaign's "fast"
        # registration) and its own defaults (4 frames at resolution 48), seeds 0 and 1.
        for res, frames in ((16, 2), (48, 4)):
            for seed in (0, 1):
                for k in range(frames - 1):
                    yield (
                        "campaign",
                        f"campaign-{res} seed{seed} {k}->{k + 1}",
                        (lambda r=res, f=frames, s=seed, k=k: demo(r, k, f, _fast(), seed=s)),
                    )
    if want("gt"):
        for level in ("small", "medium", "large"):
            for spacing in (0.05, 0.0145):

                def gt(level: str = level, spacing: float = spacing) -> Pair:
                    p = make_pair(level, spacing)
                    return {"source": p.source, "target": p.target, "truth": p.gt_verts, "label": "correct",
                            "options": {}}  # fmt: skip

                yield "gt", f"gt-{level} {spacing}", gt
    if want("captured"):
        for level, spacing in (("small", 0.035), ("medium", 0.035), ("large", 0.035), ("medium", 0.0135)):

            def cap(level: str = level, spacing: float = spacing) -> Pair:
                p = make_captured_pair(level, spacing)
                return {"source": p.source, "target": p.target, "truth": p.gt_verts, "label": "correct", "options": {}}

            yield "captured", f"captured-{level} {spacing}", cap
    if want("simplified"):
        # The paper's set (b) registers the originals (k-1 onto k); a simplified source is measured too, in case a
        # caller registers one (coarse source: its chords leave the target's curved parts farther away).
        for keep in (0.5, 0.1):
            for res in (48, 160):

                def simp(res: int = res, keep: float = keep) -> Pair:
                    p = demo(res, 0, 2, {})
                    return {**p, "source": _qem(*p["source"], keep), "truth": None}

                yield "simplified", f"qem{int(keep * 100)} demo-{res} 0->1", simp
    if want("constructed"):
        import trimesh

        def sphere() -> Pair:
            big = trimesh.creation.icosphere(subdivisions=3)
            small = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
            small.vertices += [3.0, 0.0, 0.0]
            tgt = trimesh.util.concatenate([big, small])
            return {"source": _np((big.vertices, big.faces)), "target": _np((tgt.vertices, tgt.faces)),
                    "truth": None, "label": "failure", "options": {}}  # fmt: skip

        yield "constructed", "far sphere (test)", sphere
        for res in (16, 48):
            for frac in (0.01, 0.03):

                def extra(res: int = res, frac: float = frac) -> Pair:
                    p = demo(res, 0, 2, {})
                    return {**p, "target": _with_extra_part(p["target"], frac, 0.3), "truth": None, "label": "failure"}

                yield "constructed", f"demo-{res} 0->1 + {100 * frac:g}% far part", extra
    if models is None:
        return
    spans = {"horse-gallop": 11, "samba": 8, "crane": 8, "chickenCrossing": 7, "cow": 6}
    for model, span in spans.items():
        folder = models / model
        if not folder.is_dir() or not want(model):
            continue
        frames = [_np(m) for m in load_sequence(folder, dtype=torch.float64)[: span + 1]]
        same = all(f[1].shape == frames[0][1].shape and (f[1] == frames[0][1]).all() for f in frames)
        for k in range(span):
            s, t = frames[k], frames[k + 1]

            def cragl(s: Any = s, t: Any = t, same: bool = same) -> Pair:
                return {"source": s, "target": t, "truth": t[0] if same else None, "label": "correct" if same
                        else "unknown", "options": {}}  # fmt: skip

            yield model, f"{model} {k}->{k + 1}", cragl
        if model == "horse-gallop":
            for keep in (0.5, 0.1):
                for k in (0, 4):

                    def hs(k: int = k, keep: float = keep, frames: list[Any] = frames) -> Pair:
                        return {"source": _qem(*frames[k], keep), "target": frames[k + 1], "truth": None,
                                "label": "correct", "options": {}}  # fmt: skip

                    yield "simplified", f"qem{int(keep * 100)} horse-gallop {k}->{k + 1}", hs
            for k in (0, 3, 6):

                def skip(k: int = k, frames: list[Any] = frames) -> Pair:
                    return {"source": frames[k], "target": frames[k + 2], "truth": frames[k + 2][0],
                            "label": "correct", "options": {}}  # fmt: skip

                yield "horse-skip", f"horse-gallop {k}->{k + 2}", skip

            def horse_extra(frames: list[Any] = frames) -> Pair:
                return {"source": frames[0], "target": _with_extra_part(frames[1], 0.02, 0.3), "truth": None,
                        "label": "failure", "options": {}}  # fmt: skip

            yield "constructed", "horse-gallop 0->1 + 2% far part", horse_extra


def measure(pair: Pair, dense: int = 20000) -> dict[str, Any]:
    """Register the pair (one thread, float64) and return what the plausibility check sees, in diagonals."""
    seen: dict[str, Any] = {}
    original = nonrigid_module._Fit.plausibility

    def spy(self: Any) -> Any:
        out = original(self)
        with torch.no_grad():
            far = self.source_index.point_mesh_distance_unchecked(self.samples, nonrigid_module._lengths(self.samples))
            # Sorted by distance, with the area weights plausibility averages them with (drawn by face, not by area).
            order = far.dists.argsort()
            seen["fit_target"] = far.dists[order].numpy().copy()
            seen["fit_weights"] = self.sample_weights[order].numpy().copy()
            # The library's h (mean edge of the finer mesh, per face, in diagonals), not this script's unique edges.
            frame = self.frame
            seen["finer_edge"] = min(nonrigid_module._mean_edge_length(m) for m in (frame.source, frame.target))
            nodes = self.graph.nodes
            d = torch.cdist(nodes, nodes)
            d.fill_diagonal_(math.inf)
            seen["node_spacing"] = float(d.min(1).values.median())
            seen["surface"] = self.frame.source.surface_vertex_mask().numpy().copy()
        return out

    nonrigid_module._Fit.plausibility = spy  # type: ignore[method-assign]
    try:
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RegistrationWarning)
            r = register_nonrigid(pair["source"], pair["target"], num_threads=1, **pair["options"])
        seconds = time.perf_counter() - t0
    finally:
        nonrigid_module._Fit.plausibility = original  # type: ignore[method-assign]
    sv, sf = pair["source"]
    tv, tf = pair["target"]
    diag = float(np.linalg.norm(tv.max(0) - tv.min(0)))
    tgt_t = (torch.from_numpy(tv), torch.from_numpy(tf))
    samples = sample_surface(*tgt_t, n=dense, generator=torch.Generator().manual_seed(1)).points
    dense_d = point_mesh_distance(samples, r.mesh).dists.numpy() / diag
    residual = r.residual.numpy() / diag
    e_t, e_s = _edges(tv, tf) / diag, _edges(sv, sf) / diag
    out: dict[str, Any] = {
        "label": pair["label"],
        "num_source_verts": int(sv.shape[0]),
        "num_target_verts": int(tv.shape[0]),
        "converged": bool(r.converged),
        "reason": r.reason,
        "warnings": len(caught),
        "seconds": seconds,
        "target_edge_mean": float(e_t.mean()),
        "target_edge_median": float(np.median(e_t)),
        "source_edge_mean": float(e_s.mean()),
        "source_edge_median": float(np.median(e_s)),
        "node_spacing": seen["node_spacing"],
        "fit_target": seen["fit_target"].tolist(),
        "fit_weights": seen["fit_weights"].tolist(),
        "finer_edge": seen["finer_edge"],
        "dense_target": np.sort(dense_d).tolist(),
        "source": np.sort(residual[seen["surface"]] if seen["surface"].shape == residual.shape else residual).tolist(),
        "residual_max": float(residual.max()),
    }
    if pair["truth"] is not None:
        err = np.linalg.norm(r.verts.numpy() - pair["truth"], axis=1) / diag
        out.update(truth_max=float(err.max()), truth_p99=float(np.quantile(err, 0.99)),
                   truth_over_5pct=float((err > 0.05).mean()), truth_rmse=float(np.sqrt((err**2).mean())))  # fmt: skip
    return out


def beyond(sorted_d: list[float], t: float, weights: list[float] | None = None) -> float:
    """Fraction of the sorted distances that are > ``t`` (weighted by ``weights``, in the same order, when given)."""
    a = np.asarray(sorted_d)
    i = int(np.searchsorted(a, t, side="right"))
    if weights is None:
        return float(1.0 - i / max(a.size, 1))
    w = np.asarray(weights)
    return float(w[i:].sum() / max(w.sum(), np.finfo(np.float64).tiny))


CANDIDATES: dict[str, Callable[[dict[str, Any]], float]] = {
    "2% diag": lambda m: 0.02,
    "3% diag": lambda m: 0.03,
    "5% diag": lambda m: 0.05,
    "1x node spacing": lambda m: m["node_spacing"],
    "2x mean tgt edge": lambda m: 2 * m["target_edge_mean"],
    "2x median tgt edge": lambda m: 2 * m["target_edge_median"],
    **{f"max(2%, {k:g}x finer edge)": (lambda m, k=k: max(0.02, k * m["finer_edge"])) for k in (2, 2.5, 3, 3.5, 4)},
}
"""Candidate distances (diagonals); ``max(2%, 4x finer edge)`` is the default uncovered distance."""


def report(results: dict[str, dict[str, Any]]) -> None:
    print(f"{'pair':44s} {'label':8s} {'V':>6s} {'h_t':>7s} {'h_s':>7s} {'nodes':>6s} {'truth max':>9s} "
          f"{'conv':5s} " + " ".join(f"{c[:14]:>14s}" for c in CANDIDATES))  # fmt: skip
    for side in ("fit_target", "dense_target", "source"):
        print(f"--- fraction beyond, {side} (the fit's own 2000 target samples, 20,000 denser ones, surface vertices)")
        worst: dict[str, dict[str, tuple[float, str]]] = {"correct": {}, "failure": {}}
        for name, m in results.items():
            weights = m["fit_weights"] if side == "fit_target" else None
            fr = {c: beyond(m[side], fn(m), weights) for c, fn in CANDIDATES.items()}
            truth = f"{m['truth_max']:.3f}" if "truth_max" in m else "-"
            print(f"{name:44s} {m['label']:8s} {m['num_source_verts']:6d} {m['target_edge_mean']:7.4f} "
                  f"{m['source_edge_mean']:7.4f} {m['node_spacing']:6.3f} {truth:>9s} {m['converged']!s:5s} "
                  + " ".join(f"{100 * f:13.2f}%" for f in fr.values()))  # fmt: skip
            if m["label"] in worst:
                for c, f in fr.items():
                    cur = worst[m["label"]].get(c)
                    better = cur is None or (f > cur[0] if m["label"] == "correct" else f < cur[0])
                    if better:
                        worst[m["label"]][c] = (f, name)
        for c in CANDIDATES:
            if c in worst["correct"] and c in worst["failure"]:
                (fc, nc), (ff, nf) = worst["correct"][c], worst["failure"][c]
                ratio = ff / fc if fc > 0 else math.inf
                print(
                    f"  {c:30s} correct max {100 * fc:6.2f}% ({nc}); failure min {100 * ff:6.2f}% ({nf}); "
                    f"ratio {ratio:.2f}"
                )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", type=Path, default=None, help="folder of CraGL models/<name>/ folders")
    parser.add_argument("--only", nargs="*", default=None, help="groups to run (default: all)")
    parser.add_argument("--out", type=Path, default=Path("/tmp/coverage.json"), help="JSON written (and extended)")
    parser.add_argument("--report", action="store_true", help="only print the report of --out")
    args = parser.parse_args()
    results: dict[str, dict[str, Any]] = json.loads(args.out.read_text()) if args.out.exists() else {}
    if not args.report:
        torch.set_num_threads(1)
        for group, name, make in pairs(args.models, set(args.only) if args.only else None):
            if name in results:
                continue
            m = measure(make())
            m["group"] = group
            results[name] = m
            args.out.write_text(json.dumps(results))
            print(f"{name}: {m['seconds']:.1f} s, converged {m['converged']} {m['reason'][:60]}", flush=True)
    # Labelled by what happened: a registered vertex > 0.1 of the diagonal from its true place, and > 3 mean target
    # edges (on the demo at resolution 16, an edge is 0.055 of the diagonal and the "truth", the analytic motion of a
    # marching-cubes vertex, lies up to 0.12 off the next frame's coarse surface: not a failure of the registration).
    for m in results.values():
        if "truth_max" in m:
            m["label"] = "failure" if m["truth_max"] > max(0.1, 3 * m["target_edge_mean"]) else "correct"
    report(results)


if __name__ == "__main__":
    main()
