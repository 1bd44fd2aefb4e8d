"""Adam over one flat parameter buffer: the per-tensor overhead of a tiny network, paid once.

A PPO minibatch step on 2x64 MLPs is dominated by per-tensor kernel launches: gradient
clipping and Adam each touch ~16 small tensors. Making the parameters views of one flat
tensor, and their gradients views of one flat gradient, turns both into single-tensor
operations (the same arithmetic, about a fifth of the step time saved).
"""

from __future__ import annotations

import torch
from torch import nn


def flatten_(params: list[nn.Parameter]) -> nn.Parameter:
    """Re-home ``params`` (in place) as views of one flat parameter, gradients included.

    Autograd accumulates into an existing ``.grad`` in place, so the gradient views keep
    filling the flat gradient; zero it with ``zero_grad(set_to_none=False)``.
    """
    flat = nn.Parameter(torch.cat([p.detach().reshape(-1) for p in params]))
    flat.grad = torch.zeros_like(flat)
    offset = 0
    for p in params:
        n = p.numel()
        p.data = flat.data[offset : offset + n].view_as(p)
        p.grad = flat.grad[offset : offset + n].view_as(p)
        offset += n
    return flat


def flat_adam(params: list[nn.Parameter], lr: float, eps: float = 1e-5) -> torch.optim.Adam:
    """Fused Adam on :func:`flatten_` of ``params`` (equivalent to Adam on the params)."""
    return torch.optim.Adam([flatten_(params)], lr=lr, eps=eps, fused=True)
