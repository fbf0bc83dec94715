"""Noise schedule: closed forms, the textbook reverse step, strided sequences, DDIM."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.modules import NoiseSchedule


def test_linear_schedule_closed_forms():
    schedule = NoiseSchedule(1000)
    assert schedule.betas[0].item() == pytest.approx(1e-4)
    assert schedule.betas[-1].item() == pytest.approx(0.02)
    expected = 1.0
    for t in (0, 1, 10, 500, 999):
        expected = math.prod(1 - (1e-4 + (0.02 - 1e-4) * s / 999) for s in range(t + 1))
        assert schedule.alpha_bar[t].item() == pytest.approx(expected, rel=1e-10)
    var = schedule.posterior_variance()
    t = 500
    closed = schedule.betas[t] * (1 - schedule.alpha_bar[t - 1]) / (1 - schedule.alpha_bar[t])
    assert var[t].item() == pytest.approx(closed.item(), rel=1e-12)
    assert var[0].item() == 0.0


def test_cosine_schedule_closed_form():
    """Nichol & Dhariwal (2021), eq. 17: abar_t = f(t) / f(0), f(t) = cos^2((t/T + s)/(1 + s)
    pi/2), s = 0.008, with beta_t = 1 - abar_t / abar_{t-1} clipped at 0.999. Our index t
    (0-based) is their t + 1 (the first training step already adds noise)."""
    T, s = 1000, 0.008
    schedule = NoiseSchedule(T, "cosine")
    f = lambda t: math.cos((t / T + s) / (1 + s) * math.pi / 2) ** 2  # noqa: E731
    for t in (0, 1, 10, 250, 500, 900, 990):
        assert schedule.alpha_bar[t].item() == pytest.approx(f(t + 1) / f(0), rel=1e-9)
        beta = min(1 - f(t + 1) / f(t), 0.999)
        assert schedule.betas[t].item() == pytest.approx(beta, rel=1e-9)
    assert schedule.betas.max().item() == pytest.approx(0.999)  # the clip is reached at t = T-1
    abar = schedule.alpha_bar
    assert (abar[1:] < abar[:-1]).all() and abar[-1] < 1e-3 and abar[0] > 0.99


def test_strided_timesteps():
    schedule = NoiseSchedule(1000)
    steps = schedule.timesteps(50)
    gaps = steps[:-1] - steps[1:]
    assert steps[0] == 999 and steps[-1] == 0 and len(set(steps.tolist())) == 50
    assert gaps.min() >= 20 and gaps.max() <= 21  # evenly spaced, ending at t = 0
    assert schedule.timesteps(1000).tolist() == list(range(999, -1, -1))
    for bad in (0, 1001, 2.5):
        with pytest.raises(ValueError, match="num_inference_steps"):
            schedule.timesteps(bad)


def test_full_ddpm_step_equals_the_textbook_reverse_step():
    """With every step visited, the strided step is eq. 10: x_{t-1} = (x_t - beta_t /
    sqrt(1 - abar_t) eps) / sqrt(alpha_t) + sigma_t z, sigma_t^2 the posterior variance."""
    schedule = NoiseSchedule(100)
    g = torch.Generator().manual_seed(0)
    x = torch.randn(64, 3, generator=g, dtype=torch.float64)
    var = schedule.posterior_variance()
    for t in (99, 50, 1):
        eps = torch.randn(64, 3, generator=g, dtype=torch.float64)
        z = torch.randn(64, 3, generator=g, dtype=torch.float64)
        ours = schedule.step(x, eps, t, t - 1, noise=z, clip=False)
        beta, alpha, abar = schedule.betas[t], schedule.alphas[t], schedule.alpha_bar[t]
        textbook = (x - beta / (1 - abar).sqrt() * eps) / alpha.sqrt() + var[t].sqrt() * z
        torch.testing.assert_close(ours, textbook, rtol=1e-10, atol=1e-10)
    final = schedule.step(x, eps, 0, -1, clip=False)  # the last step adds no noise
    torch.testing.assert_close(final, schedule.predict_x0(x, eps, 0, clip=False))


def test_ddim_with_the_true_noise_lands_on_the_forward_process():
    schedule = NoiseSchedule(1000)
    g = torch.Generator().manual_seed(1)
    x0 = torch.rand(32, 2, generator=g, dtype=torch.float64) * 1.6 - 0.8
    eps = torch.randn(32, 2, generator=g, dtype=torch.float64)
    t, s = 700, 300
    x_t = schedule.add_noise(x0, eps, torch.full((32,), t))
    x_s = schedule.step(x_t, eps, t, s, sampler="ddim")
    torch.testing.assert_close(x_s, schedule.add_noise(x0, eps, torch.full((32,), s)))


def test_predicted_clean_sample_is_clipped_to_the_bounds():
    schedule = NoiseSchedule(1000)
    x = torch.full((4, 2), 5.0)
    assert schedule.predict_x0(x, torch.zeros(4, 2), 10).abs().max() <= 1.0
    out = schedule.step(x, torch.zeros(4, 2), 10, -1)
    assert out.abs().max() <= 1.0


def test_bad_input():
    with pytest.raises(ValueError, match="kind"):
        NoiseSchedule(10, "quadratic")
    with pytest.raises(ValueError, match="num_train_steps"):
        NoiseSchedule(0)
    with pytest.raises(ValueError, match="sampler"):
        NoiseSchedule(10).step(torch.zeros(2), torch.zeros(2), 5, 3, sampler="euler")
