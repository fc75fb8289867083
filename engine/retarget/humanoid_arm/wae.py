"""Shared latent space (§IV-B, Eqs. 1–5): one Wasserstein auto-encoder per domain, glued by paired data.

Per domain j: encoder Q^j and decoder P^j (3-layer ResNet MLPs, tanh), an adversarial latent prior
(discriminator d^j, Jensen–Shannon: Eq. 3 with the l1 reconstruction cost), and on the glue set the latent
consensus loss ‖Q^j(x^j) − Q^l(x^l)‖² (Eq. 4) and the cross-domain reconstruction ‖P^l(Q^j(x^j)) − x^l‖²
(Eq. 5). Inputs are normalised (zero mean, unit variance, stored with the weights); mini-batches are drawn
with LA-DPP. Weights are plain tensors (safetensors) beside a JSON metadata file. torch is imported only
in this package.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numba
import numpy as np
import torch
from torch import nn

from engine.retarget.humanoid_arm.la_dpp import BatchSampler

torch.set_num_threads(1)  # two shared cores: one training thread behaves best


class ResNetMLP(nn.Module):
    """in → tanh(W0 x) → (layers − 1) residual blocks h + tanh(W h) → linear out."""

    def __init__(self, d_in: int, d_out: int, hidden: int = 128, layers: int = 3):
        super().__init__()
        self.inp = nn.Linear(d_in, hidden)
        self.blocks = nn.ModuleList(nn.Linear(hidden, hidden) for _ in range(layers - 1))
        self.out = nn.Linear(hidden, d_out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.tanh(self.inp(x))
        for block in self.blocks:
            h = h + torch.tanh(block(h))
        return self.out(h)


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _mlp_forward(x: np.ndarray, w_in_t: np.ndarray, b_in: np.ndarray, w_blocks_t: np.ndarray, b_blocks: np.ndarray,
                 w_out_t: np.ndarray, b_out: np.ndarray, h: np.ndarray, out: np.ndarray) -> None:
    """One sample through the ResNet MLP: h = tanh(W_in x + b); h += tanh(W h + b) per block; out = W_out h + b.
    Weights transposed (out, in) so every dot product runs over contiguous memory; ``h`` is scratch."""
    hidden, d_in = w_in_t.shape
    for j in range(hidden):
        acc = b_in[j]
        for i in range(d_in):
            acc += w_in_t[j, i] * x[i]
        h[0, j] = np.tanh(acc)
    cur = 0
    for b in range(w_blocks_t.shape[0]):
        nxt = 1 - cur
        for j in range(hidden):
            acc = b_blocks[b, j]
            for i in range(hidden):
                acc += w_blocks_t[b, j, i] * h[cur, i]
            h[nxt, j] = h[cur, j] + np.tanh(acc)
        cur = nxt
    for j in range(w_out_t.shape[0]):
        acc = b_out[j]
        for i in range(hidden):
            acc += w_out_t[j, i] * h[cur, i]
        out[j] = acc


class CompiledEncoder:
    """A trained encoder for one sample at a time (the run-time path of LWL2): the input normalisation folded
    into the first layer, one numba call (:func:`_mlp_forward`) — equal to :class:`NumpyMLP` on normalised
    input to rounding (tested); batches go through :class:`NumpyMLP`."""

    def __init__(self, net: "NumpyMLP", mean: np.ndarray, std: np.ndarray):
        self.net, self.mean, self.std = net, mean, std
        w_in = net.w_in / std[:, None]  # ((x − m) / s) W + b = x (W / s) + (b − (m / s) W)
        self.w_in_t = np.ascontiguousarray(w_in.T)
        self.b_in = net.b_in - (mean / std) @ net.w_in
        self.w_blocks_t = np.ascontiguousarray(np.stack([w.T for w, _ in net.blocks]))
        self.b_blocks = np.ascontiguousarray(np.stack([b for _, b in net.blocks]))
        self.w_out_t, self.b_out = np.ascontiguousarray(net.w_out.T), net.b_out.copy()
        self._h = np.empty((2, self.w_in_t.shape[0]))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """(N, D) or (D,) raw input → (N, latent) (N = 1 for one sample)."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 2 and len(x) != 1:
            return self.net((x - self.mean) / self.std)
        out = np.empty((1, len(self.b_out)))
        _mlp_forward(x.ravel(), self.w_in_t, self.b_in, self.w_blocks_t, self.b_blocks, self.w_out_t, self.b_out,
                     self._h, out[0])
        return out


