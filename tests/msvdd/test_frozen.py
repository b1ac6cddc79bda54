"""`svdd_fit="frozen"`: mu and Sigma held fixed between estimates over the whole training split (the repaired
M-SVDD that `msvdd` trains). Analytic checks of the floor and the estimates' scale equivariance, and on the
toy task at the smoke scale: the schedule of the estimates, Sigma's rank, the bias-free network."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from msvdd.config import MSVDDConfig
from msvdd.contract import Windows
from msvdd.losses import effective_rank, floored_covariance
from msvdd.model import MSVDD, z_biases

FROZEN = {"svdd_fit": "frozen", "bias_free": True, "val_fraction": 0.0, "w": 1.0}
"""The fields `msvdd` sets that matter here (at the smoke budget no validation split is held out)."""


def test_floored_covariance_raises_only_the_small_eigenvalues() -> None:
    rotation, _ = torch.linalg.qr(
        torch.randn(4, 4, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    )
    lam = torch.tensor([8.0, 4.0, 1e-3, 0.0], dtype=torch.float64)
    cov = rotation @ torch.diag(lam) @ rotation.T
    floor = 0.05  # mean eigenvalue 3.00025: the floor is 0.1500125
    out = torch.linalg.eigvalsh(floored_covariance(cov, floor, eps=0.0)).flip(0)
    expected = torch.tensor([8.0, 4.0, floor * lam.mean(), floor * lam.mean()], dtype=torch.float64)
    torch.testing.assert_close(out, expected)
    # Condition number bounded by 1 / floor times the largest over the mean eigenvalue; eps adds eps I.
    ridge = torch.linalg.eigvalsh(floored_covariance(cov, floor, eps=0.5)).flip(0)
    torch.testing.assert_close(ridge, expected + 0.5)
    # Scale-equivariant: a^2 cov -> a^2 out (the floor is relative).
    scaled = torch.linalg.eigvalsh(floored_covariance(1e-6 * cov, floor, eps=0.0)).flip(0)
    torch.testing.assert_close(scaled, 1e-6 * expected)


def test_effective_rank_of_known_spectra() -> None:
    assert effective_rank(torch.full((5,), 2.0)) == pytest.approx(5.0)
    assert effective_rank(torch.tensor([3.0, 0.0, 0.0])) == pytest.approx(1.0)
    assert effective_rank(torch.tensor([2.0, 1.0, 1.0])) == pytest.approx(2**1.5)


def test_the_held_statistics_are_scale_equivariant() -> None:
    model = MSVDD(MSVDDConfig.smoke(**FROZEN))
    z = torch.randn(200, 8, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    z[:, 0] *= 30.0  # an anisotropic cloud
    mu, raw, sigma = model._robust_statistics(z, seed=3)
    a = 1e-4
    mu_a, raw_a, sigma_a = model._robust_statistics(a * z, seed=3)
    torch.testing.assert_close(mu_a, a * mu)
    torch.testing.assert_close(raw_a, a * a * raw)
    torch.testing.assert_close(sigma_a, a * a * sigma)
    with pytest.raises(ValueError, match="do not spread"):
        model._robust_statistics(torch.ones(50, 8, dtype=torch.float64), seed=0)


def test_the_estimates_follow_the_schedule_and_are_held_in_between(
    toy_train: Windows, monkeypatch: pytest.MonkeyPatch
) -> None:
    # 128 windows, batches of 32: 4 steps per epoch. Warm-up 1 epoch, then an estimate every 2 epochs: after
    # 1 and 3 epochs trained (none after the last, the 5th), and the final one after training.
    cfg = MSVDDConfig.smoke(epochs=5, stats_warmup=1, stats_every=2, **FROZEN)
    model = MSVDD(cfg)

    def no_batch_mcd(*args: object, **kwargs: object) -> None:
        raise AssertionError("the frozen fit never estimates mu and Sigma on a batch")

    monkeypatch.setattr("msvdd.model.batch_statistics", no_batch_mcd)
    held: list[object] = []
    svdd: list[float] = []
    loss = model._frozen_loss_terms

    def spy(*args: torch.Tensor) -> object:
        held.append(model._held)
        terms = loss(*args)  # type: ignore[arg-type]
        svdd.append(float(terms.svdd.detach()))
        return terms

    monkeypatch.setattr(model, "_frozen_loss_terms", spy)
    model.fit(toy_train)
    assert [f.epoch for f in model.stats_fits_] == [1, 3, -1]
    assert model.history_ is not None and model.history_.epochs["stats_fit"] == [1.0, 0.0, 1.0, 0.0, 0.0]
    # The held statistics change exactly at the scheduled estimates: none in the warm-up (whose loss is the
    # reconstruction alone), one for epochs 1-2, the next for epochs 3-4.
    assert held[:4] == [None] * 4 and svdd[:4] == [0.0] * 4
    first, second = held[4], held[12]
    assert first is not None and second is not None and first is not second
    assert all(h is first for h in held[4:12]) and all(h is second for h in held[12:20]) and len(held) == 20
    assert all(v > 0 for v in svdd[4:])
    # The last epoch is kept (validation losses under different statistics do not compare).
    assert model.history_.best_epoch == cfg.epochs - 1 and model.history_.val_loss == []


def test_sigma_keeps_full_rank(toy_train: Windows) -> None:
    cfg = MSVDDConfig.smoke(epochs=6, stats_warmup=1, stats_every=2, **FROZEN)
    model = MSVDD(cfg).fit(toy_train)
    assert model.sigma_ is not None and model.sigma_raw_ is not None
    s = cfg.s
    lam = torch.linalg.eigvalsh(model.sigma_)
    assert int(torch.linalg.matrix_rank(model.sigma_)) == s
    # The floor bounds the condition number: lambda_min >= floor * mean(raw eigenvalues).
    raw = torch.linalg.eigvalsh(model.sigma_raw_)
    assert float(lam.min()) >= cfg.variance_floor * float(raw.clamp_min(0).mean()) * (1 - 1e-9)
    assert int(torch.linalg.matrix_rank(model.sigma_raw_)) == s
    # No estimate loses rank against the first: the effective rank of the raw estimate stays.
    ranks = [f.effective_rank for f in model.stats_fits_]
    assert len(ranks) == 4 and min(ranks) >= 0.5 * ranks[0]
    assert model.history_ is not None
    history_ranks = model.history_.epochs["stats_effective_rank"]
    # The history's figure of epoch e (0-based) is the estimate held after it: the first after epoch 0.
    assert history_ranks[0] == history_ranks[1] == pytest.approx(ranks[0])
    assert history_ranks[2] == pytest.approx(ranks[1])


def test_bias_free_network_maps_zero_to_zero(toy_train: Windows) -> None:
    model = MSVDD(MSVDDConfig.smoke(epochs=2, **FROZEN)).fit(toy_train)
    biases = z_biases(model.module.net)
    assert biases and all(not b.requires_grad and float(b.abs().max()) == 0.0 for b in biases)
    audio, imu = model._tensors(toy_train.subset(slice(0, 2)))
    with torch.inference_mode():
        zero = model.module.net(torch.zeros_like(audio), torch.zeros_like(imu)).z
        assert float(zero.abs().max()) == 0.0  # no constant z but 0 is reachable: no trivial solution
        with_bias = MSVDD(MSVDDConfig.smoke(epochs=1)).module.net(
            torch.zeros_like(audio), torch.zeros_like(imu)
        )
        assert float(with_bias.z.abs().max()) > 0.0
    # The decoders keep their biases.
    assert model.module.net.imu_decoder is not None and model.module.net.imu_decoder.out.bias.requires_grad


def test_euclidean_frozen_fixes_the_centre_once(toy_train: Windows, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = MSVDDConfig.smoke(epochs=4, stats_warmup=1, stats_every=1, use_mahalanobis=False, **FROZEN)
    model = MSVDD(cfg)
    centres: list[torch.Tensor] = []
    set_center = model._set_center

    def spy(z: torch.Tensor) -> None:
        set_center(z)
        centres.append(model.module.center.clone())

    monkeypatch.setattr(model, "_set_center", spy)
    model.fit(toy_train)
    assert len(centres) == 1 and model.stats_fits_ == []  # Deep SVDD: c after the warm-up, then fixed
    assert model.mu_ is not None
    torch.testing.assert_close(model.mu_, centres[0].to(torch.float64))
    torch.testing.assert_close(model.sigma_, torch.eye(cfg.s, dtype=torch.float64))


def test_score_is_d_plus_the_weighted_reconstruction_of_the_own_decoders(
    toy_train: Windows, toy_test: tuple[Windows, np.ndarray]
) -> None:
    model = MSVDD(MSVDDConfig.smoke(epochs=2, **FROZEN)).fit(toy_train)
    batch = toy_test[0]
    d, rec = model.score_components(batch)
    # Rec is the decoders' mean Huber error per modality, summed (no frame densities anywhere).
    assert model.frame_density_ is None and model.has_term
    audio, imu = model._tensors(batch)
    with torch.inference_mode():
        out = model.module.net(audio, imu)
        parts = [p.to(torch.float64).numpy() for p in model.rec_parts(out, audio, imu)]
    np.testing.assert_allclose(rec, np.sum(parts, axis=0), rtol=1e-6)
    ratio = model.mean_d_ / model.mean_rec_
    np.testing.assert_allclose(model.score(batch), d + model.config.w * ratio * rec, rtol=1e-12)
    # Without reconstruction there are no decoders and the score is D.
    bare = MSVDD(dataclasses.replace(model.config, use_reconstruction=False)).fit(toy_train)
    assert bare.module.net.audio_decoder is None and bare.module.net.imu_decoder is None
    np.testing.assert_array_equal(bare.score(batch), bare.score_components(batch)[0])
