"""Baseline of §V-A / the issue: a feed-forward network trained on the glue (paired) set only, L2 loss.

Same ResNet MLP as the WAE's parts; it cannot use the domain-specific sets and guarantees nothing about
collisions. Saved beside the LWL2 weights (``<robot>_lwl2_ff.safetensors``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from engine.retarget.humanoid_arm.wae import ResNetMLP


class FeedForward:
    def __init__(self, net: ResNetMLP, mean_in, std_in, mean_out, std_out):
        self.net, self.mean_in, self.std_in, self.mean_out, self.std_out = net, mean_in, std_in, mean_out, std_out

    @torch.no_grad()
    def __call__(self, x: np.ndarray) -> np.ndarray:
        t = torch.as_tensor((x - self.mean_in) / self.std_in, dtype=torch.float32)
        return self.net(t).numpy().astype(np.float64) * self.std_out + self.mean_out

    def tensors(self) -> dict[str, torch.Tensor]:
        out = {f"net.{k}": v.detach().contiguous() for k, v in self.net.state_dict().items()}
        for k in ("mean_in", "std_in", "mean_out", "std_out"):
            out[k] = torch.as_tensor(getattr(self, k))
        return out


def train_feed_forward(x: np.ndarray, y: np.ndarray, iterations: int = 2000, hidden: int = 128, seed: int = 0,
                       batch_size: int = 128) -> FeedForward:
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    mi, si = x.mean(0), np.maximum(x.std(0), 1e-3)
    mo, so = y.mean(0), np.maximum(y.std(0), 1e-3)
    xt = torch.as_tensor((x - mi) / si, dtype=torch.float32)
    yt = torch.as_tensor((y - mo) / so, dtype=torch.float32)
    net = ResNetMLP(x.shape[1], y.shape[1], hidden)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(iterations):
        idx = torch.as_tensor(rng.integers(len(x), size=min(batch_size, len(x))))
        loss = ((net(xt[idx]) - yt[idx]) ** 2).sum(dim=1).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    net.eval()
    return FeedForward(net, mi, si, mo, so)


def ff_path(weights: Path) -> Path:
    return weights.with_name(weights.name + "_ff.safetensors")


def save_feed_forward(ff: FeedForward, weights: Path) -> None:
    from safetensors.torch import save

    from engine.atomic_io import atomic_write_bytes

    atomic_write_bytes(ff_path(weights), save(ff.tensors()))


def load_feed_forward(weights: Path) -> FeedForward:
    """The baseline saved beside ``weights``; ValueError (one line) on a missing, truncated or inconsistent file."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    path = ff_path(weights)
    try:
        t = load_file(str(path))
        state = {k[4:]: v for k, v in t.items() if k.startswith("net.")}
        d_in, hidden = state["inp.weight"].shape[1], state["inp.weight"].shape[0]
        d_out = state["out.weight"].shape[0]
        layers = 1 + sum(1 for k in state if k.startswith("blocks.") and k.endswith(".weight"))
        net = ResNetMLP(d_in, d_out, hidden, layers)
        net.load_state_dict(state)
        stats = [t[k].numpy().astype(np.float64) for k in ("mean_in", "std_in", "mean_out", "std_out")]
    except (OSError, ValueError, KeyError, IndexError, RuntimeError, SafetensorError) as exc:
        detail = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise ValueError(f"{path}: cannot load the feed-forward baseline: {detail}") from None
    net.eval()
    return FeedForward(net, *stats)
