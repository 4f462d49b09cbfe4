"""A Lightning callback logging a validation pair's error-coloured mesh to every logger of the trainer."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

from lightning.pytorch import Callback, LightningModule, Trainer

from torchmeshmetric._checks import check_int
from torchmeshmetric.structures import MeshLike
from torchmeshmetric.viz.colors import check_vmax
from torchmeshmetric.viz.error_mesh import error_mesh
from torchmeshmetric.viz.mesh_logging import check_tag, log_error_mesh, surface_errors

__all__ = ["ErrorMeshCallback"]


class ErrorMeshCallback(Callback):
    """At the end of every ``every_n_epochs``-th validation epoch, log ``pair(trainer, module)``'s error mesh.

    ``pair`` returns ``(simplified, reference)``: e.g. the model's output for one validation frame and that frame.
    The simplified mesh is coloured by the distance of each vertex to the reference surface and logged with
    :func:`~torchmeshmetric.viz.mesh_logging.log_error_mesh` to every logger of the trainer (TensorBoard
    ``add_mesh``, W&B GLB, else a PLY/GLB file in the logger's folder), by the global-zero process only, not
    during the sanity check.

    Args:
        pair: ``(trainer, module) -> (simplified, reference)``.
        tag: the log's name.
        vmax: the error of the brightest colour, finite and positive, the same at every epoch so that colours
            compare (default: each mesh's 95th percentile).
        every_n_epochs: log every n-th validation epoch.
        unit: the unit of the distances.
        file_format: the file of the loggers that take files.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> callback = ErrorMeshCallback(lambda trainer, module: (sphere, sphere), vmax=0.01)
        >>> callback.tag
        'val/error_mesh'
    """

    def __init__(
        self,
        pair: Callable[[Trainer, LightningModule], tuple[MeshLike, MeshLike]],
        *,
        tag: str = "val/error_mesh",
        vmax: float | None = None,
        every_n_epochs: int = 1,
        unit: str = "mesh units",
        file_format: Literal["glb", "ply"] = "glb",
    ) -> None:
        if not callable(pair):
            raise TypeError(f"pair: expected a callable (trainer, module) -> (simplified, reference), found {pair!r}")
        every_n_epochs = check_int(every_n_epochs, "every_n_epochs", 1)
        self.vmax = check_vmax(vmax)  # refused now, not at the end of the first validation epoch
        self.pair = pair
        self.tag = check_tag(tag)
        self.every_n_epochs = every_n_epochs
        self.unit = unit
        self.file_format: Literal["glb", "ply"] = file_format
        self.what = "surface distance to the reference"

    def on_validation_epoch_end(self, trainer: Trainer, pl_module: LightningModule) -> None:
        """Log the pair's error mesh to every logger (global zero only, not in the sanity check)."""
        if trainer.sanity_checking or not trainer.is_global_zero:
            return
        if trainer.current_epoch % self.every_n_epochs:
            return
        simplified, reference = self.pair(trainer, pl_module)
        # measured and coloured once, logged to every logger
        coloured = error_mesh(
            self.tag, simplified, surface_errors(simplified, reference), what=self.what, vmax=self.vmax, unit=self.unit
        )
        loggers: list[Any] = list(trainer.loggers)
        for logger in loggers:
            log_error_mesh(logger, self.tag, coloured, step=trainer.global_step, file_format=self.file_format)