class NumpyMLP:
    """The same forward pass as a trained :class:`ResNetMLP` in float64 numpy: a single 15-d pose costs
    tens of µs instead of torch's per-call overhead (hundreds of µs) — the run-time path of LWL2."""

    def __init__(self, net: ResNetMLP):
        g = lambda t: t.detach().numpy().astype(np.float64)  # noqa: E731
        self.w_in, self.b_in = g(net.inp.weight).T.copy(), g(net.inp.bias)
        self.blocks = [(g(b.weight).T.copy(), g(b.bias)) for b in net.blocks]
        self.w_out, self.b_out = g(net.out.weight).T.copy(), g(net.out.bias)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        h = np.tanh(x @ self.w_in + self.b_in)
        for w, b in self.blocks:
            h = h + np.tanh(h @ w + b)
        return h @ self.w_out + self.b_out


class SharedLatentWAE(nn.Module):
    def __init__(self, dims: dict[str, int], latent_dim: int = 8, hidden: int = 128, seed: int | None = None):
        """``seed``: initialise the weights from this seed (reproducible training); None: torch's global RNG."""
        super().__init__()
        if seed is not None:
            torch.manual_seed(seed)
        self.dims, self.latent_dim, self.hidden = dict(dims), latent_dim, hidden
        self.encoders = nn.ModuleDict({k: ResNetMLP(d, latent_dim, hidden) for k, d in dims.items()})
        self.decoders = nn.ModuleDict({k: ResNetMLP(latent_dim, d, hidden) for k, d in dims.items()})
        self.discriminators = nn.ModuleDict({k: ResNetMLP(latent_dim, 1, hidden) for k in dims})
        for k, d in dims.items():
            self.register_buffer(f"mean_{k}", torch.zeros(d, dtype=torch.float64))
            self.register_buffer(f"std_{k}", torch.ones(d, dtype=torch.float64))

    def normalisation_of(self, domain: str) -> tuple[np.ndarray, np.ndarray]:
        """(mean, std) of a domain's raw features, float64 numpy copies of the registered buffers."""
        mean, std = getattr(self, f"mean_{domain}"), getattr(self, f"std_{domain}")
        return mean.numpy().copy(), std.numpy().copy()

    # normalisation (numpy in, numpy out at the edges)
    def set_normalisation(self, domain: str, data: np.ndarray) -> None:
        getattr(self, f"mean_{domain}").copy_(torch.as_tensor(data.mean(axis=0)))
        getattr(self, f"std_{domain}").copy_(torch.as_tensor(np.maximum(data.std(axis=0), 1e-3)))

    def normalise(self, domain: str, x: np.ndarray) -> np.ndarray:
        return (x - getattr(self, f"mean_{domain}").numpy()) / getattr(self, f"std_{domain}").numpy()

    def denormalise(self, domain: str, x: np.ndarray) -> np.ndarray:
        return x * getattr(self, f"std_{domain}").numpy() + getattr(self, f"mean_{domain}").numpy()

    @torch.no_grad()
    def encode(self, domain: str, x: np.ndarray) -> np.ndarray:
        t = torch.as_tensor(self.normalise(domain, np.atleast_2d(x)), dtype=torch.float32)
        return self.encoders[domain](t).numpy().astype(np.float64)

    @torch.no_grad()
    def decode(self, domain: str, z: np.ndarray) -> np.ndarray:
        t = torch.as_tensor(np.atleast_2d(z), dtype=torch.float32)
        return self.denormalise(domain, self.decoders[domain](t).numpy().astype(np.float64))

    def numpy_encoder(self, domain: str) -> CompiledEncoder:
        """A callable (N, D) raw → (N, latent) equal to :meth:`encode` (to float32 rounding), without torch:
        one compiled call per sample (:class:`CompiledEncoder`), numpy for batches."""
        encoder = self.encoders[domain]
        assert isinstance(encoder, ResNetMLP)
        mean, std = self.normalisation_of(domain)
        return CompiledEncoder(NumpyMLP(encoder), mean, std)

    def transfer(self, src: str, dst: str, x: np.ndarray) -> np.ndarray:
        """The feed-forward map P^dst(Q^src(x)) (no LWR)."""
        return self.decode(dst, self.encode(src, x))


@dataclass
class TrainConfig:
    iterations: int = 3000
    batch_size: int = 128
    lr: float = 1e-3
    beta_adv: float = 1.0  # β of Eq. 3
    w_latent: float = 1.0  # Eq. 4
    w_cross: float = 1.0  # Eq. 5
    la_dpp: bool = True
    la_dpp_chunk: int = 4096
    seed: int = 0


@dataclass
class DomainData:
    data: np.ndarray  # (N, D) raw (un-normalised)
    dpp_features: np.ndarray | None = None  # the space LA-DPP measures distances in (default: the normalised data)


CHECKPOINT_FORMAT = "lwl2-wae-checkpoint/1"


