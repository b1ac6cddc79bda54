"""`msvdd.context_net`: the learned density of a frame given its neighbours, against the exact conditional of
a Gaussian autoregressive process, a frame ordinary alone but out of place, and its own saved state."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from msvdd.context_net import ContextNet, aligned_context, fit_context_net

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


NOISE = 0.1
"""Scale of the noise between a frame and the other modality's frame under it in the cross-modal tests."""


def _paired_windows(n: int, steps: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(x (n, steps, 1), other (n, 2 steps, 1)): the other modality runs at twice the frame rate with i.i.d.
    standard normal frames, and x_t = other_{2t+1} + NOISE e_t, the other's frame under t's centre."""
    rng = np.random.default_rng(seed)
    other = rng.standard_normal((n, 2 * steps, 1))
    x = other[:, 1::2] + NOISE * rng.standard_normal((n, steps, 1))
    return torch.from_numpy(x).float(), torch.from_numpy(other).float()


def test_aligned_context_picks_the_other_modalitys_frames_under_each_frame() -> None:
    other = torch.arange(10.0).reshape(1, 10, 1)
    # 4 frames over the other's 10: centres 0.5, 1.5, 2.5, 3.5 of 4 -> frames floor(1.25), floor(3.75), ...
    got = aligned_context(other, 4, neighbours=1)[0]
    assert got.tolist() == [[0, 1, 2], [2, 3, 4], [5, 6, 7], [7, 8, 9]]  # edges repeated
    assert aligned_context(other, 10, neighbours=0)[0, :, 0].tolist() == list(range(10))


def test_a_cross_modal_context_learns_the_exact_conditional() -> None:
    # x_t given the other modality is N(other_{2t+1}, NOISE^2); its own neighbours say nothing (independent).
    # Whitened by its spread s = sqrt(1 + NOISE^2), the mean -log p is that Gaussian's entropy minus log s.
    train, train_other = _paired_windows(1000, 20, 0)
    val, val_other = _paired_windows(200, 20, 1)
    net = fit_context_net(train, val, seed=0, cross=(train_other, val_other))
    own = fit_context_net(train, val, seed=0)
    test, test_other = _paired_windows(300, 20, 2)
    s = float(train.reshape(-1).double().std())
    exact = 0.5 * math.log(2 * math.pi * math.e * NOISE**2) - math.log(s)
    assert abs(float(net.nll(test, test_other).mean()) - exact) < 0.1
    assert float(own.nll(test).mean()) > exact + 2.0  # without the other modality: about the marginal
    # The frame that no longer matches the other modality's stands out; state round trip keeps the context.
    moved = test.clone()
    moved[:, 7] += 1.0  # 10 noise scales off
    nominal = net.peak_distance(test, test_other)
    assert net.peak_distance(moved, test_other).min() > torch.quantile(nominal, 0.95)
    loaded = ContextNet.from_state(net.state(), torch.device("cpu"))
    assert loaded.cross_p == 1 and torch.equal(loaded.nll(test, test_other), net.nll(test, test_other))


def test_cross_frames_are_checked_and_an_older_state_loads_without_them() -> None:
    train, other = _paired_windows(60, 10, 3)
    net = fit_context_net(train, None, seed=0, cross=(other, None))
    with pytest.raises(ValueError, match="needs cross frames of 1 values; got none"):
        net.nll(train)
    with pytest.raises(ValueError, match="needs cross frames of 1 values; got 2 values a frame"):
        net.nll(train, other.repeat(1, 1, 2))
    plain = fit_context_net(train, None, seed=0)
    with pytest.raises(ValueError, match="has no cross-modal context"):
        plain.nll(train, other)
    with pytest.raises(ValueError, match="cross frames of 59 windows for 60 training windows"):
        fit_context_net(train, None, seed=0, cross=(other[1:], None))
    with pytest.raises(ValueError, match="validation windows are missing"):
        fit_context_net(train, train[:5], seed=0, cross=(other, None))
    # A state saved before cross-modal contexts existed has no cross_* entries: it loads as a plain network.
    state = {k: v for k, v in plain.state().items() if not k.startswith("cross")}
    assert torch.equal(ContextNet.from_state(state, torch.device("cpu")).nll(train), plain.nll(train))
