"""The registration's Adam is torch.optim.Adam(fused=True) bit for bit, without importing torch._dynamo."""

from __future__ import annotations

import subprocess
import sys

import pytest
import torch

from torchmeshmetric.registration.adam import Adam


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_same_iterates_as_torch_optim_adam(dtype: torch.dtype) -> None:
    g = torch.Generator().manual_seed(0)
    start = [torch.randn(40, 3, generator=g, dtype=dtype), torch.randn(40, 3, generator=g, dtype=dtype)]
    ours = [p.clone().requires_grad_() for p in start]
    ref = [p.clone().requires_grad_() for p in start]
    opt, ref_opt = Adam(ours, lr=0.01), torch.optim.Adam(ref, lr=0.01, foreach=False, fused=True)
    for step in range(25):
        grads = [torch.randn(40, 3, generator=g, dtype=dtype) * 10.0**-step for _ in start]
        for p, q, gr in zip(ours, ref, grads, strict=True):
            p.grad, q.grad = gr.clone(), gr.clone()
        if step == 7:  # a parameter without a gradient is skipped, its moments untouched
            ours[1].grad = ref[1].grad = None
        opt.step()
        ref_opt.step()
        for p, q in zip(ours, ref, strict=True):
            assert torch.equal(p, q)


def test_a_registration_does_not_import_dynamo() -> None:
    code = (
        "import sys, torch\n"
        "from torchmeshmetric import register_nonrigid\n"
        "from torchmeshmetric.data import demo_sequence\n"
        "seq = demo_sequence(2, resolution=24)\n"
        "register_nonrigid(seq.frames[0], seq.frames[1])\n"
        "assert 'torch._dynamo' not in sys.modules, 'torch._dynamo was imported'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)
