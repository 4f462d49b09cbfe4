"""Adam for the registration loop: torch's own Adam update on a list of parameters, without the Optimizer class.

``torch.optim.Adam(fused=True).step()`` calls the functional :func:`torch.optim.adam.adam` (one fused kernel per
parameter list); this class calls it directly with the same state and arguments, so the iterates are the same bit
for bit (tested). What it leaves out is the class's machinery, which the registration does not use (parameter
groups, hooks, state dicts) and which costs there: its first method call imports ``torch._dynamo`` (~2 s per
process: a third of the paper-size demo's registration time) and each step ~50 us of Python around a ~12 us kernel.
"""

from __future__ import annotations

from collections.abc import Iterable

import torch
from torch import Tensor
from torch.optim.adam import adam

__all__ = ["Adam"]


class Adam:
    """Adam (Kingma & Ba) with torch's fused kernel on ``params``; defaults are ``torch.optim.Adam``'s.

    Args:
        params: leaf tensors updated in place from their ``.grad`` (a parameter without a gradient is skipped,
            as ``torch.optim.Adam`` does).
        lr: learning rate.
        betas: decay rates of the first and second moment estimates.
        eps: term added to the denominator.

    Example:
        >>> x = torch.tensor([1.0, -2.0], requires_grad=True)
        >>> opt = Adam([x], lr=0.1)
        >>> x.grad = torch.tensor([0.5, -0.5])
        >>> opt.step()
        >>> x.detach()
        tensor([ 0.9000, -1.9000])
    """

    def __init__(
        self, params: Iterable[Tensor], lr: float, betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8
    ) -> None:
        self.params = list(params)
        self.lr, self.betas, self.eps = lr, betas, eps
        # The state torch.optim.Adam(fused=True) creates: float32 step counters on the parameter's device.
        self.exp_avgs = [torch.zeros_like(p, memory_format=torch.preserve_format) for p in self.params]
        self.exp_avg_sqs = [torch.zeros_like(p, memory_format=torch.preserve_format) for p in self.params]
        self.steps = [torch.zeros((), dtype=torch.float32, device=p.device) for p in self.params]

    @torch.no_grad()
    def step(self) -> None:
        """One Adam update of every parameter that has a gradient."""
        have = [i for i, p in enumerate(self.params) if p.grad is not None]
        grads = [self.params[i].grad for i in have]
        adam(
            [self.params[i] for i in have],
            [g for g in grads if g is not None],
            [self.exp_avgs[i] for i in have],
            [self.exp_avg_sqs[i] for i in have],
            [],
            [self.steps[i] for i in have],
            foreach=False,
            capturable=False,
            differentiable=False,
            fused=True,
            grad_scale=None,
            found_inf=None,
            has_complex=False,
            decoupled_weight_decay=False,
            amsgrad=False,
            beta1=self.betas[0],
            beta2=self.betas[1],
            lr=self.lr,
            weight_decay=0.0,
            eps=self.eps,
            maximize=False,
        )
