"""`ContextNet`: a frame's density given its neighbours, learned (a mixture density network, Bishop 1994).

`msvdd.context.ContextMixture` models p(x_t | c_t) with two Gaussian mixtures over a fixed linear context, the
principal axes of the neighbouring frames. `ContextNet` learns the context and the conditional density
together. Its input is the k = `CONTEXT_NEIGHBOURS` frames on either side of x_t in the same window (the
window's edge frames repeated, `msvdd.context.neighbour_context`) and, for a cross-modal density, the
`CROSS_NEIGHBOURS` frames on either side of the other modality's frame at the same time and that frame itself
(`aligned_context`: frame j(t) = floor((t + 1/2) T_o / T) of the other modality's T_o frames, edges repeated);
an encoder of two GELU layers of
`HIDDEN` units maps them to `FEATURES` values, a head of two more to the logits, means and log scales of
`COMPONENTS` diagonal Gaussians over x_t whitened by the training frames (y = (x - m) V diag(lambda)^-1/2,
V, lambda the eigenvectors and eigenvalues of their covariance). The log scales are clamped to [-5, 3].

Training minimises the mean -log p(y_t | c_t) over frames: AdamW (weight decay 1e-4) with a one-cycle
learning rate peaking at 2e-3, `EPOCHS` epochs of `FRAMES_PER_EPOCH` frames drawn without replacement from
the training frames in batches of `BATCH`, from a seeded initialisation and seeded draws; the epoch with
the lowest mean loss over (up to `VAL_FRAMES` of) the validation frames is kept, the last one without
validation frames. Like `ContextMixture` the floor is the smallest -log p over every training frame and a
window's distance is sqrt(2 (nll - floor)) of its least likely frame.

Every constant was set before the network was first run, none tuned (`CROSS_NEIGHBOURS` = 2 is the frames'
own `CONTEXT_NEIGHBOURS`). Where it is used was chosen on the dev dataset (seed 1) of the `paper` preset
(docs/detectors.md): the audio term of the references `context-net-frames`, `frame-density` and of
`frame-density-msvdd` (`MSVDDConfig.frame_density`; the method was named `msvdd` in 0.1.0), on the
normalised log-mel input frames given their neighbours; and the IMU term of the latter two, the IMU input
frames given their neighbours and the log-mel frames around them (on the dev set the audio context helped
the IMU frames' density, an interval clear of zero; the IMU context did nothing for the log-mel frames').
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
CROSS_NEIGHBOURS = 2
"""Frames of the other modality on each side of the aligned one in a cross-modal context."""
BATCH = 1024
"""Frames per optimiser step."""
VAL_FRAMES = 100_000
"""Validation frames (the first ones) whose mean loss selects the epoch."""
_LOG_SCALE = (-5.0, 3.0)
_BLOCK = 256
"""Windows per block when scoring."""
_SIZE_FIELDS = ("p", "neighbours", "cross_p", "cross_neighbours")
"""The integer entries of `ContextNet.state` beside the weights."""


def aligned_context(other: torch.Tensor, steps: int, neighbours: int = CROSS_NEIGHBOURS) -> torch.Tensor:
    """(N, T_o, q) frames of another modality -> (N, steps, (2 k + 1) q): for each of `steps` frames t, the
    other modality's frames j(t) - k .. j(t) + k in time order, j(t) = floor((t + 1/2) T_o / steps) the one
    under t's centre (both modalities' frames span the same window), the window's edge frames repeated."""
    t_o = other.shape[1]
    t = torch.arange(steps, device=other.device, dtype=torch.float64)
    j = torch.floor((t + 0.5) * t_o / steps).long().clamp(0, t_o - 1)
    return torch.cat([other[:, (j + o).clamp(0, t_o - 1)] for o in range(-neighbours, neighbours + 1)], dim=2)


