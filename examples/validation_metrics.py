"""A validation loop that accumulates the paper's metrics over batches and logs them (Lightning not required).

Run: PYTHONPATH=. python examples/validation_metrics.py

In a LightningModule the same collection is used as ``self.val_metrics.update(simplified, reference)`` in
``validation_step`` and ``self.log_dict(self.val_metrics.compute())`` then ``self.val_metrics.reset()`` in
``on_validation_epoch_end``: every value is a 0-dim float tensor, and DDP synchronisation is exact.
"""

import numpy as np
import torch
import trimesh
from torchmetrics import MetricCollection

from torchmeshmetric.metrics import MeshSurfaceDistance, NearestVertexDistance


def validation_batches(num_batches: int = 3, batch_size: int = 2):
    """Pairs (simplified, reference): a coarse noisy sphere against a finer one, in ragged batches."""
    rng = np.random.default_rng(0)
    for b in range(num_batches):
        simplified, reference = [], []
        for i in range(batch_size):
            radius = 1.0 + 0.05 * (b * batch_size + i)
            ref = trimesh.creation.icosphere(subdivisions=3, radius=radius)
            simp = trimesh.creation.icosphere(subdivisions=1 + i % 2, radius=radius)
            v = simp.vertices + rng.normal(0, 0.01, simp.vertices.shape)
            simplified.append((torch.tensor(v, dtype=torch.float32), torch.tensor(simp.faces)))
            reference.append(ref)
        yield simplified, reference


def main() -> None:
    metrics = MetricCollection(
        {"surface": MeshSurfaceDistance(two_sided=True), "vertex": NearestVertexDistance()}, prefix="val/"
    )
    for epoch in range(2):
        for simplified, reference in validation_batches():
            metrics.update(simplified, reference)
        logged = {k: v.item() for k, v in metrics.compute().items()}  # what log_dict would receive
        metrics.reset()
        keys = ["val/surface_ave", "val/surface_rmse", "val/surface_hausdorff", "val/vertex_ave", "val/vertex_psnr"]
        print(f"epoch {epoch}: " + ", ".join(f"{k}={logged[k]:.5f}" for k in keys))


if __name__ == "__main__":
    main()
