"""Log a validation mesh coloured by its error at every validation epoch (TensorBoard, W&B, or files).

Run: PYTHONPATH=. python examples/log_error_meshes.py [LOG_DIR]   (needs lightning and tensorboard; ~10 s on 2 cores)
then ``tensorboard --logdir LOG_DIR`` and open the MESH tab: the simplified sphere, coloured by the distance of each
vertex to the reference surface, one mesh per epoch on one colour scale (``vmax``), the scale in the mesh's config.

A toy model learns per-vertex offsets that move a coarse, shifted sphere onto a finer one (the surface distance as
the loss). ``ErrorMeshCallback(pair)`` calls ``pair(trainer, module)`` at the end of every validation epoch and logs
the error mesh to every logger of the trainer: TensorBoard ``add_mesh`` here, a GLB file for the CSV logger
(``meshes/val_error_mesh-830a3d9e_step*.glb`` in its folder), ``wandb.Object3D`` (GLB) with ``WandbLogger``.
``log_error_mesh(logger, tag, mesh, reference=...)`` does the same from any training loop.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import torch
import trimesh
from lightning.pytorch import LightningModule, Trainer
from lightning.pytorch.loggers import CSVLogger, TensorBoardLogger

from torchmeshmetric.metrics import MeshSurfaceDistanceLoss
from torchmeshmetric.viz.error_mesh_callback import ErrorMeshCallback


class Offsets(LightningModule):
    """A coarse sphere's vertices plus learned offsets, trained onto the reference surface."""

    def __init__(self, coarse: trimesh.Trimesh, reference: trimesh.Trimesh) -> None:
        super().__init__()
        self.register_buffer("verts", torch.tensor(coarse.vertices + np.array([0.08, 0.0, 0.0]), dtype=torch.float32))
        self.register_buffer("faces", torch.tensor(coarse.faces))
        self.offsets = torch.nn.Parameter(torch.zeros_like(self.verts))
        # in the model's dtype (float32): the loss computes in the promoted dtype of its two meshes (docs/concepts.md,
        # "Precision: one dtype rule"), so a float64 reference would make every step float64
        self.reference = (torch.tensor(reference.vertices, dtype=torch.float32), torch.tensor(reference.faces))
        self.loss = MeshSurfaceDistanceLoss(power=2, two_sided=True)

    def simplified(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self.verts + self.offsets, self.faces

    def training_step(self, batch: object, batch_idx: int) -> torch.Tensor:
        return self.loss(self.simplified(), self.reference)

    def validation_step(self, batch: object, batch_idx: int) -> None:
        with torch.no_grad():
            self.log("val/loss", self.loss(self.simplified(), self.reference))

    def configure_optimizers(self) -> torch.optim.Optimizer:
        return torch.optim.Adam(self.parameters(), lr=1e-2)


def main(log_dir: str, epochs: int = 3) -> Path:
    """Train for ``epochs`` epochs, logging the error mesh after each; returns the TensorBoard folder."""
    reference = trimesh.creation.icosphere(subdivisions=3)
    module = Offsets(trimesh.creation.icosphere(subdivisions=2), reference)
    steps = torch.utils.data.DataLoader(torch.utils.data.TensorDataset(torch.zeros(10, 1)), batch_size=1)
    tensorboard = TensorBoardLogger(log_dir, name="tb")
    callback = ErrorMeshCallback(
        lambda trainer, m: ((m.simplified()[0].detach(), m.simplified()[1]), reference),
        vmax=0.08,  # the starting shift: one scale for every epoch, so that colours compare
    )
    trainer = Trainer(
        max_epochs=epochs,
        logger=[tensorboard, CSVLogger(log_dir, name="csv")],
        callbacks=[callback],
        accelerator="cpu",
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        log_every_n_steps=5,
    )
    trainer.fit(module, steps, steps)
    return Path(tensorboard.log_dir)


if __name__ == "__main__":
    folder = main(sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="error-meshes-"))
    print(f"logged; run: tensorboard --logdir {folder.parent}")
