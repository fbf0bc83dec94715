"""TrainingFeedback from collected data; the trigger policy, decision log and a training loop."""

from __future__ import annotations

import json
import logging
import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator

from torchrl_auv.advisor import (
    AdvisorDecision,
    AdvisorTrigger,
    RuleBasedAdvisor,
    TrainingFeedback,
    feedback_from_training,
)
from torchrl_auv.envs import AUVTrackingEnv
from torchrl_auv.objectives import LyapunovActorCriticLoss, LyapunovSpec


def _batch(signal, velocity, reward):
    """[2 envs, T] batch with observation [signal, velocity] and the given rewards."""
    obs = torch.stack([signal, velocity], -1).expand(2, -1, -1)
    return TensorDict(
        {"observation": obs, ("next", "reward"): reward.view(1, -1, 1).expand(2, -1, 1)},
        [2, len(signal)],
    )


def test_oscillation_indices_are_zero_crossing_rates():
    t = torch.arange(41.0)
    sine = torch.sin(2 * math.pi * t / 10 + 0.3)  # period 10 steps: 2 crossings per 10 steps
    decay = torch.exp(-t / 10)  # monotone approach: no crossing
    fb = feedback_from_training(
        _batch(sine, decay, -torch.ones(41)), position_indices=[0], velocity_indices=[1]
    )
    assert fb.position_oscillation == pytest.approx(8 / 40)
    assert fb.velocity_oscillation == 0.0 and fb.oscillation_index == fb.position_oscillation


def test_return_trend_and_loss_output_series():
    t = torch.arange(40.0)
    improving = _batch(torch.ones(40), torch.ones(40), torch.where(t < 20, -2.0, -1.0))
    outputs = [
        TensorDict(
            {
                "lambda": torch.tensor(v),
                "violation_rate": torch.tensor(r),
                "lyapunov_value": torch.tensor(ly),
            },
            [],
        )
        for v, r, ly in [(1.0, 0.2, 4.0), (0.8, 0.4, 4.0), (0.5, 0.6, 2.0), (0.4, 0.8, 2.0)]
    ]
    fb = feedback_from_training(improving, outputs, position_indices=[0], velocity_indices=[1])
    assert fb.return_trend == pytest.approx(0.5)  # from -2 to -1
    assert fb.violation_rate == pytest.approx(0.5) and fb.lambda_trend == pytest.approx(-0.6)
    assert fb.lyapunov_trend == pytest.approx(-0.5) and fb.steps == 80
    two = [_batch(torch.ones(5), torch.ones(5), -torch.ones(5) * k) for k in (4.0, 2.0)]
    assert feedback_from_training(
        two, position_indices=[0], velocity_indices=[1]
    ).return_trend == pytest.approx(0.5)


def test_collisions_and_bad_input():
    td = _batch(torch.ones(4), torch.ones(4), -torch.ones(4))
    td["collision"] = torch.tensor([[0, 1, 0, 1], [0, 0, 0, 0]])
    kwargs = {"position_indices": [0], "velocity_indices": [1]}
    assert feedback_from_training(td, collision_key="collision", **kwargs).collisions == 2
    with pytest.raises(ValueError, match="observation_key"):
        feedback_from_training(td, observation_key="obs", **kwargs)
    with pytest.raises(ValueError, match="velocity_indices"):
        feedback_from_training(td)  # the default indices need the tracking env's 16 entries
    with pytest.raises(ValueError, match="batches"):
        feedback_from_training([])


class _Loss:
    def __init__(self, spec=None):
        self.spec = spec or LyapunovSpec()

    def set_lyapunov_spec(self, spec):
        self.spec = spec


