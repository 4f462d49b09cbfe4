"""Lightning: train with our loss, log our metrics, and check the logged epoch values against a direct computation.

What a user writes (see docs/lightning.md): update the metric in ``validation_step`` and log its scalar views,
``self.log_dict(metric.statistics(prefix=...))`` or ``self.log(name, metric.statistic("rmse"))``. Lightning then
computes each view at the end of the epoch (exact pooled statistics over all batches and processes, float64) and
resets the metric. A metric object whose ``compute()`` returns a dict cannot be logged by Lightning (checked below).
"""

from __future__ import annotations

import multiprocessing as mp

import numpy as np
import pytest
import torch
import trimesh
from torch import nn

L = pytest.importorskip("lightning")
from lightning.pytorch.loggers import Logger  # noqa: E402

from torchmeshmetric.metrics import (  # noqa: E402
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistance,
)

NUM_ITEMS = 5
BATCH = 2  # 5 items in batches of 2: the last validation batch holds one item


def _items() -> list[tuple[tuple[torch.Tensor, torch.Tensor], trimesh.Trimesh]]:
    """(simplified, reference) pairs: coarse noisy shifted spheres against finer ones of another radius."""
    out = []
    for i in range(NUM_ITEMS):
        radius = 1.0 + 0.1 * i
        ref = trimesh.creation.icosphere(subdivisions=1, radius=radius)
        simp = trimesh.creation.icosphere(subdivisions=0, radius=radius)
        rng = np.random.default_rng(i)
        v = simp.vertices + rng.normal(0, 0.02, simp.vertices.shape) + [0.05, 0.0, 0.0]
        out.append(((torch.tensor(v, dtype=torch.float32), torch.tensor(simp.faces)), ref))
    return out


def _collate(batch):
    return [b[0] for b in batch], [b[1] for b in batch]


def _loader(items):
    return torch.utils.data.DataLoader(items, batch_size=BATCH, shuffle=False, collate_fn=_collate)


class Shift(nn.Module):
    """The 'simplifier' being trained: one learned translation applied to every simplified mesh."""

    def __init__(self) -> None:
        super().__init__()
        self.t = nn.Parameter(torch.zeros(3))

    def forward(self, meshes):
        return [(v + self.t, f) for v, f in meshes]


class Module(L.LightningModule):
    def __init__(self, items=None) -> None:
        super().__init__()
        self.items = items
        self.model = Shift()
        self.loss = MeshSurfaceDistanceLoss(power=2)
        self.surface = MeshSurfaceDistance(two_sided=True)
        self.vertex = NearestVertexDistance()
        # Scalar views of the metrics above, which is what Lightning can log: they share the metrics' accumulation.
        self.surface_log = self.surface.statistics(prefix="val/surface_")
        self.vertex_rmse = self.vertex.statistic("rmse")

    def training_step(self, batch, batch_idx):
        simplified, reference = batch
        loss = self.loss(self.model(simplified), reference)
        self.log("train/loss", loss, batch_size=len(simplified))
        return loss

    def validation_step(self, batch, batch_idx):
        simplified, reference = batch
        moved = self.model(simplified)
        self.surface.update(moved, reference)
        self.vertex.update(moved, reference)
        self.log_dict(self.surface_log, batch_size=len(simplified))
        self.log("val/vertex_rmse", self.vertex_rmse, batch_size=len(simplified))

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.5)

    def val_dataloader(self):
        # DDP: an uneven split chosen here (rank 0: items 0-2 in batches of 2 and 1, rank 1: items 3-4), so that no
        # item is duplicated or dropped (Lightning's DistributedSampler would pad the 5 items to 6).
        items = self.items or _items()
        if self.trainer.world_size == 2:
            items = items[:3] if self.trainer.global_rank == 0 else items[3:]
        return _loader(items)


