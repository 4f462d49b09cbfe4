"""Validation of the registered temporal metrics against the exact ones on real fixed-connectivity animations.

Run (once; minutes): ``python -m tests.benchmarks.temporal_validation MODEL_DIR [MODEL_DIR ...] --frames 4
--out /tmp/temporal-validation.json``, each MODEL_DIR a folder of OBJ frames with one connectivity (e.g.
``models/horse-gallop`` and ``models/samba`` of CraGL/Hyperspectral-Inverse-Skinning: use them from a scratch
folder, never commit them). For each animation ``A``:

* every original frame is **remeshed independently** (each edge split at a random point along it, then QEM back to
  the frame's face count: the same surface, a connectivity of its own in every frame);
* each **distortion** at four levels gives a fixed-connectivity ``Â`` (the exact figures ``metric(A, Â)``), remeshed
  the same way frame by frame (another seed) for the registered figures ``registered(remeshed A, remeshed Â)``:
  quantisation (10 to 7 bits of the bounding box), Laplacian smoothing (1 to 8 steps), per-frame noise along the
  normals, a smooth static bump along the normals, per-frame jitter (isotropic, tangential included), flicker (a
  smooth offset along the normals whose sign alternates every frame), and simplification (QEM to 50 % to 5 % of the
  faces: the simplified frames are the distorted sequence itself, and the exact reference is ``A``'s vertices on the
  simplified surface along ``A``'s normals);
* ``none`` (the remeshing alone) is the registered form's floor.

Printed and written: every figure exact and registered, Spearman's rank correlation over all distortions and
levels (per figure and animation), the spread of registered / exact across the levels of each kind, the normal
displacements' ratios, and flicker/jitter's rise of STED_t. docs/temporal.md holds the figures.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import fast_simplification
import numpy as np
import torch

from torchmeshmetric.data.sequence import load_sequence
from torchmeshmetric.structures import Mesh
from torchmeshmetric.temporal import carry_onto, kg_error, kso_error, sted, track_original
from torchmeshmetric.temporal.figures import FIGURE_NAMES
from torchmeshmetric.temporal.topology import mesh_edges

LEVELS = {
    "quantisation": [10, 9, 8, 7],
    "smoothing": [1, 2, 4, 8],
    "noise": [0.001, 0.002, 0.004, 0.008],
    "bump": [0.002, 0.004, 0.008, 0.016],
    "jitter": [0.001, 0.002, 0.004, 0.008],
    "flicker": [0.001, 0.002, 0.004, 0.008],
    "slide": [0.001, 0.002, 0.004, 0.008],
    "simplification": [0.5, 0.25, 0.1, 0.05],
}
NORMAL_KINDS = ("noise", "bump", "flicker")
#: Distortions with a tangential part, which no surface shows (the registered forms cannot see it by design).
TANGENTIAL_KINDS = ("jitter", "slide")


def _normals(verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    return Mesh(verts, faces, validate=False).vertex_normals()


def remesh(verts: torch.Tensor, faces: torch.Tensor, rng: np.random.Generator) -> Mesh:
    """The same surface, another connectivity: split every edge at a random point, then QEM to the face count."""
    v, f = verts.numpy(), faces.numpy()
    edges = mesh_edges(faces, v.shape[0]).numpy()
    t = rng.uniform(0.3, 0.7, size=(edges.shape[0], 1))
    new = (1 - t) * v[edges[:, 0]] + t * v[edges[:, 1]]
    key = {(int(a), int(b)): i + v.shape[0] for i, (a, b) in enumerate(edges)}

    def mid(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.array([key[(min(x, y), max(x, y))] for x, y in zip(a.tolist(), b.tolist(), strict=True)])

    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
    split = np.concatenate([np.stack(s, 1) for s in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    pts, tri = fast_simplification.simplify(np.concatenate([v, new]), split, target_count=f.shape[0])
    return Mesh(torch.from_numpy(np.asarray(pts, dtype=np.float64)), torch.from_numpy(np.asarray(tri, dtype=np.int64)))


def remesh_exact(verts: torch.Tensor, faces: torch.Tensor, rng: np.random.Generator) -> Mesh:
    """The same point set, another connectivity: a random half of the faces split 1-to-3 at a random interior point.

    No vertex moves and no QEM runs, so every point of the remeshed surface is a point of the input surface (and
    back): what the registered forms see of a distortion is the distortion, not the remesher's filtering.
    """
    v, f = verts.numpy(), faces.numpy()
    split = rng.random(f.shape[0]) < 0.5
    w = rng.uniform(0.2, 0.6, size=(int(split.sum()), 3))
    w /= w.sum(axis=1, keepdims=True)
    inner = np.einsum("tk,tkd->td", w, v[f[split]])
    idx = v.shape[0] + np.arange(inner.shape[0])
    a, b, c = f[split, 0], f[split, 1], f[split, 2]
    tri = np.concatenate([f[~split], np.stack([a, b, idx], 1), np.stack([b, c, idx], 1), np.stack([c, a, idx], 1)])
    return Mesh(torch.from_numpy(np.concatenate([v, inner])), torch.from_numpy(tri.astype(np.int64)))


def distort(kind: str, level: float, a: torch.Tensor, faces: torch.Tensor, diag: float, seed: int) -> torch.Tensor:
    """The fixed-connectivity distortion ``Â`` of ``A`` (F, V, 3)."""
    g = torch.Generator().manual_seed(seed)
    n = torch.stack([_normals(v, faces) for v in a])
    if kind == "quantisation":
        step = diag * 2.0 ** -int(level)
        lo = a.amin(dim=(0, 1))
        return torch.round((a - lo) / step) * step + lo
    if kind == "smoothing":
        edges = mesh_edges(faces, a.shape[1])
        out = a.clone()
        deg = torch.bincount(edges.flatten(), minlength=a.shape[1]).to(a.dtype)[:, None]
        for _ in range(int(level)):
            acc = torch.zeros_like(out)
            acc.index_add_(1, edges[:, 0], out[:, edges[:, 1]])
            acc.index_add_(1, edges[:, 1], out[:, edges[:, 0]])
            out = out + 0.5 * (acc / deg - out)
        return out
    if kind == "noise":  # a new pattern along the normals every frame (a codec's residual)
        return a + level * diag * torch.randn((*a.shape[:2], 1), generator=g, dtype=a.dtype) * n
    if kind in ("bump", "flicker"):  # a smooth field of the rest shape along the normals
        x0 = a[0] / diag
        field = torch.sin(9.0 * x0[:, :1] + 1.0) * torch.sin(7.0 * x0[:, 1:2] + 2.0) * torch.sin(8.0 * x0[:, 2:] + 3.0)
        sign = torch.ones(a.shape[0], 1, 1, dtype=a.dtype)
        if kind == "flicker":
            sign = (torch.arange(a.shape[0]) % 2 * 2 - 1).to(a.dtype)[:, None, None]
        return a + level * diag * sign * field[None] * n
    if kind == "slide":  # jitter's tangential part alone: the surface is unchanged up to second order
        d = level * diag * torch.randn(a.shape, generator=g, dtype=a.dtype)
        return a + d - (d * n).sum(-1, keepdim=True) * n
    if kind == "jitter":  # isotropic per-vertex per-frame offsets: tangential motion included
        return a + level * diag * torch.randn(a.shape, generator=g, dtype=a.dtype)
    raise ValueError(kind)


def figures(a: torch.Tensor, b: torch.Tensor, faces: torch.Tensor) -> dict[str, float]:
    s = sted(a, b, faces)
    return {
        "kg": kg_error(a, b).item(),
        "kso": kso_error(a, b).item(),
        "sted_s": s.spatial.item(),
        "sted_t": s.temporal.item(),
        "sted": s.sted.item(),
    }


def spearman(x: list[float], y: list[float]) -> float:
    rx, ry = np.argsort(np.argsort(x)).astype(float), np.argsort(np.argsort(y)).astype(float)
    return float(np.corrcoef(rx, ry)[0, 1])


def validate(
    folder: Path,
    num_frames: int,
    log: Callable[[str], None],
    remesher: str = "exact",
    keep_first: bool = False,
    true_correspondence: bool = False,
) -> dict[str, object]:
    frames = load_sequence(folder, dtype=torch.float64)[:num_frames]
    faces = frames[0].faces
    a = torch.stack([m.verts for m in frames])
    diag = float(frames[0].bbox_diagonal())
    rng = np.random.default_rng(0)
    remesh_fn = remesh_exact if remesher == "exact" else remesh
    remeshed = [remesh_fn(v, faces, rng) for v in a]
    if keep_first:  # the tracked set is A's own frame 0 (its vertices and edges), as when the original is captured
        remeshed[0] = Mesh(a[0], faces)
    t0 = time.perf_counter()
    registrations = None
    if true_correspondence:  # the ceiling of any tracking: each remeshed point at its barycentric place on A
        from tests.temporal.test_exact_remesh import _true_registrations  # (that module imports this one)

        registrations = _true_registrations(a, faces, remeshed)
    tracking = track_original(remeshed, registrations=registrations)
    seconds = time.perf_counter() - t0
    log(f"{folder.name}: {a.shape[1]} vertices, {a.shape[0]} frames; registrations + tracking {seconds:.1f} s")
    rows = []
    cases = [("none", 0.0)] + [(kind, level) for kind, levels in LEVELS.items() for level in levels]
    for i, (kind, level) in enumerate(cases):
        if kind == "simplification":
            simplified = [
                Mesh(
                    *(
                        torch.from_numpy(np.asarray(x))
                        for x in fast_simplification.simplify(v.numpy(), faces.numpy(), 1 - level)
                    )
                )
                for v in a
            ]
            simplified = [Mesh(m.verts.double(), m.faces.long()) for m in simplified]
            b = torch.stack(
                [carry_onto([m], v[None], faces)[0] for m, v in zip(simplified, a, strict=True)]
            )  # A's vertices on the simplified surface along A's normals
            distorted = simplified
        else:
            b = a.clone() if kind == "none" else distort(kind, level, a, faces, diag, seed=100 + i)
            distorted = [remesh_fn(v, faces, rng) for v in b]
        exact = figures(a, b, faces)
        carried = carry_onto(distorted, tracking.verts, tracking.faces)
        registered = figures(tracking.verts, carried, tracking.faces)
        rows.append({"kind": kind, "level": level, "exact": exact, "registered": registered})
        log(f"  {kind:>14} {level:<6} " + " ".join(f"{k}={exact[k]:.4g}/{registered[k]:.4g}" for k in FIGURE_NAMES))
    return {
        "model": folder.name,
        "vertices": int(a.shape[1]),
        "frames": int(a.shape[0]),
        "remesh": remesher,
        "keep_first": keep_first,
        "true_correspondence": true_correspondence,
        "rows": rows,
    }


def summary(result: dict[str, object]) -> dict[str, object]:
    rows = [r for r in result["rows"] if r["kind"] != "none"]  # type: ignore[union-attr]
    out: dict[str, object] = {}
    out["spearman"] = {
        k: spearman([r["exact"][k] for r in rows], [r["registered"][k] for r in rows]) for k in FIGURE_NAMES
    }
    spread = {}
    for kind in LEVELS:
        mine = [r for r in rows if r["kind"] == kind]
        spread[kind] = {}
        for k in FIGURE_NAMES:
            ratios = [r["registered"][k] / r["exact"][k] for r in mine if r["exact"][k] > 0]
            spread[kind][k] = {"min": min(ratios), "max": max(ratios), "spread": max(ratios) / min(ratios) - 1}
    out["ratio"] = spread
    visible = [r for r in rows if r["kind"] not in TANGENTIAL_KINDS]
    out["spearman_visible"] = {
        k: spearman([r["exact"][k] for r in visible], [r["registered"][k] for r in visible]) for k in FIGURE_NAMES
    }
    return out


def markdown(results: list[dict[str, object]]) -> str:
    """The validation's tables (docs/temporal.md): figures, Spearman, ratio spreads, temporal rises."""
    short = ("kg", "kso", "sted_s", "sted_t")
    lines = []
    for result in results:
        rows = result["rows"]  # type: ignore[index]
        lines += [
            f"**{result['model']}** ({result['vertices']} vertices, {result['frames']} frames): exact / registered",
            "",
            "| distortion | level | " + " | ".join(short) + " |",
            "|---|---:|" + "---:|" * len(short),
        ]
        for r in rows:  # type: ignore[union-attr]
            cells = " | ".join(f"{r['exact'][k]:.4g} / {r['registered'][k]:.4g}" for k in short)
            lines.append(f"| {r['kind']} | {r['level']:g} | {cells} |")
        summ = result["summary"]  # type: ignore[index]
        lines += ["", "| | " + " | ".join(FIGURE_NAMES) + " |", "|---|" + "---:|" * len(FIGURE_NAMES)]
        lines.append("| Spearman | " + " | ".join(f"{summ['spearman'][k]:.3f}" for k in FIGURE_NAMES) + " |")
        lines.append(
            "| Spearman without jitter/slide | "
            + " | ".join(f"{summ['spearman_visible'][k]:.3f}" for k in FIGURE_NAMES)
            + " |"
        )
        for kind, per in summ["ratio"].items():
            cells = " | ".join(
                f"{per[k]['min']:.2f} to {per[k]['max']:.2f} ({100 * per[k]['spread']:.0f} %)" for k in FIGURE_NAMES
            )
            lines.append(f"| ratio {kind} | {cells} |")
        floor = next(r for r in rows if r["kind"] == "none")["registered"]["sted_t"]  # type: ignore[union-attr]
        lines += ["", "| STED_t rise over the floor | level | exact | registered - floor | registered / exact |"]
        lines.append("|---|---:|---:|---:|---:|")
        for r in rows:  # type: ignore[union-attr]
            if r["kind"] in ("flicker", "jitter", "noise", "slide"):
                rise = r["registered"]["sted_t"] - floor
                lines.append(
                    f"| {r['kind']} | {r['level']:g} | {r['exact']['sted_t']:.4g} | {rise:.4g} | "
                    f"{rise / r['exact']['sted_t']:.2f} |"
                )
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+", type=Path)
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument(
        "--remesh", choices=("exact", "qem"), default="exact", help="exact: 1-to-3 splits (default); qem: issue 44's"
    )
    parser.add_argument(
        "--keep-first", action="store_true", help="original frame 0 not remeshed: the tracked set is A's own frame 0"
    )
    parser.add_argument(
        "--true-correspondence",
        action="store_true",
        help="track by the true correspondence instead of the registration (--remesh exact): any tracking's ceiling",
    )
    parser.add_argument("--out", type=Path, default=Path("/tmp/temporal-validation.json"))
    parser.add_argument("--markdown", action="store_true", help="print the tables of --out (written before) and stop")
    args = parser.parse_args()
    if args.markdown:
        print(markdown(json.loads(args.out.read_text())))
        return
    results = []
    for folder in args.models:
        if args.true_correspondence and args.remesh != "exact":
            parser.error("--true-correspondence needs --remesh exact (the remeshed points on A's surface)")
        log = lambda s: print(s, flush=True)  # noqa: E731
        result = validate(folder, args.frames, log, args.remesh, args.keep_first, args.true_correspondence)
        result["summary"] = summary(result)
        print(json.dumps(result["summary"], indent=1), flush=True)
        results.append(result)
        args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
