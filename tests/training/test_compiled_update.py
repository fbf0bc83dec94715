"""The compiled update (``optim.compile``): the same gradient steps as the eager one."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf

from torchrl_auv import training


def _lac_learner(env, compile_update: bool) -> training.Learner:
    torch.manual_seed(0)
    actor, critic = training.make_actor(env, (16,)), training.make_lyapunov_critic(env, (16,))
    optim = {
        "gamma": 0.97,
        "lambda_max": 1.0,
        "loss_function": "smooth_l1",
        "tau": 0.05,
        "actor_lr": 1e-3,
        "critic_lr": 1e-3,
        "dual_lr": 1e-3,
        "compile": compile_update,
    }
    cfg = OmegaConf.create(
        {
            "optim": optim,
            "lyapunov": {"form": "softplus", "stability_weight": 0.1, "cost": "stability"},
            "network": {"hidden": [16]},
        }
    )
    return training.lac_from_config(cfg, env, actor, critic)


def test_the_compile_switch_reaches_the_learners():
    """``optim.compile`` (a recipe key, absent: off) reaches the LAC and SAC learners, and a
    value that is not a boolean is refused naming the key (nothing compiles here)."""
    env = training.make_env("ideal", seed=0, num_envs=1, max_steps=5)
    assert _lac_learner(env, False).compile is False
    assert _lac_learner(env, True).compile is True
    sac_optim = {
        "gamma": 0.99,
        "alpha_init": 1.0,
        "tau": 0.005,
        "loss_function": "smooth_l1",
        "actor_lr": 1e-3,
        "critic_lr": 1e-3,
        "alpha_lr": 1e-3,
    }
    cfg = OmegaConf.create({"optim": sac_optim, "network": {"hidden": [8]}, "device": "cpu"})
    actor = training.make_actor(env, (8,))
    assert training.sac_from_config(cfg, env, actor).compile is False
    cfg.optim.compile = True
    assert training.sac_from_config(cfg, env, actor).compile is True
    with pytest.raises(ValueError, match=r"optim\.compile"):
        training.check_choices({"optim": {"compile": "yes"}})


@pytest.mark.slow
def test_compiled_lac_updates_equal_the_eager_ones():
    """Three LAC updates (Lyapunov and task critics, actor, duals, target networks) compiled
    and eager from the same weights and batches, with inductor drawing eager torch's random
    numbers (``fallback_random``): the same losses and weights to float32 rounding."""
    import torch._inductor.config as inductor_config

    env = training.make_env("ideal", seed=0, num_envs=2, max_steps=20)
    data = training.select_for_replay(env.rollout(12).reshape(-1))
    eager, compiled = _lac_learner(env, False), _lac_learner(env, True)
    with inductor_config.patch(fallback_random=True):
        for step in range(3):
            batch = data[4 * step : 4 * step + 8]
            torch.manual_seed(step)
            out_eager = eager.step(batch.clone())
            torch.manual_seed(step)
            out_compiled = compiled.step(batch.clone())
            for key in ("loss_actor", "loss_lyapunov", "loss_qvalue", "lambda", "beta"):
                torch.testing.assert_close(
                    out_compiled[key], out_eager[key], rtol=1e-5, atol=1e-6, msg=key
                )
    params = dict(eager.loss.named_parameters())
    for name, value in compiled.loss.named_parameters():
        torch.testing.assert_close(value, params[name], rtol=1e-5, atol=1e-6, msg=name)
    targets = eager.loss.target_lyapunov_network_params.values(True, True)
    for a, b in zip(
        compiled.loss.target_lyapunov_network_params.values(True, True), targets, strict=True
    ):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)
