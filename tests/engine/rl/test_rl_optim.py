"""The flat fused Adam, and the torch version it needs."""

from __future__ import annotations

import tomllib
from pathlib import Path

import torch
from packaging.requirements import Requirement
from torch import nn

from engine.rl.optim import flat_adam

PYPROJECT = Path(__file__).parents[3] / "pyproject.toml"


def test_flat_adam_steps_like_adam_on_the_separate_tensors() -> None:
    torch.manual_seed(0)
    a, b = nn.Linear(3, 4), nn.Linear(3, 4)
    b.load_state_dict(a.state_dict())
    flat = flat_adam(list(a.parameters()), lr=0.1)
    plain = torch.optim.Adam(b.parameters(), lr=0.1, eps=1e-5)
    x = torch.randn(8, 3)
    for net, opt in ((a, flat), (b, plain)):
        opt.zero_grad(set_to_none=False)
        net(x).square().sum().backward()
        opt.step()
    assert flat.param_groups[0]["fused"]
    for p, q in zip(a.parameters(), b.parameters(), strict=True):
        torch.testing.assert_close(p, q)


def test_declared_torch_floor_has_fused_adam_on_cpu() -> None:
    deps = tomllib.loads(PYPROJECT.read_text())["project"]["dependencies"]
    torch_req = next(Requirement(d) for d in deps if Requirement(d).name == "torch")
    assert not torch_req.specifier.contains("2.3.1")  # fused=True on CPU arrived in 2.4
    assert torch_req.specifier.contains("2.4.0")
