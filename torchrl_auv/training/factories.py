"""Factories the training recipes share: env, actor, critic, SAC loss, replay buffer, logger.

Each ``make_*`` takes plain values (a recipe passes its Hydra groups in), returns a TorchRL
object and hides nothing a user would want to change: compose them into your own loop as
``recipes/sac/train.py`` does.

Layout: the multi-agent ``("agents", ...)`` keys of :class:`~torchrl_auv.envs.DataCollectionEnv`
with ONE set of network parameters shared by the AUVs (each AUV's decision is made from its own
observation; the demonstrations the proposer learns from are per AUV too). The flat layout
would tie the networks to the number of AUVs and double the input width for nothing.

Examples:
    >>> env = make_env("ideal", seed=0, num_envs=2)
    >>> actor = make_actor(env, hidden=(32, 32))
    >>> loss, target_updater = make_sac_loss(actor, make_q_critic(env, hidden=(32, 32)), env)
    >>> sorted(loss(select_for_replay(env.rollout(3, actor))).keys())[:3]
    ['alpha', 'entropy', 'loss_actor']
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch
from tensordict import TensorDictBase
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal
from torchrl.objectives import SACLoss, SoftUpdate

from torchrl_auv.envs import DataCollectionEnv

__all__ = [
    "REPLAY_KEYS",
    "ObsActionMLP",
    "bytes_per_frame",
    "make_actor",
    "make_env",
    "make_logger",
    "make_q_critic",
    "make_replay_buffer",
    "make_sac_loss",
    "select_for_replay",
]

AGENTS = "agents"
OBSERVATION = (AGENTS, "observation")
ACTION = (AGENTS, "action")
Q_VALUE = (AGENTS, "state_action_value")
#: What the losses read: the env's tensordict also carries the whole simulator state
#: (terrain, waves, nodes: about 30 KB per scene and step), which the buffer must not store.
REPLAY_KEYS = (
    OBSERVATION,
    ACTION,
    ("next", AGENTS, "observation"),
    ("next", AGENTS, "reward"),
    ("next", AGENTS, "cost"),
    ("next", AGENTS, "stability_cost"),
    ("next", AGENTS, "done"),
    ("next", AGENTS, "terminated"),
)


def make_env(
    sea_state: str = "ideal",
    *,
    seed: int,
    num_envs: int = 4,
    controller: str = "s_surface",
    rate_model: str = "shannon",
    max_steps: int | None = None,
    device: str | torch.device = "cpu",
    compile_physics: bool = False,
) -> DataCollectionEnv:
    """A batch of ``num_envs`` data-collection scenes on the ``("agents", ...)`` layout.

    Args:
        sea_state: ``ideal``, ``es`` or ``ves``.
        seed: seeds the env's generator (scenes, noise).
        num_envs: scenes simulated in one batch.
        controller: low-level controller, ``s_surface``, ``pid`` or ``smc``.
        rate_model: ``shannon`` or ``paper`` link rate.
        max_steps: decisions per episode (default the env's, 1000).
        device: where the env's tensors live.
        compile_physics: run the 20 Hz physics through ``torch.compile`` (about a minute of
            compilation on a fresh machine, seconds from the on-disk cache; then about 5x
            faster at batch 1, see ``benchmarks/bench_speed.py``).
    """
    if num_envs < 1:
        raise ValueError(f"num_envs must be >= 1, got {num_envs}")
    return DataCollectionEnv(batch_size=[num_envs], sea_state=sea_state, controller=controller,
                             rate_model=rate_model, seed=seed, max_steps=max_steps,
                             device=device, compile_physics=compile_physics)  # fmt: skip


def _dims(env: DataCollectionEnv) -> tuple[int, int]:
    obs = env.observation_spec[OBSERVATION].shape[-1]
    return obs, env.full_action_spec[ACTION].shape[-1]


def make_actor(env: DataCollectionEnv, hidden: Sequence[int] = (256, 256)) -> ProbabilisticActor:
    """Per-AUV TanhNormal actor (shared weights) within the env's action bounds ``[-1, 1]``.

    Reads ``("agents", "observation")``, writes ``("agents", "loc" | "scale" | "action")``.
    """
    obs_dim, act_dim = _dims(env)
    net = nn.Sequential(
        MLP(in_features=obs_dim, out_features=2 * act_dim, num_cells=list(hidden),
            activation_class=nn.ReLU),
        NormalParamExtractor(),
    )  # fmt: skip
    module = TensorDictModule(net, in_keys=[OBSERVATION], out_keys=[(AGENTS, "loc"),
                                                                    (AGENTS, "scale")])  # fmt: skip
    spec = env.full_action_spec[ACTION]
    return ProbabilisticActor(
        module,
        in_keys=[(AGENTS, "loc"), (AGENTS, "scale")],
        out_keys=[ACTION],
        spec=env.full_action_spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low[0, 0], "high": spec.space.high[0, 0]},
        return_log_prob=False,
    )


class ObsActionMLP(nn.Module):
    """An MLP of the concatenated observation and action (a critic's body), one output."""

    def __init__(self, in_features: int, hidden: Sequence[int]) -> None:
        super().__init__()
        self.net = MLP(in_features=in_features, out_features=1, num_cells=list(hidden),
                       activation_class=nn.ReLU)  # fmt: skip

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([obs, action], -1))


def make_q_critic(env: DataCollectionEnv, hidden: Sequence[int] = (256, 256)) -> TensorDictModule:
    """Per-AUV Q(o, a) (shared weights), written to ``("agents", "state_action_value")``.

    A plain ``TensorDictModule`` with an explicit out key: TorchRL's ``ValueOperator`` names its
    output ``state_value`` when the action key is nested.
    """
    obs_dim, act_dim = _dims(env)
    return TensorDictModule(ObsActionMLP(obs_dim + act_dim, hidden), in_keys=[OBSERVATION, ACTION],
                            out_keys=[Q_VALUE])  # fmt: skip


def make_sac_loss(
    actor: ProbabilisticActor,
    critic: TensorDictModule,
    env: DataCollectionEnv,
    *,
    gamma: float = 0.97,
    alpha_init: float = 1.0,
    num_qvalue_nets: int = 2,
    tau: float = 0.005,
    loss_function: str = "smooth_l1",
) -> tuple[SACLoss, SoftUpdate]:
    """TorchRL's ``SACLoss`` on the agents layout (reward ``== -cost``) and its target updater.

    The target entropy is ``-action_dim`` per AUV; ``loss_function`` is SACLoss's Q loss
    (``smooth_l1``, SACLoss's own default, or ``l2``).
    """
    loss = SACLoss(actor_network=actor, qvalue_network=critic, num_qvalue_nets=num_qvalue_nets,
                   alpha_init=alpha_init, target_entropy=-float(_dims(env)[1]),
                   delay_qvalue=True, loss_function=loss_function)  # fmt: skip
    loss.set_keys(action=ACTION, state_action_value=Q_VALUE, reward=(AGENTS, "reward"),
                  done=(AGENTS, "done"), terminated=(AGENTS, "terminated"))  # fmt: skip
    loss.make_value_estimator(gamma=gamma)
    return loss, SoftUpdate(loss, tau=tau)


def select_for_replay(data: TensorDictBase) -> TensorDictBase:
    """The frames of a collected batch with only :data:`REPLAY_KEYS`, flattened to ``[frames]``."""
    return data.select(*REPLAY_KEYS).reshape(-1)


def bytes_per_frame(frame: TensorDictBase) -> int:
    """Bytes one stored frame takes (the sum over its leaves; ``frame`` has batch ``[]``)."""
    return sum(t.numel() * t.element_size() for t in frame.values(True, True))


def make_replay_buffer(
    size: int,
    *,
    batch_size: int,
    storage: str = "memory",
    scratch_dir: str | Path | None = None,
) -> TensorDictReplayBuffer:
    """Uniform replay of ``size`` frames in RAM (``storage="memory"``) or on disk
    (``"memmap"``, under ``scratch_dir``)."""
    if storage == "memory":
        backing = LazyTensorStorage(size)
    elif storage == "memmap":
        backing = LazyMemmapStorage(size, scratch_dir=scratch_dir)
    else:
        raise ValueError(f"replay_buffer.storage must be 'memory' or 'memmap', got {storage!r}")
    return TensorDictReplayBuffer(storage=backing, batch_size=batch_size)


def make_logger(
    backend: str | None,
    run_dir: str | Path,
    *,
    exp_name: str,
    project: str = "torchrl-auv",
    offline: bool = True,
    config: dict | None = None,
    group: str | None = None,
):
    """A TorchRL logger writing under ``run_dir`` (wandb offline by default), or ``None`` when
    ``backend`` is empty. ``config`` is stored with a wandb run, ``group`` is its wandb group
    (a sweep's runs share one)."""
    from torchrl.record.loggers import get_logger

    if not backend:
        return None
    kwargs = {}
    if backend == "wandb":
        # TorchRL's WandbLogger writes under its log_dir (logger_name) already
        kwargs["wandb_kwargs"] = {"offline": offline, "project": project, "config": config or {},
                                  "group": group}  # fmt: skip
    return get_logger(backend, logger_name=str(run_dir), experiment_name=exp_name, **kwargs)
