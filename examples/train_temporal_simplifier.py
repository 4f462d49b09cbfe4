"""Train a small learned simplifier with the temporal-consistency loss, validate it on held-out frames (Lightning).

Run: PYTHONPATH=. python examples/train_temporal_simplifier.py [--quick]   (a few minutes on 2 CPU cores)

What it does (docs/training.md explains the choices and shows the results):

1. The built-in demo sequence; its first frames train, the following frames are held out (a later part of the
   motion). Every original pair is registered once (``register_pairs``); the registrations serve the loss, the
   Registered QEM baseline, the validation metric and the final evaluation alike.
2. The model: QEM simplifies each frame to a face count; a per-vertex MLP, shared by all frames, reads local features
   of the QEM mesh (its curvature, and where the original surface lies relative to the simplified faces around the
   vertex) and moves the vertex along its normal by at most half its mean edge length. Same faces as QEM: equal face
   counts by construction.
3. Loss, per training pair ``(k-1, k)``: frame-``k`` term + λ · temporal term, the two-sided surface distances of
   :class:`~torchmeshmetric.metrics.TemporalConsistencyLoss` (λ > 0: ``λ * TemporalConsistencyLoss(frame_weight=1/λ)``;
   λ = 0: the frame term alone, ``MeshSurfaceDistanceLoss``). Gradients reach both frames of the pair.
4. Validation every few epochs on the held-out pairs with ``TemporalConsistency(flicker=True)``, logged through
   Lightning; at the end ``evaluate_sequence`` + ``compare_methods`` on the held-out frames: QEM, Registered QEM and
   the model for each λ, with the paired 95 % intervals over frame pairs.
"""

from __future__ import annotations

import argparse
import csv
import json
import tempfile
import time
from dataclasses import dataclass
from typing import Any

import torch
from lightning.pytorch import LightningModule, Trainer
from lightning.pytorch.loggers import CSVLogger
from torch import Tensor, nn

from torchmeshmetric import Mesh
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.evaluation import TemporalConsistency, compare_methods, evaluate_sequence, register_pairs
from torchmeshmetric.evaluation.results import flatten_statistics
from torchmeshmetric.kernels import point_mesh_distance
from torchmeshmetric.metrics import MeshSurfaceDistanceLoss, TemporalConsistencyLoss
from torchmeshmetric.simplification import simplify_qem, simplify_sequence


@dataclass
class Setup:
    """The experiment's sizes (``quick()``: the test's few-second version)."""

    num_train: int = 8  # training frames (7 training pairs)
    num_held_out: int = 8  # held-out frames (7 held-out pairs)
    resolution: int = 64  # demo marching-cubes resolution (~6k faces per frame)
    faces: int = 1000  # faces per simplified frame
    steps: int = 150  # Adam steps (one step per epoch: the whole training set is one batch)
    lr: float = 1e-2
    validate_every: int = 50
    seed: int = 0

    @classmethod
    def quick(cls) -> Setup:
        return cls(num_train=3, num_held_out=3, resolution=32, faces=200, steps=6, validate_every=3)


# --- data -----------------------------------------------------------------------------------------------------------


@dataclass
class Frame:
    """One frame ready for the model: the original, its QEM simplification and the QEM vertices' features."""

    original: Mesh
    qem: Mesh
    normals: Tensor  # (V, 3) unit vertex normals of the QEM mesh
    scale: Tensor  # (V,) mean incident edge length (the offsets' unit)
    features: Tensor  # (V, F)


