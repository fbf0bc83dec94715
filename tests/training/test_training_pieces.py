"""torchrl_auv.training: config checks, replay selection, checkpoint state, selection wiring."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf
from tensordict import TensorDict

from torchrl_auv import training
from torchrl_auv.advisor import AdvisorTrigger, RuleBasedAdvisor
from torchrl_auv.objectives import LyapunovSpec, LyapunovSpecState


@pytest.mark.parametrize(
    ("cfg", "named"),
    [
        ({"env": {"sea_state": "calm"}}, "env.sea_state"),
        ({"env": {"controller": "lqr"}}, "env.controller"),
        ({"env": {"rate_model": "fast"}}, "env.rate_model"),
        ({"collector": {"backend": "slurm"}}, "collector.backend"),
        ({"collector": {"total_frames": 0}}, "collector.total_frames"),
        ({"collector": {"num_workers": 0}}, "collector.num_workers"),
        ({"advisor": {"backend": "oracle"}}, "advisor.backend"),
        ({"lyapunov": {"form": "cubic"}}, "lyapunov.form"),
        (
            {"lyapunov": {"stability_weight": 0}},
            "lyapunov.stability_weight must be a finite number > 0",
        ),
        ({"replay_buffer": {"storage": "disk"}}, "replay_buffer.storage"),
        ({"eval": {"sea_states": ["ideal", "storm"]}}, "eval.sea_states"),
        ({"proposer": {"alone_replan_every": 0}}, "proposer.alone_replan_every"),
        ({"proposer": {"alone_replan_every": 9, "horizon": 8}}, "proposer.alone_replan_every"),
        ({"selection": {"include_actor": "yes"}}, "selection.include_actor"),
        ({"optim": {"loss_function": "l1"}}, "optim.loss_function"),
        ({"lyapunov": {"cost": "energy"}}, "lyapunov.cost"),
        ({"logger": {"backend": "wandbb"}}, "logger.backend"),
        ({"optim": {"updates_per_batch": 0}}, "optim.updates_per_batch"),
        ({"network": {"critics": 0}}, "network.critics"),
        ({"network": {"layer_norm": "yes"}}, "network.layer_norm"),
        ({"optim": {"multiplier": "adam"}}, "optim.multiplier"),
        ({"optim": {"critic_cost": "energy"}}, "optim.critic_cost"),
        ({"optim": {"constraint": "quantile"}}, "optim.constraint"),
        ({"optim": {"pid_gains": [1.0, -0.1, 0.0]}}, "optim.pid_gains"),
        ({"optim": {"pid_gains": [1.0, 0.1]}}, "optim.pid_gains"),
        ({"optim": {"multiplier": "dual", "lambda_init": 0.0}}, "optim.lambda_init"),
        ({"optim": {"lambda_init": 5.0, "lambda_max": 1.0}}, "optim.lambda_init"),
        ({"lyapunov": {"legs": True, "cost": "task"}}, "lyapunov.legs"),
        ({"lyapunov": {"filter": "rank", "cost": "task"}}, "lyapunov.cost"),
        (
            {"lyapunov": {"filter": "rank"}, "selection": {"backup": "actor"}},
            "selection.backup",
        ),
        ({"lyapunov": {"filter": "rank"}, "residual": {"bound": 0.2}}, "residual.bound"),
        ({"lyapunov": {"filter": "on"}}, "lyapunov.filter"),
        ({"lyapunov": {"filter": "veto"}, "selection": {"anchor": None}}, "selection.anchor"),
        ({"lyapunov": {"inputs": "vehicle"}}, "lyapunov.inputs"),
        ({"advisor": {"forms": ["softplus", "cubic"]}}, "advisor.forms"),
        ({"advisor": {"forms": []}}, "advisor.forms"),
        ({"optim": {"violation_budget": 1.0}}, "optim.violation_budget"),
        (
            {"optim": {"violation_budget": 0.05, "multiplier": "dual"}},
            "optim.violation_budget",
        ),
        ({"lyapunov": {"gamma": 1.5}}, "lyapunov.gamma"),
        ({"lyapunov": {"gamma": 0}}, "lyapunov.gamma"),
        ({"lyapunov": {"gamma": True}}, "lyapunov.gamma"),
    ],
)
def test_check_choices_names_the_key(cfg, named):
    with pytest.raises(ValueError, match=named.replace(".", r"\.")):
        training.check_choices(cfg)


def test_check_choices_accepts_the_recipe_defaults():
    training.check_choices(
        {
            "env": {"sea_state": "ves", "controller": "pid", "rate_model": "paper"},
            "collector": {"total_frames": 10, "num_workers": 2, "backend": "local"},
            "device": "cpu",
        }
    )


def test_a_run_shorter_than_its_random_warm_up_is_said_before_it_starts():
    with pytest.warns(
        UserWarning,
        match=r"collector\.total_frames \(200\) <= "
        r"collector\.init_random_frames \(400\).*no gradient update",
    ):
        training.check_choices({"collector": {"total_frames": 200, "init_random_frames": 400}})


def test_the_replay_buffer_stores_only_what_the_losses_read():
    env = training.make_env("ideal", seed=0, num_envs=2)
    rollout = env.rollout(3)
    stored = training.select_for_replay(rollout)
    assert stored.batch_size == (6,)
    assert set(stored.keys(True, True)) == set(training.REPLAY_KEYS)
    # 2 AUVs: obs 38 + 38 (next) + action 3 + reward, cost, stability cost float32; done,
    # terminated bool
    expected = 2 * ((38 + 38 + 3 + 1 + 1 + 1) * 4 + 2 * 1)
    assert training.bytes_per_frame(stored[0]) == expected
    whole = sum(t.numel() * t.element_size() for t in rollout[0, 0].values(True, True))
    assert whole > 20 * expected  # the env's tensordict carries the simulator state


def test_spec_and_advisor_state_survive_a_checkpoint(tmp_path):
    class Loss(torch.nn.Module):  # anything holding the spec as a LyapunovSpecState
        def __init__(self):
            super().__init__()
            self.spec_state = LyapunovSpecState()

        def set_lyapunov_spec(self, spec):
            self.spec_state.spec = spec

    loss = Loss()
    trigger = AdvisorTrigger(RuleBasedAdvisor(), "task", log_path=tmp_path / "a.jsonl")
    progress = training.Progress()
    modules = {"loss": loss, "advisor": trigger}
    ckpt, rotation = training.make_checkpoint(tmp_path, modules=modules, progress=progress)
    loss.set_lyapunov_spec(LyapunovSpec(form="log", alpha=0.05))
    trigger.load_state_dict({"last_frame": 300})
    progress.frames = 400
    rotation.save(ckpt, step=400)

    fresh_loss = Loss()
    fresh = AdvisorTrigger(RuleBasedAdvisor(), "task", log_path=tmp_path / "b.jsonl")
    fresh_progress = training.Progress()
    ckpt2, _ = training.make_checkpoint(
        tmp_path,
        modules={"loss": fresh_loss, "advisor": fresh},
        progress=fresh_progress,
    )
    assert training.resume_latest(tmp_path, ckpt2, fresh_progress)[0] == 400
    assert (fresh_loss.spec_state.spec.form, fresh_loss.spec_state.spec.alpha) == ("log", 0.05)
    # the cooldown runs on from the restored consultation frame: no "start" consultation
    assert fresh.reason(400, None) is None and fresh.state_dict()["last_frame"] == 300


def test_the_loss_owns_the_spec_the_selector_and_a_resumed_run_follow(tmp_path):
    env = training.make_history_env("ideal", history=2, seed=0, num_envs=1, max_steps=5)
    from torchrl_auv.modules import DiffusionProposer

    proposer = DiffusionProposer.for_env(env, num_candidates=2, horizon=2, num_inference_steps=2)
    critic = training.make_lyapunov_critic(env, (8,))
    loss = training.make_lac_loss(training.make_actor(env, (8,)), critic, env)
    policy = training.make_selection_policy(
        proposer, critic, mode="lyapunov", loss=loss, critic_out_key=training.LYAPUNOV_RAW
    )
    selector = policy[-1]
    assert selector.spec == loss.spec and selector.spec_state is loss.spec_state
    loss.set_lyapunov_spec(LyapunovSpec(form="squared", alpha=0.25))  # an advisor's step
    assert (selector.spec.form, selector.spec.alpha) == ("squared", 0.25)
    # the buffer the workers receive with the weights
    assert "spec_state.code" in dict(selector.named_buffers())
    assert selector.state_dict()["spec_state.code"][0] != 0
    progress = training.Progress()
    ckpt, rotation = training.make_checkpoint(tmp_path, modules={"loss": loss}, progress=progress)
    rotation.save(ckpt, step=0)
    loss.set_lyapunov_spec(LyapunovSpec(form="log", alpha=0.5))
    training.resume_latest(tmp_path, ckpt, progress)
    assert (selector.spec.form, selector.spec.alpha) == ("squared", 0.25)  # back with the loss
    with pytest.raises(ValueError, match="spec must be a LyapunovSpec"):
        loss.spec = "squared"
    with pytest.raises(ValueError, match="needs mode='lyapunov'"):
        training.make_selection_policy(
            proposer, critic, mode="q", loss=loss, critic_out_key=training.LYAPUNOV_RAW
        )


def test_feedback_batch_puts_time_second_last_per_auv():
    obs = torch.arange(2 * 5 * 3 * 37, dtype=torch.float32).reshape(2, 5, 3, 37)
    data = TensorDict(
        {("agents", "observation"): obs, ("next", "agents", "reward"): torch.zeros(2, 5, 3, 1)},
        [2, 5],
    )
    fb = training.feedback_batch(data)
    assert fb["observation"].shape == (2, 3, 5, 37) and fb.batch_size == (2, 3, 5)
    torch.testing.assert_close(fb["observation"][1, 2, 4], obs[1, 4, 2])


def test_ranked_candidates_and_the_live_lyapunov_critic():
    env = training.make_history_env("ideal", history=2, seed=0, num_envs=2, max_steps=20)
    from torchrl_auv.modules import DiffusionProposer

    proposer = DiffusionProposer.for_env(env, num_candidates=3, horizon=2, num_inference_steps=2)
    actor = training.make_actor(env, (16,))
    critic = training.make_lyapunov_critic(env, (16,))
    loss = training.make_lac_loss(actor, critic, env)
    policy = training.make_selection_policy(
        proposer,
        critic,
        mode="lyapunov",
        actor=actor,
        critic_out_key=training.LYAPUNOV_RAW,
        loss=loss,
    )
    td = policy(env.reset())
    scores, ranking = td["agents", "selector", "scores"], td["agents", "selector", "ranking"]
    assert scores.shape[-1] == 4  # K = 3 candidates and the actor's own action
    # each rank executes the candidate of that place in the ranking (scores sorted, best first)
    ordered = scores.gather(-1, ranking)
    assert (ordered[..., :-1] >= ordered[..., 1:]).all()
    for rank in (0, 3):
        torch.manual_seed(1)
        out = training.RankedCandidate(policy, rank)(env.reset())
        first = torch.cat(
            [out["agents", "proposer", "first_actions"], out[training.ACTOR_ACTION].unsqueeze(-2)],
            -2,
        )
        index = out["agents", "selector", "ranking"][..., rank]
        chosen = first.gather(-2, index[..., None, None].expand(2, 2, 1, 3))[..., 0, :]
        torch.testing.assert_close(out["agents", "action"], chosen)
    # the selector scores with the critic the loss trains (shared parameters, no copy)
    obs = td["agents", "observation"]
    before = policy[-1].scores(obs, td["agents", "proposer", "first_actions"]).clone()
    with torch.no_grad():
        for p in loss.lyapunov_network_params.values(True, True):
            p.add_(0.5)
    after = policy[-1].scores(obs, td["agents", "proposer", "first_actions"])
    assert not torch.allclose(before, after)


def test_without_the_actor_the_selection_set_is_the_k_candidates():
    env = training.make_history_env("ideal", history=2, seed=0, num_envs=2, max_steps=20)
    from torchrl_auv.modules import DiffusionProposer

    proposer = DiffusionProposer.for_env(env, num_candidates=3, horizon=2, num_inference_steps=2)
    actor = training.make_actor(env, (16,))
    critic = training.make_lyapunov_critic(env, (16,))
    loss = training.make_lac_loss(actor, critic, env)
    policy = training.make_selection_policy(
        proposer,
        critic,
        mode="lyapunov",
        actor=None,
        critic_out_key=training.LYAPUNOV_RAW,
        loss=loss,
    )
    td = policy(env.reset())
    assert td["agents", "selector", "scores"].shape[-1] == 3
    assert training.ACTOR_ACTION not in td.keys(True, True)
    rows = training.evaluation_policies("diffusion_lac", policy, actor, proposer)
    assert {"OA", "CA1", "CA2", "RL", "proposer alone"} <= set(rows) and "CA3" not in rows
    rows = training.evaluation_policies("diffusion_lac", policy, actor, proposer, ranks=False)
    assert set(rows) == {"diffusion_lac", "RL", "proposer alone"}


def test_batch_metrics_log_the_share_of_each_selection_slot():
    index = torch.tensor([[[0, 3], [3, 3]], [[1, 3], [0, 2]]])  # [B=2, T=2, N=2], slots 0..3
    selector = {"index": index, "scores": torch.zeros(2, 2, 2, 4)}
    step = {
        "agents": {"cost": torch.ones(2, 2, 2, 1)},
        "done": torch.zeros(2, 2, 1, dtype=torch.bool),
    }
    data = TensorDict({"agents": {"selector": selector}, "next": step}, [2, 2])
    out = training.batch_metrics(data)
    shares = [out[f"train/selected_rank_{i}"] for i in range(4)]
    assert shares == [2 / 8, 1 / 8, 1 / 8, 4 / 8]
    del data["agents", "selector"]
    assert not any(k.startswith("train/selected_rank") for k in training.batch_metrics(data))


def test_batch_metrics_log_which_side_of_the_candidates_the_executed_action_lies_on():
    # 4 AUV-decisions, K = 3 candidates of 2 action dimensions; the executed action is in
    # dimension 0 the largest, the largest, the smallest, the middle one; in dimension 1 the
    # largest each time (a selection that always turns one way)
    first = torch.tensor([[0.0, 1.0], [0.5, 2.0], [-0.5, 3.0]]).expand(2, 2, 3, 2)
    executed = torch.tensor([[[0.5, 3.0], [0.5, 3.0]], [[-0.5, 3.0], [0.0, 3.0]]])
    step = {"agents": {"cost": torch.ones(2, 2, 1)}, "done": torch.zeros(2, 1, dtype=torch.bool)}
    data = TensorDict(
        {"agents": {"proposer": {"first_actions": first}, "action": executed}, "next": step}, [2]
    )
    out = training.batch_metrics(data)
    assert out["train/selected_side_0"] == (1 + 1 - 1 + 0) / 4
    assert out["train/selected_side_1"] == 1.0
    assert out["train/selected_extreme_0"] == 3 / 4 and out["train/selected_extreme_1"] == 1.0
    # drawn at random among exchangeable candidates, the side averages out near 0
    gen = torch.Generator().manual_seed(0)
    first = torch.randn(4000, 2, 5, 3, generator=gen)
    pick = torch.randint(0, 5, (4000, 2, 1, 1), generator=gen).expand(4000, 2, 1, 3)
    step = {
        "agents": {"cost": torch.ones(4000, 2, 1)},
        "done": torch.zeros(4000, 1, dtype=torch.bool),
    }
    data = TensorDict(
        {
            "agents": {
                "proposer": {"first_actions": first},
                "action": first.gather(-2, pick).squeeze(-2),
            },
            "next": step,
        },
        [4000],
    )
    out = training.batch_metrics(data)
    sides = [out[f"train/selected_side_{d}"] for d in range(3)]
    assert all(abs(side) < 0.03 for side in sides), sides
    extremes = [out[f"train/selected_extreme_{d}"] for d in range(3)]
    assert all(abs(extreme - 2 / 5) < 0.03 for extreme in extremes), extremes
    del data["agents", "proposer"]
    assert not any(k.startswith("train/selected_side") for k in training.batch_metrics(data))


def test_evaluation_rows_repeat_on_the_same_seed_whatever_the_global_rng():
    def make(sea, seed):
        return training.make_env(sea, seed=seed, num_envs=2, max_steps=15)

    rows = []
    for noise in (0, 1):
        torch.manual_seed(noise)  # a different global state before each evaluation
        rows.append(
            training.evaluate(make, {"random": lambda env: None}, ["ideal"], seed=5, steps=15)
        )
    assert rows[0] == rows[1]
    other = training.evaluate(make, {"random": lambda env: None}, ["ideal"], seed=6, steps=15)
    assert other[0]["cost_mean"] != rows[0][0]["cost_mean"]


def test_evaluation_shows_its_progress_per_decision(capsys):
    def make(sea, seed):
        return training.make_env(sea, seed=seed, num_envs=1, max_steps=6)

    training.evaluate(
        make,
        {"random": lambda env: None, "expert": training.reference_policies()["expert"]},
        ["ideal"],
        seed=5,
        steps=6,
        progress=True,
    )
    err = capsys.readouterr().err
    assert "12/12" in err and "ideal expert" in err
    training.evaluate(make, {"random": lambda env: None}, ["ideal"], seed=5, steps=6)
    assert "evaluation" not in capsys.readouterr().err  # off by default


def test_compile_switches_reach_the_env_and_the_proposer(tmp_path):
    """``env.compile_physics`` and ``proposer.compile`` (recipe keys) switch the compiled
    paths on; without the keys both stay eager (nothing compiles here: no step is taken)."""
    from omegaconf import OmegaConf

    from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES
    from torchrl_auv.modules import DiffusionProposer

    env_cfg = {
        "sea_state": "ideal",
        "num_envs": 1,
        "controller": "pid",
        "rate_model": "shannon",
        "max_steps": 10,
    }
    cfg = OmegaConf.create({"seed": 0, "device": "cpu", "env": env_cfg})
    assert training.env_from_config(cfg).vehicles.compile is False
    cfg.env.compile_physics = True
    assert training.env_from_config(cfg).vehicles.compile is True
    cfg.eval = {"num_envs": 1, "steps": 5}
    held_out = training.held_out_env(cfg, 1, 5)
    assert held_out("ideal", 100000).vehicles.compile is True  # evaluation compiles too
    cfg.env.compile_physics = False
    assert training.held_out_env(cfg, 1, 5)("ideal", 100000).vehicles.compile is False

    path = tmp_path / "proposer.pt"
    obs = len(AGENT_OBSERVATION_FEATURES)  # history 0: the observation alone
    DiffusionProposer(obs, 3, num_candidates=2, horizon=2, num_inference_steps=2).save(path)
    proposer_cfg = {
        "path": str(path),
        "demo_episodes": 1,
        "demo_steps": 1,
        "pretrain_steps": 1,
        "batch_size": 1,
        "lr": 1e-3,
        "num_candidates": 2,
        "horizon": 2,
        "history": 0,
        "num_inference_steps": 2,
        "sampler": "ddim",
        "hidden": 8,
        "demo_sea_state": "ideal",
    }
    cfg.proposer = proposer_cfg
    assert training.proposer_from_config(cfg).compile is False
    cfg.proposer.compile = True
    assert training.proposer_from_config(cfg).compile is True


def test_the_critic_loss_functions_reach_the_losses():
    env = training.make_env("ideal", seed=0, num_envs=1, max_steps=5)
    actor, critic = training.make_actor(env, (8,)), training.make_q_critic(env, (8,))
    assert training.make_sac_loss(actor, critic, env)[0].loss_function == "smooth_l1"  # TorchRL's
    assert training.make_sac_loss(actor, critic, env, loss_function="l2")[0].loss_function == "l2"
    lyapunov = training.make_lyapunov_critic(env, (8,))
    assert training.make_lac_loss(actor, lyapunov, env).loss_function == "l2"
    huber = training.make_lac_loss(actor, lyapunov, env, loss_function="smooth_l1")
    assert huber.loss_function == "smooth_l1"


def test_the_lyapunov_critic_reads_the_task_features_only_where_asked():
    """lyapunov.inputs=task: the critic's output moves with a task feature (the target's
    distance) and not with the vehicle's (entries 24-37); all: with both. lyapunov.gamma
    reaches the loss as its Lyapunov discount, the task critic keeping optim.gamma."""
    env = training.make_env("ideal", seed=0, num_envs=1, max_steps=5)
    cfg = OmegaConf.create(
        {
            "network": {"hidden": [8]},
            "device": "cpu",
            "lyapunov": {"inputs": "task", "form": "softplus", "stability_weight": 0.1},
        }
    )
    td = env.reset()
    td["agents", "action"] = torch.zeros(1, 2, 3)

    def moved(critic, index):
        shaken = td.clone()
        shaken["agents", "observation"][..., index] += 0.5
        before = critic(td.clone())["agents", "lyapunov_raw"]
        return not torch.equal(before, critic(shaken)["agents", "lyapunov_raw"])

    torch.manual_seed(0)
    task = training.lyapunov_critic_from_config(cfg, env)
    assert moved(task, 3) and not moved(task, slice(24, 38))
    cfg.lyapunov.inputs = "all"
    every = training.lyapunov_critic_from_config(cfg, env)
    assert moved(every, 3) and moved(every, slice(24, 38))
    with pytest.raises(ValueError, match="inputs must be one of"):
        training.make_lyapunov_critic(env, (8,), inputs="vehicle")
    actor = training.make_actor(env, (8,))
    loss = training.make_lac_loss(actor, task, env, gamma=0.99, lyapunov_gamma=0.999)
    assert (loss.gamma, loss.lyapunov_gamma) == (0.99, 0.999)
    assert training.make_lac_loss(actor, task, env, gamma=0.99).lyapunov_gamma == 0.99


def test_the_lyapunov_cost_choice_sets_what_each_critic_learns():
    """lyapunov.cost=task: one critic on the task cost (the paper); stability: the Lyapunov
    critic on the stability cost and a task Q critic on the cost, both trained by the loss,
    both in the critics' optimiser, both soft-updated."""
    from torchrl.objectives import SoftUpdate

    env = training.make_env("ideal", seed=0, num_envs=2, max_steps=5)
    actor, lyapunov = training.make_actor(env, (8,)), training.make_lyapunov_critic(env, (8,))
    task = training.make_lac_loss(actor, lyapunov, env)
    assert task.qvalue_network is None and task.tensor_keys.cost == ("agents", "cost")
    stable = training.make_lac_loss(actor, lyapunov, env, cost="stability", hidden=(8,))
    assert stable.tensor_keys.cost == ("agents", "stability_cost")
    assert stable.tensor_keys.task_cost == ("agents", "cost")
    updater = SoftUpdate(stable, tau=0.5)  # before any forward, as the recipes do
    data = training.select_for_replay(env.rollout(4, actor))
    out = stable(data)
    assert torch.isfinite(out["loss_qvalue"]) and torch.isfinite(out["loss_lyapunov"])
    optimisers = training.lac_optimisers(
        stable, OmegaConf.create({"actor_lr": 1e-3, "critic_lr": 1e-3, "dual_lr": 1e-3})
    )
    critic_params = {id(p) for g in optimisers["critic_optim"].param_groups for p in g["params"]}
    assert {id(p) for p in stable.qvalue_network_params.values(True, True)} <= critic_params
    before = [p.detach().clone() for p in stable.target_qvalue_network_params.values(True, True)]
    training.gradient_step(stable, optimisers, updater, data)
    after = stable.target_qvalue_network_params.values(True, True)
    assert any((a != b).any() for a, b in zip(after, before, strict=True))
    with pytest.raises(ValueError, match="cost must be one of"):
        training.make_lac_loss(actor, lyapunov, env, cost="energy")