class MemoryLogger(Logger):
    def __init__(self) -> None:
        super().__init__()
        self.history: list[tuple[int, dict[str, float]]] = []

    @property
    def name(self) -> str:
        return "memory"

    @property
    def version(self) -> int:
        return 0

    def log_hyperparams(self, params, *args, **kwargs) -> None:
        pass

    def log_metrics(self, metrics, step=None) -> None:
        self.history.append((step, dict(metrics)))


def _trainer(**kwargs):
    defaults = {
        "accelerator": "cpu",
        "enable_progress_bar": False,
        "enable_checkpointing": False,
        "enable_model_summary": False,
    }
    return L.Trainer(**(defaults | kwargs))


def _direct(model: Shift, items) -> dict[str, float]:
    """The metrics computed directly on all items in one update, with the trained model."""
    with torch.no_grad():
        moved = model([it[0] for it in items])
    surface, vertex = MeshSurfaceDistance(two_sided=True), NearestVertexDistance()
    surface.update(moved, [it[1] for it in items])
    vertex.update(moved, [it[1] for it in items])
    out = {f"val/surface_{k}": float(v) for k, v in surface.compute().items()}
    out["val/vertex_rmse"] = float(vertex.compute()["rmse"])
    return out


def test_fit_logs_exact_epoch_statistics(tmp_path):
    items = _items()
    module = Module(items)
    logger = MemoryLogger()
    trainer = _trainer(max_epochs=2, logger=logger, default_root_dir=tmp_path, log_every_n_steps=1)
    trainer.fit(module, train_dataloaders=_loader(items))
    val_logs = [m for _, m in logger.history if "val/surface_ave" in m]
    assert len(val_logs) == 2  # one per epoch (the sanity check logs nothing, and its updates were reset)
    assert float(module.model.t.detach().norm()) > 0  # the loss trained the shift
    expected = _direct(module.model, items)
    logged = val_logs[-1]
    assert set(expected) <= set(logged)
    for k, v in expected.items():
        assert logged[k] == pytest.approx(v, rel=1e-12, abs=0), k
    # The accumulation was reset between epochs: the first epoch's values differ (other weights), none are pooled.
    assert val_logs[0]["val/surface_count"] == logged["val/surface_count"] == expected["val/surface_count"]
    assert val_logs[0]["val/surface_ave"] != logged["val/surface_ave"]


def test_dict_metric_object_cannot_be_logged_but_its_views_can():
    class DictLogging(Module):
        def validation_step(self, batch, batch_idx):
            simplified, reference = batch
            self.surface.update(self.model(simplified), reference)
            self.log("val/surface", self.surface, batch_size=len(simplified))

    with pytest.raises(ValueError, match="must be a tensor"):
        _trainer(logger=False, limit_val_batches=1).validate(DictLogging(_items()[:2]), verbose=False)


def test_manual_log_dict_of_compute_at_epoch_end():
    # The other working pattern: log the computed dict at the epoch end (Lightning keeps float64 values float64).
    class ManualLogging(Module):
        def validation_step(self, batch, batch_idx):
            simplified, reference = batch
            self.surface.update(self.model(simplified), reference)

        def on_validation_epoch_end(self):
            self.log_dict({f"val/surface_{k}": v for k, v in self.surface.compute().items()})
            self.surface.reset()

    items = _items()
    (logged,) = _trainer(logger=False).validate(ManualLogging(items), verbose=False)
    expected = _direct(Shift(), items)
    assert set(expected) - {"val/vertex_rmse"} <= set(logged)
    for k in set(expected) - {"val/vertex_rmse"}:
        assert logged[k] == pytest.approx(expected[k], rel=1e-12, abs=0), k


def test_view_rejects_update_and_unknown_keys():
    m = MeshSurfaceDistance()
    with pytest.raises(ValueError, match="reverse_ave"):
        m.statistic("reverse_ave")  # one-sided: no reverse statistics
    with pytest.raises(ValueError, match="distinct"):
        m.statistics(["ave", "ave"])
    with pytest.raises(TypeError, match="source"):
        m.statistic("ave").update(torch.zeros(1, 3), trimesh.creation.icosphere(subdivisions=1))
    assert "symmetric_psnr" in MeshSurfaceDistance(two_sided=True).statistic_names()