def test_trigger_consults_at_start_on_thresholds_and_respects_the_cooldown(tmp_path):
    log = tmp_path / "run" / "advisor.jsonl"
    trigger = AdvisorTrigger(RuleBasedAdvisor(), "collect data", log_path=log, cooldown=1000)
    loss = _Loss(LyapunovSpec(form="squared", alpha=0.2))
    assert trigger.step(0, None, loss).reasons == ()  # start: the paper's default
    assert loss.spec.form == "softplus"
    oscillating = TrainingFeedback(position_oscillation=0.5)
    assert trigger.step(500, oscillating, loss) is None  # cooldown
    assert trigger.step(1500, TrainingFeedback(), loss) is None  # nothing crossed
    decision = trigger.step(1500, oscillating, loss)
    assert decision.form == "squared" and loss.spec.prior == "position"
    records = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r["trigger"] for r in records] == ["start", "oscillation_index 0.500 >= 0.3"]
    assert records[1]["spec_before"]["form"] == "softplus" and records[1]["applied"]
    assert records[1]["feedback"]["position_oscillation"] == 0.5 and records[1]["latency_s"] >= 0
    assert records[0]["task"] == "collect data"
    # appended, never truncated: a second trigger on the same file keeps the old lines
    AdvisorTrigger(RuleBasedAdvisor(), "x", log_path=log).step(0, None, _Loss())
    assert len(log.read_text().splitlines()) == 3


def test_an_advisor_that_raises_does_not_stop_training_and_says_so_once(tmp_path, caplog):
    class Broken:
        def propose(self, task, feedback, current) -> AdvisorDecision:
            raise RuntimeError("boom")

    loss = _Loss()
    trigger = AdvisorTrigger(Broken(), "x", log_path=tmp_path / "a.jsonl", cooldown=0)
    with caplog.at_level(logging.WARNING):
        decision = trigger.step(0, None, loss)
        for frame in (10, 20):  # the same failure again: counted, said once
            trigger.step(frame, TrainingFeedback(collisions=1.0), loss)
    assert not decision.accepted and decision.reasons == ("advisor raised RuntimeError: boom",)
    assert loss.spec == LyapunovSpec()
    said = [r.getMessage() for r in caplog.records if "kept the Lyapunov spec" in r.getMessage()]
    assert len(said) == 1 and "RuntimeError: boom" in said[0]
    assert trigger.failure_summary() == "advisor raised RuntimeError: boom (x3)"
    with pytest.raises(ValueError, match="advisor"):
        AdvisorTrigger(object(), "x", log_path=tmp_path / "a.jsonl")


def test_wandb_table_and_scalars(tmp_path, monkeypatch):
    from torchrl.record.loggers import get_logger

    monkeypatch.setenv("WANDB_MODE", "offline")
    logger = get_logger(
        "wandb",
        logger_name=str(tmp_path),
        experiment_name="advisor",
        wandb_kwargs={"offline": True, "project": "torchrl-auv-tests"},
    )
    trigger = AdvisorTrigger(
        RuleBasedAdvisor(), "tight", log_path=tmp_path / "a.jsonl", logger=logger
    )
    trigger.step(0, None, _Loss())
    logger.experiment.finish()
    files = list(tmp_path.rglob("*.table.json"))
    assert files, "no wandb table written"
    table = json.loads(files[0].read_text())
    assert table["columns"][:3] == ["frame", "trigger", "form"]
    assert table["data"][0][2] == "squared"


def _actor(env):
    net = nn.Sequential(MLP(in_features=16, out_features=6, num_cells=[32]), NormalParamExtractor())
    return ProbabilisticActor(
        TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        spec=env.action_spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        return_log_prob=True,
    )


def test_in_a_training_loop_the_decision_changes_the_loss_spec(tmp_path):
    """AUVTrackingEnv + LyapunovActorCriticLoss + the trigger: the start decision and a
    later feedback-driven one both reach the loss, and the log records them."""
    torch.manual_seed(0)
    env = AUVTrackingEnv(batch_size=[4], sea_state="es", seed=0, max_steps=50)
    actor = _actor(env)
    critic = ValueOperator(
        MLP(in_features=19, out_features=8, num_cells=[32]), in_keys=["observation", "action"]
    )
    loss = LyapunovActorCriticLoss(actor, critic, form="log", stability_weight=0.3)
    optim = torch.optim.Adam(loss.parameters(), lr=1e-3)
    # a low oscillation threshold and no cooldown, so the short run must trigger again
    trigger = AdvisorTrigger(
        RuleBasedAdvisor(),
        "very extreme seas: hold heading and depth",
        log_path=tmp_path / "advisor.jsonl",
        cooldown=0,
        oscillation=0.01,
    )
    collector = Collector(
        env, actor, frames_per_batch=40, total_frames=120, auto_register_policy_transforms=False
    )
    trigger.step(0, None, loss)
    assert (loss.spec.form, loss.spec.alpha) == ("squared", 0.2)
    lambda_before, frames, outputs = loss.log_lambda.detach().clone(), 0, []
    for batch in collector:
        frames += batch.numel()
        for _ in range(3):
            out = loss(batch.reshape(-1))
            optim.zero_grad()
            sum(v for k, v in out.items() if k.startswith("loss")).backward()
            optim.step()
            outputs.append(out.detach())
        trigger.step(frames, feedback_from_training(batch, outputs[-3:]), loss)
    collector.shutdown()
    records = [json.loads(line) for line in (tmp_path / "advisor.jsonl").read_text().splitlines()]
    assert records[0]["applied"] and records[0]["decision"]["form"] == "squared"
    later = [r for r in records[1:] if r["applied"]]
    assert later, [r["trigger"] for r in records]
    assert loss.spec.form == later[-1]["decision"]["form"]
    assert loss.spec.alpha == later[-1]["decision"]["alpha"]
    assert not torch.equal(loss.log_lambda.detach(), lambda_before)  # duals kept training