def save_checkpoint(path: Path, it: int, model: SharedLatentWAE, opt, opt_d, rng: np.random.Generator,
                    cfg: TrainConfig) -> None:
    """Everything a resumed run needs to continue exactly where this one stopped (plain tensors and
    strings: loadable with ``torch.load(weights_only=True)``), written atomically."""
    import io

    from engine.atomic_io import atomic_write_bytes

    buf = io.BytesIO()
    torch.save({"format": CHECKPOINT_FORMAT, "iteration": it, "model": model.state_dict(), "opt": opt.state_dict(),
                "opt_d": opt_d.state_dict(), "numpy_rng": json.dumps(rng.bit_generator.state),
                "torch_rng": torch.get_rng_state(), "config": json.dumps(cfg.__dict__, sort_keys=True)}, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: Path, cfg: TrainConfig) -> dict:
    """A checkpoint of a run with the same configuration; ValueError (one line) otherwise."""
    try:
        ck = torch.load(path, weights_only=True)
    except (OSError, RuntimeError, ValueError, EOFError) as exc:
        raise ValueError(f"{path}: cannot read the training checkpoint: {str(exc).splitlines()[0]}") from None
    if not isinstance(ck, dict) or ck.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: format: expected {CHECKPOINT_FORMAT!r}")
    if ck.get("config") != json.dumps(cfg.__dict__, sort_keys=True):
        raise ValueError(f"{path}: config: the checkpoint belongs to another training configuration "
                         f"(delete it or train with the same options)")
    return ck


def train_wae(model: SharedLatentWAE, domains: dict[str, DomainData], glue: dict[str, np.ndarray] | None,
              cfg: TrainConfig, progress: Callable[[int, int, dict], None] | None = None,
              should_stop: Callable[[], bool] | None = None, checkpoint: Path | None = None,
              checkpoint_every: int = 100) -> dict:
    """Train in place. ``glue`` maps each domain to (G, D) raw arrays of corresponding rows (or None).

    With ``checkpoint``: the state is saved there every ``checkpoint_every`` iterations and on cancel, and a
    run finding a checkpoint of the same configuration continues from it — with the saved random states,
    so an interrupted and resumed run gives the same weights as an uninterrupted one.
    Returns the final losses. Raises KeyboardInterrupt through when cancelled."""
    rng = np.random.default_rng(cfg.seed)
    torch.manual_seed(cfg.seed)
    names = list(domains)
    normed = {}
    samplers = {}
    for k in names:
        model.set_normalisation(k, domains[k].data)
        normed[k] = torch.as_tensor(model.normalise(k, domains[k].data), dtype=torch.float32)
        dpp = domains[k].dpp_features
        feats = dpp if dpp is not None else normed[k].numpy()
        samplers[k] = BatchSampler(feats, cfg.batch_size, rng, cfg.la_dpp, chunk=cfg.la_dpp_chunk)
    glue_t = None
    if glue:
        glue_t = {k: torch.as_tensor(model.normalise(k, glue[k]), dtype=torch.float32) for k in names}
        n_glue = len(next(iter(glue.values())))
    ae_params = [p for k in names for p in (*model.encoders[k].parameters(), *model.decoders[k].parameters())]
    disc_params = [p for k in names for p in model.discriminators[k].parameters()]
    opt = torch.optim.Adam(ae_params, lr=cfg.lr)
    opt_d = torch.optim.Adam(disc_params, lr=cfg.lr)
    start = 0
    if checkpoint is not None and Path(checkpoint).is_file():
        ck = load_checkpoint(Path(checkpoint), cfg)
        model.load_state_dict(ck["model"])
        opt.load_state_dict(ck["opt"])
        opt_d.load_state_dict(ck["opt_d"])
        rng.bit_generator.state = json.loads(ck["numpy_rng"])
        torch.set_rng_state(ck["torch_rng"])
        start = int(ck["iteration"])
        for sampler in samplers.values():
            sampler.rng = rng
    return _train_loop(model, names, normed, samplers, glue_t, n_glue if glue_t is not None else 0, cfg, rng,
                       opt, opt_d, start, time.perf_counter(), progress, should_stop, checkpoint, checkpoint_every)