def test_close_logger_finishes_wandb_runs_and_leaves_other_loggers(tmp_path):
    from torchrl.record.loggers import CSVLogger

    training.close_logger(None)
    csv = CSVLogger("run", log_dir=str(tmp_path))
    csv.log_scalar("x", 1.0, step=0)
    training.close_logger(csv)  # TorchRL's CSV experiment has no finish(): nothing to do

    class _Run:
        finished = False

        def finish(self):
            self.finished = True

    class _Logger:
        experiment = _Run()

    logger = _Logger()
    training.close_logger(logger)
    assert logger.experiment.finished


def test_an_unreachable_advisor_endpoint_is_refused_before_any_work():
    import http.server
    import socket
    import threading

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cfg = {"advisor": {"backend": "openai", "base_url": f"http://127.0.0.1:{port}/v1"}}
    with pytest.raises(
        ValueError,
        match=rf"advisor\.base_url http://127\.0\.0\.1:{port}/v1 "
        r"does not answer.*advisor\.backend=rules",
    ):
        training.check_config(cfg)
    # a real HTTP server answers (a 404 for /models still proves the endpoint is there)
    server = http.server.HTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        cfg["advisor"]["base_url"] = f"http://127.0.0.1:{server.server_port}/v1"
        training.check_config(cfg)
    finally:
        server.shutdown()
        server.server_close()
    training.check_config({"advisor": {"backend": "rules", "base_url": "http://127.0.0.1:1"}})