def test_consultation_and_failure_counts_survive_a_checkpoint(tmp_path):
    """A resumed run's summary counts every session's consultations and failures, not only the
    last session's (the counts ride in the trigger's state_dict through a real checkpoint)."""
    from torchrl_auv.training import Progress, make_checkpoint, resume_latest

    class Broken:
        def propose(self, task, feedback, current) -> AdvisorDecision:
            raise RuntimeError("boom: 12 s")

    def trigger() -> AdvisorTrigger:
        return AdvisorTrigger(Broken(), "x", log_path=tmp_path / "a.jsonl", cooldown=0)

    first, progress = trigger(), Progress()
    for frame in (0, 10):
        first.step(frame, TrainingFeedback(collisions=1.0), _Loss())
    ckpt, rotation = make_checkpoint(tmp_path, modules={"advisor": first}, progress=progress)
    progress.frames = 10
    rotation.save(ckpt, step=10)

    second, progress = trigger(), Progress()
    ckpt, _ = make_checkpoint(tmp_path, modules={"advisor": second}, progress=progress)
    assert resume_latest(tmp_path, ckpt, progress)[0] == 10
    second.step(20, TrainingFeedback(collisions=1.0), _Loss())
    assert second.consultations == 3 and len(second.records) == 1
    # the decision log says where the resumed session took over (decisions logged above it
    # with a later frame were rolled back with the session that made them)
    lines = [json.loads(line) for line in (tmp_path / "a.jsonl").read_text().splitlines()]
    assert [line.get("event") for line in lines] == [None, None, "restored", None]
    assert lines[2]["last_consultation_frame"] == 10 and lines[2]["consultations"] == 2
    assert second.failure_summary() == "advisor raised RuntimeError: boom: # s (x3)"
    # a checkpoint written before the counts were kept still loads
    third = trigger()
    third.load_state_dict({"last_frame": 5})
    assert third.consultations == 0 and third.failures == {} and third.reason(5, None) is None


def test_the_decisions_in_force_drop_those_a_resume_rolled_back(tmp_path):
    """A decision log across sessions: the consultations logged after the checkpoint a run
    resumed from were rolled back with their session; the resumed session's stand."""
    from torchrl_auv.advisor import decisions_in_force

    log = tmp_path / "advisor.jsonl"
    records = [
        {"frame": 1000, "applied": False},
        {"frame": 21000, "applied": True},
        {"event": "restored", "last_consultation_frame": 1000, "consultations": 1},
        {"frame": 21000, "applied": False},
        {"frame": 43000, "applied": True},
        {"event": "restored", "last_consultation_frame": 43000, "consultations": 3},
    ]
    log.write_text("".join(json.dumps(r) + "\n" for r in records) + "\n")
    kept = decisions_in_force(log)
    assert [(r["frame"], r["applied"]) for r in kept] == [
        (1000, False),
        (21000, False),
        (43000, True),
    ]
    # a restore before any consultation (-1) rolls back every earlier one
    with log.open("a") as f:
        f.write(json.dumps({"event": "restored", "last_consultation_frame": -1}) + "\n")
    assert decisions_in_force(log) == []
    assert decisions_in_force(tmp_path / "missing.jsonl") == []
