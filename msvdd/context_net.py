"""`ContextNet`: a frame's density given its neighbours, learned (a mixture density network, Bishop 1994).

`msvdd.context.ContextMixture` models p(x_t | c_t) with two Gaussian mixtures over a fixed linear context, the
principal axes of the neighbouring frames. `ContextNet` learns the context and the conditional density
together. Its input is the k = `CONTEXT_NEIGHBOURS` frames on either side of x_t in the same window (the
window's edge frames repeated, `msvdd.context.neighbour_context`); an encoder of two GELU layers of
`HIDDEN` units maps them to `FEATURES` values, a head of two more to the logits, means and log scales of
`COMPONENTS` diagonal Gaussians over x_t whitened by the training frames (y = (x - m) V diag(lambda)^-1/2,
V, lambda the eigenvectors and eigenvalues of their covariance). The log scales are clamped to [-5, 3].

Training minimises the mean -log p(y_t | c_t) over frames: AdamW (weight decay 1e-4) with a one-cycle
learning rate peaking at 2e-3, `EPOCHS` epochs of `FRAMES_PER_EPOCH` frames drawn without replacement from
the training frames in batches of `BATCH`, from a seeded initialisation and seeded draws; the epoch with
the lowest mean loss over (up to `VAL_FRAMES` of) the validation frames is kept, the last one without
validation frames. Like `ContextMixture` the floor is the smallest -log p over every training frame and a
window's distance is sqrt(2 (nll - floor)) of its least likely frame.

Every constant was set before the network was first run, none tuned. Where it is used (the audio term of the
reference method `context-net-frames`, on `msvdd`'s normalised log-mel input frames) was chosen on the dev
dataset (seed 1) of the `paper` preset: README, "The detector".
"""

from __future__ import annotations

import math

import torch
from torch import nn

from msvdd.context import CONTEXT_NEIGHBOURS, _offsets, neighbour_context

COMPONENTS = 8
"""Gaussians of the conditional density."""
FEATURES = 16
"""Width of the encoder's output (the learned context)."""
HIDDEN = 256
"""Width of the encoder's and the head's hidden layers."""
EPOCHS = 10
"""Training epochs."""
FRAMES_PER_EPOCH = 200_000
"""Training frames drawn per epoch (all of them when there are fewer)."""
BATCH = 1024
"""Frames per optimiser step."""
VAL_FRAMES = 100_000
"""Validation frames (the first ones) whose mean loss selects the epoch."""
_LOG_SCALE = (-5.0, 3.0)
_BLOCK = 256
"""Windows per block when scoring."""