def test_a_loss_state_saved_before_the_spec_was_in_it_loads_and_keeps_the_spec_in_force():
    env = training.make_env("ideal", seed=0, num_envs=1, max_steps=2)
    loss = training.make_lac_loss(
        training.make_actor(env, (8,)), training.make_lyapunov_critic(env, (8,)), env
    )
    older = {k: v for k, v in loss.state_dict().items() if not k.startswith("spec_state.")}
    loss.set_lyapunov_spec(LyapunovSpec(form="log", alpha=0.3))
    loss.load_state_dict(older)  # strict: no missing key reported for the spec
    assert (loss.spec.form, loss.spec.alpha) == ("log", 0.3)
    newer = {k: v.clone() for k, v in loss.state_dict().items()}  # as saved: a copy
    loss.set_lyapunov_spec(LyapunovSpec(form="squared", alpha=0.05))
    loss.load_state_dict(newer)
    assert (loss.spec.form, loss.spec.alpha) == ("log", 0.3)


def test_the_q_critics_learn_the_stability_cost_where_asked():
    env = training.make_env("ideal", seed=0, num_envs=1, max_steps=3)
    actor = training.make_actor(env, (8,))
    critic = training.make_q_critic(env, (8,))
    loss, _ = training.make_sac_loss(actor, critic, env, critic_cost="stability")
    assert loss.reward_from == ("agents", "stability_cost")
    assert training.make_sac_loss(actor, critic, env)[0].reward_from is None
    with pytest.raises(ValueError, match="critic_cost must be one of"):
        training.make_sac_loss(actor, critic, env, critic_cost="energy")