class ContextNet(nn.Module):
    """-log p(x_t | neighbours[, the other modality's frames around t]) of each frame; `fit_context_net`
    trains one, `nll` and `peak_distance` score (`cross`: the other modality's frames, when `cross_p` > 0)."""

    def __init__(
        self,
        p: int,
        neighbours: int = CONTEXT_NEIGHBOURS,
        cross_p: int = 0,
        cross_neighbours: int = CROSS_NEIGHBOURS,
    ) -> None:
        super().__init__()
        if cross_p < 0 or cross_neighbours < 0:
            raise ValueError(
                f"cross_p = {cross_p}, cross_neighbours = {cross_neighbours} are invalid; allowed: 0 or more"
            )
        self.p = p
        self.neighbours = neighbours
        self.cross_p = cross_p
        self.cross_neighbours = cross_neighbours
        q = len(_offsets(neighbours)) * p + (2 * cross_neighbours + 1) * cross_p
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

    def contexts(self, frames: torch.Tensor, cross: torch.Tensor | None = None) -> torch.Tensor:
        """(N, T, p) window frames [and (N, T_o, cross_p) the other modality's] -> (N, T, q) float32 raw
        contexts: the neighbours (`neighbour_context`), then the aligned cross frames (`aligned_context`).

        Raises:
            ValueError: cross frames missing, given to a network without a cross context, or of another size.
        """
        x = frames.to(torch.float32)
        own = neighbour_context(x, self.neighbours)
        if self.cross_p == 0:
            if cross is not None:
                raise ValueError("this context network has no cross-modal context; cross frames were given")
            return own
        if cross is None or cross.shape[2] != self.cross_p:
            got = "none" if cross is None else f"{cross.shape[2]} values a frame"
            raise ValueError(f"this context network needs cross frames of {self.cross_p} values; got {got}")
        return torch.cat(
            [own, aligned_context(cross.to(torch.float32), x.shape[1], self.cross_neighbours)], 2
        )

    def window_nll(self, frames: torch.Tensor, cross: torch.Tensor | None = None) -> torch.Tensor:
        """(N, T, p) window frames [and (N, T_o, cross_p) cross frames] -> (N, T) float32 -log p(x_t | c_t)
        in one pass (`nll` runs it in blocks)."""
        x = frames.to(torch.float32)
        return self.frame_nll(self.contexts(x, cross), (x - self.center) @ self.whiten)

    def nll(self, frames: torch.Tensor, cross: torch.Tensor | None = None) -> torch.Tensor:
        """(N, T, p) window frames [and cross frames] -> (N, T) float64 -log p(x_t | c_t), in blocks of
        windows, no gradient."""
        blocks = frames.split(_BLOCK)
        crosses = [None] * len(blocks) if cross is None else list(cross.split(_BLOCK))
        with torch.inference_mode():
            out = [
                self.window_nll(block, c).to(torch.float64) for block, c in zip(blocks, crosses, strict=True)
            ]
        if not out:
            return torch.zeros(0, frames.shape[1], dtype=torch.float64, device=frames.device)
        return torch.cat(out)

    def peak_distance(self, frames: torch.Tensor, cross: torch.Tensor | None = None) -> torch.Tensor:
        """(N, T, p) window frames [and cross frames] -> (N,) float64 sqrt(2 (nll - floor)) of each window's
        least likely frame."""
        nll = self.nll(frames, cross).amax(dim=1)
        return (2.0 * (nll - self.floor).clamp_min(0.0)).sqrt()

    def state(self) -> dict[str, torch.Tensor]:
        """Tensors for saving (CPU): the weights, whitening, floor, frame sizes and neighbours."""
        state = {k: v.detach().cpu() for k, v in self.state_dict().items()}
        sizes = {k: torch.tensor(getattr(self, k)) for k in _SIZE_FIELDS}
        return {**state, **sizes}

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor], device: torch.device) -> ContextNet:
        """Inverse of `state` (a missing key: KeyError; a wrong shape: RuntimeError). A state saved before
        cross-modal contexts existed has none."""
        sizes = {k: int(state[k]) for k in _SIZE_FIELDS if k in state}
        net = cls(
            int(state["p"]),
            int(state["neighbours"]),
            **{k: v for k, v in sizes.items() if k.startswith("cross")},
        )
        net.load_state_dict({k: v for k, v in state.items() if k not in _SIZE_FIELDS})
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
    cross: tuple[torch.Tensor, torch.Tensor | None] | None = None,
) -> ContextNet:
    """The `ContextNet` of training windows' frames (N, T, p) on their device, trained as the module
    docstring says, the epoch chosen on `val_frames` (M, T, p) (None or empty: the last epoch). `cross`:
    the other modality's frames of the same training and validation windows, (N, T_o, q) and (M, T_o', q)
    (None when there is no validation), for a cross-modal context.

    Raises:
        ValueError: fewer than two training frames, or cross frames of other windows.
    """
    n, steps, p = frames.shape
    if n * steps < 2:
        raise ValueError(f"a context network needs at least 2 training frames, got {n * steps}")
    if cross is not None and len(cross[0]) != n:
        raise ValueError(f"cross frames of {len(cross[0])} windows for {n} training windows")
    device = frames.device
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        net = ContextNet(p, neighbours, cross_p=0 if cross is None else cross[0].shape[2]).to(device)
    center, whiten = _whitening(frames.reshape(-1, p))
    net.center.copy_(center)
    net.whiten.copy_(whiten)
    x = frames.to(torch.float32)
    train_cross = None if cross is None else cross[0].to(device)
    contexts = net.contexts(x, train_cross).reshape(n * steps, -1)
    targets = ((x - center) @ whiten).reshape(n * steps, p)
    val: tuple[torch.Tensor, torch.Tensor] | None = None
    if val_frames is not None and len(val_frames):
        v = val_frames.to(device, torch.float32)
        val_cross = None if cross is None else cross[1]
        if cross is not None and (val_cross is None or len(val_cross) != len(v)):
            raise ValueError("cross frames of the validation windows are missing or of other windows")
        val = (
            net.contexts(v, None if val_cross is None else val_cross.to(device)).reshape(
                -1, contexts.shape[1]
            )[:VAL_FRAMES],
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
    net.floor.fill_(float(net.nll(frames, train_cross).min()))
    return net
