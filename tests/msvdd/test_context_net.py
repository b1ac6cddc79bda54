"""`msvdd.context_net`: the learned density of a frame given its neighbours, against the exact conditional of
a Gaussian autoregressive process, a frame ordinary alone but out of place, and its own saved state."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from msvdd.context_net import ContextNet, fit_context_net

A, SIGMA = 0.9, 1.0
"""AR(1) coefficient and innovation scale of the test process x_t = A x_{t-1} + SIGMA e_t."""


def _ar_windows(n: int, steps: int, seed: int) -> torch.Tensor:
    """(n, steps, 1) windows of the stationary AR(1) process, each started from its stationary law."""
    rng = np.random.default_rng(seed)
    x = np.zeros((n, steps))
    x[:, 0] = rng.standard_normal(n) * SIGMA / math.sqrt(1 - A * A)
    for t in range(1, steps):
        x[:, t] = A * x[:, t - 1] + SIGMA * rng.standard_normal(n)
    return torch.from_numpy(x[:, :, None]).float()


@pytest.fixture(scope="module")
def ar_net() -> tuple[ContextNet, torch.Tensor]:
    """A network trained on 2000 windows of 30 AR(1) frames (validation: 300 more), with its training set."""
    train = _ar_windows(2000, 30, 0)
    return fit_context_net(train, _ar_windows(300, 30, 1), seed=0), train


def test_learns_the_exact_conditional_of_a_gaussian_process(ar_net: tuple[ContextNet, torch.Tensor]) -> None:
    # For AR(1), x_t given x_{t-2}, x_{t-1}, x_{t+1}, x_{t+2} depends on x_{t-1}, x_{t+1} only, Gaussian with
    # variance SIGMA^2 / (1 + A^2): the mean -log p of interior frames is that Gaussian's entropy. The network
    # scores the frame whitened by its stationary spread s (y = (x - m) / s), which shifts -log p by log s.
    net, train = ar_net
    test = _ar_windows(500, 30, 2)
    interior = net.nll(test)[:, 2:-2]
    s = float(train.reshape(-1).double().std())
    exact = 0.5 * math.log(2 * math.pi * math.e * SIGMA**2 / (1 + A * A)) - math.log(s)
    marginal = 0.5 * math.log(2 * math.pi * math.e)  # the whitened frame alone: a standard normal
    assert marginal - exact > 1.0  # the neighbours carry more than a nat
    assert abs(float(interior.mean()) - exact) < 0.05


def test_a_frame_out_of_place_scores_above_the_nominal_windows(
    ar_net: tuple[ContextNet, torch.Tensor],
) -> None:
    net, train = ar_net
    test = _ar_windows(200, 30, 3)
    spliced = test.clone()
    # Frame 15 of each window swapped with the same frame of another window: the same marginal law, so a
    # density of frames on their own cannot tell, but the frame no longer follows from its neighbours.
    spliced[:, 15] = test.roll(100, dims=0)[:, 15]
    # Windows whose new frame 15 lies more than 4.5 conditional standard deviations off its exact conditional
    # mean A (x_14 + x_16) / (1 + A^2): far out of place, though drawn from the same marginal law.
    mean = A * (test[:, 14] + test[:, 16]) / (1 + A * A)
    z = ((spliced[:, 15] - mean) / (SIGMA / math.sqrt(1 + A * A))).abs().squeeze(1)
    moved = z > 4.5
    assert moved.sum() > 20
    nominal = net.peak_distance(test)
    assert net.peak_distance(spliced)[moved].min() > torch.quantile(nominal, 0.95)
    assert net.peak_distance(train).min() >= 0.0 and float(net.nll(train).min()) == pytest.approx(
        float(net.floor)
    )


def test_same_seed_same_network_and_state_round_trip() -> None:
    train, val = _ar_windows(200, 20, 4), _ar_windows(50, 20, 5)
    net = fit_context_net(train, val, seed=7)
    again = fit_context_net(train, val, seed=7)
    other = fit_context_net(train, val, seed=8)
    state = net.state()
    assert all(torch.equal(v, again.state()[k]) for k, v in state.items())
    assert not torch.equal(state["encoder.0.weight"], other.state()["encoder.0.weight"])
    loaded = ContextNet.from_state(state, torch.device("cpu"))
    test = _ar_windows(20, 20, 6)
    assert torch.equal(loaded.nll(test), net.nll(test))
    assert loaded.peak_distance(test).dtype == torch.float64
    assert net.nll(test[:0]).shape == (0, 20)


def test_without_validation_frames_the_last_epoch_is_kept_and_bad_input_is_refused() -> None:
    train = _ar_windows(100, 20, 4)
    assert fit_context_net(train, None, seed=0).nll(train).isfinite().all()
    with pytest.raises(ValueError, match="at least 2 training frames, got 1"):
        fit_context_net(train[:1, :1], None, seed=0)
    with pytest.raises(KeyError):
        ContextNet.from_state({"p": torch.tensor(1)}, torch.device("cpu"))