class DDPModule(Module):
    def __init__(self, out_dir) -> None:
        super().__init__()
        self.out_dir = out_dir

    def setup(self, stage):
        torch.set_num_threads(1)  # a forked child must not reuse the parent's OpenMP pool; 2 ranks on 2 cores anyway

    def on_validation_epoch_end(self):
        # Each rank records how many simplified vertices it measured itself (before the metric's sync).
        n = int(MeshSurfaceDistance._forward_states.num_distances(self.surface))
        (self.out_dir / f"rank{self.global_rank}.txt").write_text(str(n))


@pytest.mark.skipif(
    not torch.distributed.is_available() or "fork" not in mp.get_all_start_methods(), reason="needs gloo and fork"
)
def test_ddp_two_processes_equal_single_process(tmp_path):
    # "ddp_fork" (not "ddp_spawn"): the children inherit the imported modules, so this takes ~1 s instead of ~20 s
    # (re-importing lightning costs ~6 s of CPU per process); the metric's sync is the same gloo all-gather.
    items = _items()
    trainer = _trainer(
        strategy="ddp_fork", devices=2, logger=False, default_root_dir=tmp_path, use_distributed_sampler=False
    )
    (logged,) = trainer.validate(DDPModule(tmp_path), verbose=False)
    assert trainer.world_size == 2
    expected = _direct(Shift(), items)  # untrained shift: zero
    # Both ranks ran, on their own uneven share (3 and 2 items), and the logged values pool both shares.
    local = [int((tmp_path / f"rank{r}.txt").read_text()) for r in (0, 1)]
    assert local[0] > local[1] > 0 and sum(local) == expected["val/surface_count"]
    assert set(expected) <= set(logged)
    for k, v in expected.items():
        assert logged[k] == pytest.approx(v, rel=1e-12, abs=0), k


def test_a_view_logged_for_steps_logs_the_batch_value_of_its_source(tmp_path):
    # Review Q: a view never ran forward, so Lightning (on_step=True, its default in training_step) logged nothing for
    # the steps, silently. Called (forward) in the step, the source's batch value of the key is the step value; the
    # epoch value stays the pooled one.
    class StepLogging(Module):
        def __init__(self, items) -> None:
            super().__init__(items)
            self.train_surface = MeshSurfaceDistance()
            self.train_rmse = self.train_surface.statistic("rmse")
            self.batch_rmse: list[float] = []

        def training_step(self, batch, batch_idx):
            simplified, reference = batch
            moved = self.model(simplified)
            batch_values = self.train_surface([(v.detach(), f) for v, f in moved], reference)
            self.batch_rmse.append(float(batch_values["rmse"]))
            self.log("train/rmse", self.train_rmse, on_step=True, on_epoch=True, batch_size=len(simplified))
            return self.loss(moved, reference)

    items = _items()
    module = StepLogging(items)
    logger = MemoryLogger()
    trainer = _trainer(max_epochs=1, logger=logger, default_root_dir=tmp_path, log_every_n_steps=1)
    trainer.fit(module, train_dataloaders=_loader(items), val_dataloaders=_loader(items))
    steps = [m["train/rmse_step"] for _, m in logger.history if "train/rmse_step" in m]
    assert steps == pytest.approx(module.batch_rmse, rel=1e-12) and len(steps) == 3
    epoch = [m["train/rmse_epoch"] for _, m in logger.history if "train/rmse_epoch" in m]
    assert len(epoch) == 1
    view = MeshSurfaceDistance().statistic("rmse")
    assert view._forward_cache is None  # update() alone: no batch value, as for any torchmetrics metric