def vertex_normals_and_scale(mesh: Mesh) -> tuple[Tensor, Tensor]:
    """Area-weighted vertex normals and mean incident edge length of each vertex."""
    v, f = mesh.verts, mesh.faces
    fn = torch.linalg.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # |fn| = 2 * area
    normals = torch.zeros_like(v).index_add_(0, f.reshape(-1), fn.repeat_interleave(3, 0))
    normals = normals / normals.norm(dim=1, keepdim=True).clamp_min(torch.finfo(v.dtype).tiny)
    edges = torch.cat([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    length = (v[edges[:, 0]] - v[edges[:, 1]]).norm(dim=1)
    total = torch.zeros(v.shape[0], dtype=v.dtype).index_add_(0, edges.reshape(-1), length.repeat(2))
    count = torch.zeros(v.shape[0], dtype=v.dtype).index_add_(0, edges.reshape(-1), torch.ones_like(length).repeat(2))
    return normals, total / count.clamp_min(1)


def local_features(original: Mesh, qem: Mesh) -> tuple[Tensor, Tensor, Tensor]:
    """``(normals, scale, features)`` of the QEM vertices; every feature is a length divided by the local scale.

    * the umbrella curvature: (mean of the neighbours - vertex) . normal / scale;
    * where the original surface lies relative to the simplified faces around the vertex: each original vertex's
      signed offset from its closest simplified face (along that face's normal), averaged onto the face's corners
      with its barycentric weights;
    * its spread (the mean squared offset), which says whether the region is flat or folded at this scale.
    """
    v, f = qem.verts, qem.faces
    normals, scale = vertex_normals_and_scale(qem)
    n = v.shape[0]
    edges = torch.cat([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    ends = torch.cat([edges, edges.flip(1)])
    nb_sum = torch.zeros_like(v).index_add_(0, ends[:, 0], v[ends[:, 1]])
    nb_cnt = torch.zeros(n, dtype=v.dtype).index_add_(0, ends[:, 0], torch.ones(ends.shape[0], dtype=v.dtype))
    umbrella = ((nb_sum / nb_cnt.clamp_min(1)[:, None] - v) * normals).sum(1) / scale
    hit = point_mesh_distance(original.verts.to(v.dtype), qem)
    fn = torch.linalg.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn = fn / fn.norm(dim=1, keepdim=True).clamp_min(torch.finfo(v.dtype).tiny)
    signed = ((original.verts.to(v.dtype) - hit.closest) * fn[hit.face_idx]).sum(1)
    corners, weights = f[hit.face_idx].reshape(-1), hit.bary.reshape(-1)
    wsum = torch.zeros(n, dtype=v.dtype).index_add_(0, corners, weights)
    mean = torch.zeros(n, dtype=v.dtype).index_add_(0, corners, weights * signed.repeat_interleave(3))
    sq = torch.zeros(n, dtype=v.dtype).index_add_(0, corners, weights * (signed**2).repeat_interleave(3))
    mean, sq = mean / wsum.clamp_min(1e-12), sq / wsum.clamp_min(1e-12)
    features = torch.stack([umbrella, mean / scale, sq.sqrt() / scale], dim=1)
    return normals, scale, features


def make_frames(setup: Setup) -> tuple[list[Mesh], list[Frame]]:
    seq = demo_sequence(setup.num_train + setup.num_held_out, resolution=setup.resolution, seed=setup.seed)
    frames = []
    for original in seq.frames:
        qem = simplify_qem(original, setup.faces)
        normals, scale, features = local_features(original, qem)
        frames.append(Frame(original, qem, normals, scale, features))
    return seq.frames, frames


# --- model ----------------------------------------------------------------------------------------------------------


class OffsetMLP(nn.Module):
    """Per-vertex MLP on local features, shared by all frames: an offset along the normal, |offset| < scale / 2."""

    def __init__(self, num_features: int = 3, hidden: int = 32) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(num_features, hidden), nn.SiLU(), nn.Linear(hidden, hidden), nn.SiLU(), nn.Linear(hidden, 1)
        )
        nn.init.zeros_(self.net[-1].weight)  # starts as QEM exactly
        nn.init.zeros_(self.net[-1].bias)

    def forward(self, frame: Frame) -> tuple[Tensor, Tensor]:
        """The simplified frame ``(verts, faces)``: QEM's vertices moved along their normals, QEM's faces."""
        dtype = self.net[0].weight.dtype
        offset = 0.5 * torch.tanh(self.net(frame.features.to(dtype))[:, 0]) * frame.scale.to(dtype)
        return frame.qem.verts.to(dtype) + offset[:, None] * frame.normals.to(dtype), frame.qem.faces


# --- training (Lightning) -------------------------------------------------------------------------------------------


class TemporalSimplifier(LightningModule):
    """Trains :class:`OffsetMLP` with frame-``k`` term + λ · temporal term; validates with the flicker set."""

    def __init__(
        self, train: list[Frame], train_regs: list[Any], held: list[Frame], held_regs: list[Any], lam: float, lr: float
    ) -> None:
        super().__init__()
        self.model = OffsetMLP()
        self.train_frames, self.train_regs = train, train_regs
        self.held_frames, self.held_regs = held, held_regs
        self.lam, self.lr = lam, lr
        # λ > 0: λ * (flicker + frame / λ) = frame + λ * flicker, both two-sided. The module registers nothing here
        # (registrations are passed), keeps the original frames' indexes and refits the simplified ones each step.
        self.temporal = TemporalConsistencyLoss(frame_weight=1.0 / lam) if lam > 0 else None
        self.frame_only = MeshSurfaceDistanceLoss(two_sided=True)
        self.val_metric = TemporalConsistency(flicker=True)
        self.history: list[float] = []

    def loss(self) -> Tensor:
        out = [self.model(fr) for fr in self.train_frames]
        originals = [fr.original for fr in self.train_frames]
        if self.temporal is None:
            return self.frame_only(out[1:], originals[1:])
        return self.lam * self.temporal(out[1:], out[:-1], originals[1:], originals[:-1], self.train_regs)

    def training_step(self, batch: Any, batch_idx: int) -> Tensor:
        loss = self.loss()
        self.history.append(float(loss.detach()))
        self.log("train/loss", loss, batch_size=1)
        return loss

    def validation_step(self, batch: Any, batch_idx: int) -> None:
        out = [self.model(fr) for fr in self.held_frames]
        for k in range(1, len(self.held_frames)):
            fr, prev = self.held_frames[k], self.held_frames[k - 1]
            self.val_metric.update(
                out[k], fr.original, prev.original, out[k - 1], precomputed_registration=self.held_regs[k - 1]
            )

    def on_validation_epoch_end(self) -> None:
        stats = flatten_statistics(self.val_metric.compute())
        self.val_metric.reset()
        keys = ("flicker/ave", "surface_k/ave", "reverse/flicker/ave", "reverse/surface_k/ave")
        self.log_dict({f"val/{k}": stats[k] for k in keys}, batch_size=1)

    def configure_optimizers(self) -> torch.optim.Optimizer:
        return torch.optim.Adam(self.model.parameters(), lr=self.lr)


def _one_batch() -> torch.utils.data.DataLoader:
    # Every epoch is one step on the whole training set (the frames live in the module; the batch is a token).
    return torch.utils.data.DataLoader([0], batch_size=1)


def train(
    setup: Setup, frames: list[Frame], regs: list[Any], lam: float, log_dir: str
) -> tuple[TemporalSimplifier, list[dict[str, str]]]:
    """Train one model for ``lam``; returns it and the rows Lightning logged (CSV)."""
    torch.manual_seed(setup.seed)
    t = setup.num_train
    module = TemporalSimplifier(frames[:t], regs[: t - 1], frames[t:], regs[t:], lam, setup.lr)
    trainer = Trainer(
        accelerator="cpu",
        max_epochs=setup.steps,
        check_val_every_n_epoch=setup.validate_every,
        num_sanity_val_steps=0,
        log_every_n_steps=1,
        logger=CSVLogger(log_dir, name=f"lambda_{lam:g}"),
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
    )
    trainer.fit(module, _one_batch(), _one_batch())
    assert trainer.logger is not None and trainer.logger.log_dir is not None
    with open(f"{trainer.logger.log_dir}/metrics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return module, rows


# --- evaluation on the held-out frames ------------------------------------------------------------------------------


def held_out_report(
    setup: Setup, originals: list[Mesh], frames: list[Frame], regs: list[Any], models: dict[str, OffsetMLP]
) -> dict[str, Any]:
    """Every method on the held-out frames (``evaluate_sequence``), aggregates and paired comparisons."""
    t = setup.num_train
    held, held_regs = originals[t:], regs[t:]
    methods: dict[str, list[Any]] = {
        "QEM": [fr.qem for fr in frames[t:]],
        "Registered QEM": simplify_sequence(held, setup.faces, registrations=held_regs),
    }
    with torch.no_grad():
        for name, model in models.items():
            methods[name] = [Mesh(*model(fr)) for fr in frames[t:]]
    evaluations = {
        name: evaluate_sequence(held, simplified, precomputed_registrations=held_regs)
        for name, simplified in methods.items()
    }
    aggregates = {}
    for name, ev in evaluations.items():
        pairs = ev.as_dict()["pairs"]
        aggregates[name] = {
            "faces": [int(m.faces.shape[0]) for m in methods[name]],
            **{
                key: sum(p[s]["ave"] if r is None else p["reverse"][s]["ave"] for p in pairs) / len(pairs)
                for key, s, r in (
                    ("flicker_ave", "flicker", None),
                    ("surface_k_ave", "surface_k", None),
                    ("reverse_flicker_ave", "flicker", "reverse"),
                    ("reverse_surface_k_ave", "surface_k", "reverse"),
                )
            },
        }
    comparisons = compare_methods(evaluations, statistics=("ave",))
    return {"aggregates": aggregates, "comparisons": comparisons}


def quick_schedule() -> list[Any]:
    """A short registration schedule (the test's: registrations of tiny frames in a fraction of a second)."""
    from torchmeshmetric.registration import DEFAULT_SCHEDULE

    return [DEFAULT_SCHEDULE[0]._replace(max_steps=10)]


def run(
    setup: Setup, lambdas: tuple[float, ...], log_dir: str, registration_options: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The whole experiment; returns timings, training curves, validation logs and the held-out report."""
    t0 = time.perf_counter()
    originals, frames = make_frames(setup)
    t_data = time.perf_counter()
    # N - 1 pairs, registered once; the pair (last training frame, first held-out frame) is never used.
    regs = register_pairs(originals, registration_options=registration_options)
    t_reg = time.perf_counter()
    models, curves, val_logs, train_seconds = {}, {}, {}, {}
    for lam in lambdas:
        start = time.perf_counter()
        module, rows = train(setup, frames, regs, lam, log_dir)
        train_seconds[f"{lam:g}"] = time.perf_counter() - start
        name = f"MLP λ={lam:g}"
        models[name], curves[name] = module.model, module.history
        val_logs[name] = [
            {k: float(v) for k, v in r.items() if v and k.startswith("val/")} | {"epoch": int(r["epoch"])}
            for r in rows
            if r.get("val/flicker/ave")
        ]
    report = held_out_report(setup, originals, frames, regs, models)
    return {
        "seconds": {
            "data": t_data - t0,
            "registration": t_reg - t_data,
            "training": train_seconds,
            "total": time.perf_counter() - t0,
        },
        "curves": curves,
        "validation": val_logs,
        **report,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the few-second version (what the test runs)")
    parser.add_argument("--lambdas", type=float, nargs="+", default=[0.0, 1.0, 4.0])
    parser.add_argument("--json", help="also write the results to this JSON file")
    parser.add_argument(
        "--threads", type=int, help="torch threads (1 on a shared machine: many small ops, each a parallel region)"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    setup = Setup.quick() if args.quick else Setup()
    with tempfile.TemporaryDirectory() as tmp:
        out = run(setup, tuple(args.lambdas), tmp)
    print(f"seconds: {json.dumps(out['seconds'])}")
    print("held-out frames, mean over pairs of the per-pair Ave:")
    for name, agg in out["aggregates"].items():
        print(
            f"  {name:<16s} faces {min(agg['faces'])}-{max(agg['faces'])}  flicker {agg['flicker_ave']:.6f}  "
            f"surface_k {agg['surface_k_ave']:.6f}  reverse flicker {agg['reverse_flicker_ave']:.6f}  "
            f"reverse surface_k {agg['reverse_surface_k_ave']:.6f}"
        )
    print("paired differences A - B over held-out pairs (95 % t interval):")
    for versus, sets in out["comparisons"].items():
        for set_name in ("flicker", "surface_k", "reverse:flicker", "reverse:surface_k"):
            e = sets.get(set_name, {}).get("ave")
            if e is not None:
                lo, hi = e["ci95"]
                floor = f"  floor {e['noise_floor']:.6f}" if "noise_floor" in e else ""
                print(
                    f"  {versus:<30s} {set_name:<18s} {e['difference']:+.6f} [{lo:+.6f}, {hi:+.6f}] "
                    f"{e['verdict']}{floor}"
                )
    if args.json:
        from torchmeshmetric._atomic import atomic_write

        atomic_write(args.json, json.dumps(out, indent=1, default=str), overwrite=True)


if __name__ == "__main__":
    main()
