"""Train a (toy) learned simplifier with Lightning and log the paper's metrics every validation epoch.

Needs: lightning (`pip install -e '.[examples]'`, or `pip install lightning`).
Run: PYTHONPATH=. python examples/lightning_validation.py   (~15 s on 2 CPU cores)

The pattern (docs/lightning.md):

- keep the metrics as attributes and their scalar *views* next to them (``metric.statistics(...)`` is a
  ``MetricCollection`` of views, ``metric.statistic("rmse")`` a single one): Lightning can log only metrics whose
  ``compute()`` is one tensor, and the views share the metric's single accumulation;
- ``validation_step``: ``metric.update(simplified, reference)`` then ``self.log_dict(views)``; Lightning computes the
  views at the end of the epoch (exact pooled statistics over every batch and, under DDP, every process, float64)
  and resets the metric.

Multi-GPU: nothing changes (``Trainer(devices=N, strategy="ddp")``); the metric states are gathered exactly, so do
not pass ``sync_dist=True`` for the views.
"""

import csv
import tempfile

import numpy as np
import torch
import trimesh
from lightning.pytorch import LightningModule, Trainer
from lightning.pytorch.loggers import CSVLogger
from torch import nn

from torchmeshmetric.metrics import MeshSurfaceDistance, MeshSurfaceDistanceLoss, NearestVertexDistance


def pairs(n: int = 6, seed: int = 0):
    """(simplified, reference) pairs: coarse, noisy, shifted spheres against finer ones (ragged sizes)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        radius = 1.0 + 0.1 * i
        reference = trimesh.creation.icosphere(subdivisions=2, radius=radius)
        coarse = trimesh.creation.icosphere(subdivisions=1 + i % 2, radius=radius)
        v = coarse.vertices + rng.normal(0, 0.01, coarse.vertices.shape) + [0.05, -0.03, 0.0]
        out.append(((torch.tensor(v, dtype=torch.float32), torch.tensor(coarse.faces)), reference))
    return out


def loader(items, batch_size: int = 4):
    # Meshes are ragged: a batch is (list of simplified meshes, list of references).
    return torch.utils.data.DataLoader(
        items, batch_size=batch_size, collate_fn=lambda b: ([x[0] for x in b], [x[1] for x in b])
    )


class ToySimplifier(nn.Module):
    """Stands in for a learned simplifier: a learned translation of the coarse vertices."""

    def __init__(self) -> None:
        super().__init__()
        self.shift = nn.Parameter(torch.zeros(3))

    def forward(self, meshes):
        return [(v + self.shift, f) for v, f in meshes]


class SimplifierModule(LightningModule):
    def __init__(self) -> None:
        super().__init__()
        self.net = ToySimplifier()
        self.loss = MeshSurfaceDistanceLoss(power=2, two_sided=True)  # differentiable: MSE both ways
        # Metrics accumulate; their views are what Lightning logs.
        self.surface = MeshSurfaceDistance(two_sided=True)
        self.vertex = NearestVertexDistance()
        self.surface_logged = self.surface.statistics(["ave", "rmse", "hausdorff", "psnr"], prefix="val/surface_")
        self.vertex_rmse = self.vertex.statistic("rmse")

    def training_step(self, batch, batch_idx):
        simplified, reference = batch
        loss = self.loss(self.net(simplified), reference)
        self.log("train/loss", loss, batch_size=len(simplified))
        return loss

    def validation_step(self, batch, batch_idx):
        simplified, reference = batch
        out = self.net(simplified)
        self.surface.update(out, reference)
        self.vertex.update(out, reference)
        self.log_dict(self.surface_logged, batch_size=len(simplified))
        self.log("val/vertex_rmse", self.vertex_rmse, batch_size=len(simplified), prog_bar=True)

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.2)


def main() -> None:
    data = pairs()
    with tempfile.TemporaryDirectory() as tmp:
        trainer = Trainer(
            accelerator="cpu",
            max_epochs=4,
            log_every_n_steps=1,
            logger=CSVLogger(tmp),
            enable_checkpointing=False,
            enable_progress_bar=False,
            enable_model_summary=False,
        )
        module = SimplifierModule()
        trainer.fit(module, loader(data), loader(data))
        with open(f"{trainer.logger.log_dir}/metrics.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    for r in rows:  # one row per logging step; the validation values sit in the epoch-end rows
        if r["val/surface_ave"]:
            print(
                ", ".join(
                    f"{k}={r[k]}" for k in ("epoch", "val/surface_ave", "val/surface_hausdorff", "val/vertex_rmse")
                )
            )
    shift = [round(x, 4) for x in module.net.shift.tolist()]
    print("learned shift:", shift, "(the coarse meshes were shifted by +0.05, -0.03, 0)")


if __name__ == "__main__":
    main()