class ContextNet(nn.Module):
    """-log p(x_t | neighbours) of each frame; `fit_context_net` trains one, `nll` and `peak_distance`
    score."""

    def __init__(self, p: int, neighbours: int = CONTEXT_NEIGHBOURS) -> None:
        super().__init__()
        self.p = p
        self.neighbours = neighbours
        q = len(_offsets(neighbours)) * p
        self.encoder = nn.Sequential(
            nn.Linear(q, HIDDEN), nn.GELU(), nn.Linear(HIDDEN, HIDDEN), nn.GELU(), nn.Linear(HIDDEN, FEATURES)
        )
        self.head = nn.Sequential(
            nn.GELU(),
            nn.Linear(FEATURES, HIDDEN),
            nn.GELU(),
            nn.Linear(HIDDEN, COMPONENTS * (2 * p + 1)),
        )
        self.center: torch.Tensor
        self.whiten: torch.Tensor
        self.floor: torch.Tensor
        self.register_buffer("center", torch.zeros(p))
        self.register_buffer("whiten", torch.eye(p))
        self.register_buffer("floor", torch.zeros((), dtype=torch.float64))

    def frame_nll(self, context: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """(..., 2 k p) raw contexts and (..., p) whitened frames -> (...) float32 -log p(y | context)."""
        out = self.head(self.encoder(context))
        k, p = COMPONENTS, self.p
        logits = out[..., :k]
        means = out[..., k : k + k * p].reshape(*out.shape[:-1], k, p)
        log_scales = out[..., k + k * p :].reshape(*out.shape[:-1], k, p).clamp(*_LOG_SCALE)
        z = (y.unsqueeze(-2) - means) * torch.exp(-log_scales)
        log_comp = -0.5 * (z * z).sum(-1) - log_scales.sum(-1) - 0.5 * p * math.log(2.0 * math.pi)
        return -torch.logsumexp(torch.log_softmax(logits, dim=-1) + log_comp, dim=-1)

    def window_nll(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) window frames -> (N, T) float32 -log p(x_t | c_t) in one pass (`nll` runs it in
        blocks)."""
        x = frames.to(torch.float32)
        return self.frame_nll(neighbour_context(x, self.neighbours), (x - self.center) @ self.whiten)

    def nll(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) window frames -> (N, T) float64 -log p(x_t | c_t), in blocks of windows, no gradient."""
        with torch.inference_mode():
            out = [self.window_nll(block).to(torch.float64) for block in frames.split(_BLOCK)]
        if not out:
            return torch.zeros(0, frames.shape[1], dtype=torch.float64, device=frames.device)
        return torch.cat(out)

    def peak_distance(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) window frames -> (N,) float64 sqrt(2 (nll - floor)) of each window's least likely
        frame."""
        nll = self.nll(frames).amax(dim=1)
        return (2.0 * (nll - self.floor).clamp_min(0.0)).sqrt()

    def state(self) -> dict[str, torch.Tensor]:
        """Tensors for saving (CPU): the weights, whitening, floor, frame size and neighbours."""
        state = {k: v.detach().cpu() for k, v in self.state_dict().items()}
        return {**state, "p": torch.tensor(self.p), "neighbours": torch.tensor(self.neighbours)}

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor], device: torch.device) -> ContextNet:
        """Inverse of `state` (a missing key: KeyError; a wrong shape: RuntimeError)."""
        net = cls(int(state["p"]), int(state["neighbours"]))
        net.load_state_dict({k: v for k, v in state.items() if k not in ("p", "neighbours")})
        return net.to(device).eval()


def _whitening(frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(mean (p,), W (p, p)) float32 of (n, p) frames: (x - mean) @ W has identity covariance (PCA)."""
    x = frames.to(torch.float64)
    mean = x.mean(dim=0)
    c = x - mean
    evals, evecs = torch.linalg.eigh(c.T @ c / max(len(c) - 1, 1))
    return mean.float(), (evecs / evals.clamp_min(1e-6).sqrt()).float()


def fit_context_net(
    frames: torch.Tensor,
    val_frames: torch.Tensor | None,
    seed: int,
    neighbours: int = CONTEXT_NEIGHBOURS,
) -> ContextNet:
    """The `ContextNet` of training windows' frames (N, T, p) on their device, trained as the module
    docstring says, the epoch chosen on `val_frames` (M, T, p) (None or empty: the last epoch).

    Raises:
        ValueError: fewer than two training frames.
    """
    n, steps, p = frames.shape
    if n * steps < 2:
        raise ValueError(f"a context network needs at least 2 training frames, got {n * steps}")
    device = frames.device
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        net = ContextNet(p, neighbours).to(device)
    center, whiten = _whitening(frames.reshape(-1, p))
    net.center.copy_(center)
    net.whiten.copy_(whiten)
    x = frames.to(torch.float32)
    contexts = neighbour_context(x, neighbours).reshape(n * steps, -1)
    targets = ((x - center) @ whiten).reshape(n * steps, p)
    val: tuple[torch.Tensor, torch.Tensor] | None = None
    if val_frames is not None and len(val_frames):
        v = val_frames.to(device, torch.float32)
        val = (
            neighbour_context(v, neighbours).reshape(-1, contexts.shape[1])[:VAL_FRAMES],
            ((v - center) @ whiten).reshape(-1, p)[:VAL_FRAMES],
        )
    per_epoch = min(FRAMES_PER_EPOCH, n * steps)
    steps_per_epoch = math.ceil(per_epoch / BATCH)
    optimiser = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, 2e-3, total_steps=EPOCHS * steps_per_epoch)
    gen = torch.Generator().manual_seed(seed)
    best, best_state = math.inf, None
    for _ in range(EPOCHS):
        net.train()
        order = torch.randperm(n * steps, generator=gen)[:per_epoch].to(device)
        for idx in order.split(BATCH):
            loss = net.frame_nll(contexts[idx], targets[idx]).mean()
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
            schedule.step()
        if val is not None:
            net.eval()
            with torch.inference_mode():
                v_loss = float(
                    torch.cat(
                        [
                            net.frame_nll(c, y)
                            for c, y in zip(val[0].split(8 * BATCH), val[1].split(8 * BATCH), strict=True)
                        ]
                    ).mean()
                )
            if v_loss < best:
                best = v_loss
                best_state = {k: t.detach().clone() for k, t in net.state_dict().items()}
    if best_state is not None:
        net.load_state_dict(best_state)
    net.eval()
    net.floor.fill_(float(net.nll(frames).min()))
    return net