def _train_loop(model, names, normed, samplers, glue_t, n_glue, cfg, rng, opt, opt_d, start, t0, progress,
                should_stop, checkpoint, checkpoint_every) -> dict:
    bce = nn.BCEWithLogitsLoss()
    losses: dict = {}
    for it in range(start, cfg.iterations):
        if checkpoint is not None and it > start and it % checkpoint_every == 0:
            save_checkpoint(Path(checkpoint), it, model, opt, opt_d, rng, cfg)
        if should_stop is not None and should_stop():
            if checkpoint is not None:
                save_checkpoint(Path(checkpoint), it, model, opt, opt_d, rng, cfg)
            raise KeyboardInterrupt
        batches = {k: normed[k][samplers[k]()] for k in names}
        z = {k: model.encoders[k](batches[k]) for k in names}
        rec = sum((model.decoders[k](z[k]) - batches[k]).abs().sum(dim=1).mean() for k in names)
        adv = sum(bce(model.discriminators[k](z[k]), torch.ones(len(z[k]), 1)) for k in names)
        loss = rec + cfg.beta_adv * adv
        lat = cro = torch.zeros(())
        if glue_t is not None:
            gi = torch.as_tensor(rng.integers(n_glue, size=min(cfg.batch_size, n_glue)))
            gz = {k: model.encoders[k](glue_t[k][gi]) for k in names}
            for a_i, a in enumerate(names):
                for b in names[a_i + 1:]:
                    lat = lat + ((gz[a] - gz[b]) ** 2).sum(dim=1).mean()
                for b in names:
                    if b != a:
                        cro = cro + ((model.decoders[b](gz[a]) - glue_t[b][gi]) ** 2).sum(dim=1).mean()
                rec = rec + (model.decoders[a](gz[a]) - glue_t[a][gi]).abs().sum(dim=1).mean()
            loss = rec + cfg.beta_adv * adv + cfg.w_latent * lat + cfg.w_cross * cro
        opt.zero_grad()
        loss.backward()
        opt.step()
        # discriminators: prior samples are "real", encodings "fake"
        d_loss = torch.zeros(())
        for k in names:
            zp = torch.randn(cfg.batch_size, model.latent_dim)
            d_loss = d_loss + bce(model.discriminators[k](zp), torch.ones(len(zp), 1)) \
                + bce(model.discriminators[k](z[k].detach()), torch.zeros(len(z[k]), 1))
        opt_d.zero_grad()
        d_loss.backward()
        opt_d.step()
        losses = {k: float(v.detach()) for k, v in (("rec", rec), ("adv", adv), ("latent", lat), ("cross", cro), ("disc", d_loss))}
        if progress is not None and (it % 25 == 0 or it + 1 == cfg.iterations):
            progress(it + 1, cfg.iterations, {**losses, "elapsed_s": time.perf_counter() - t0})
    if checkpoint is not None:
        save_checkpoint(Path(checkpoint), cfg.iterations, model, opt, opt_d, rng, cfg)
    return losses


# ----------------------------------------------------------------------------- files


def save_weights(model: SharedLatentWAE, path: Path, extra_tensors: dict[str, np.ndarray], metadata: dict) -> None:
    """``path``.safetensors (network + extra arrays) and ``path``.json (metadata), written atomically."""
    from safetensors.torch import save

    from engine.atomic_io import atomic_write_bytes, atomic_write_text

    tensors = {f"net.{k}": v.detach().contiguous() for k, v in model.state_dict().items()}
    for k, v in extra_tensors.items():
        tensors[f"data.{k}"] = torch.as_tensor(np.ascontiguousarray(v))
    meta = {**metadata, "dims": model.dims, "latent_dim": model.latent_dim, "hidden": model.hidden}
    atomic_write_bytes(path.with_suffix(".safetensors"), save(tensors))
    atomic_write_text(path.with_suffix(".json"), json.dumps(meta, indent=1))


def load_weights(path: Path) -> tuple[SharedLatentWAE, dict[str, np.ndarray], dict]:
    """Inverse of :func:`save_weights`; ValueError (one line) on a missing or inconsistent file."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    meta_path, tensor_path = path.with_suffix(".json"), path.with_suffix(".safetensors")
    if not meta_path.is_file() or not tensor_path.is_file():
        raise ValueError(f"{path}: expected {meta_path.name} and {tensor_path.name} (train with `studio train-arms`)")
    try:
        meta = json.loads(meta_path.read_text())
        tensors = load_file(str(tensor_path))
        model = SharedLatentWAE(meta["dims"], meta["latent_dim"], meta["hidden"])
        model.load_state_dict({k[4:]: v for k, v in tensors.items() if k.startswith("net.")})
    except (OSError, ValueError, KeyError, RuntimeError, SafetensorError) as exc:  # a truncated file: SafetensorError
        raise ValueError(f"{tensor_path}: cannot load weights: {str(exc).splitlines()[0]}") from None
    model.eval()
    extra = {k[5:]: v.numpy() for k, v in tensors.items() if k.startswith("data.")}
    return model, extra, meta


__all__ = ["ResNetMLP", "NumpyMLP", "CompiledEncoder", "SharedLatentWAE", "TrainConfig", "DomainData", "train_wae", "save_weights", "load_weights"]
