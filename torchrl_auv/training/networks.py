"""The networks of the training recipes: per-AUV actor and critics, one set of weights shared
by the AUVs (each AUV decides from its own observation; the demonstrations the proposer learns
from are per AUV too). The flat layout would tie the networks to the number of AUVs and double
the input width for nothing.

Examples:
    >>> from torchrl_auv.training import make_env
    >>> env = make_env("ideal", seed=0, num_envs=2)
    >>> td = make_actor(env, hidden=(32, 32))(env.reset())
    >>> make_q_critic(env, hidden=(32,))(td)["agents", "state_action_value"].shape
    torch.Size([2, 2, 1])
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.iout import OBSERVATION_FEATURES
from torchrl_auv.training.keys import ACTION, AGENTS, LYAPUNOV_RAW, OBSERVATION, Q_VALUE

__all__ = [
    "LYAPUNOV_INPUTS",
    "ObsActionMLP",
    "critic_layer_norm",
    "make_actor",
    "make_lyapunov_critic",
    "make_q_critic",
    "observation_action_dims",
]


#: what a Lyapunov critic reads of the observation (:func:`make_lyapunov_critic`)
LYAPUNOV_INPUTS = ("all", "task")


def observation_action_dims(env: DataCollectionEnv) -> tuple[int, int]:
    """Features per AUV of the observation and of the action."""
    obs = env.observation_spec[OBSERVATION].shape[-1]
    return obs, env.full_action_spec[ACTION].shape[-1]


def make_actor(env: DataCollectionEnv, hidden: Sequence[int] = (256, 256)) -> ProbabilisticActor:
    """Per-AUV TanhNormal actor (shared weights) within the env's action bounds ``[-1, 1]``.

    Reads ``("agents", "observation")``, writes ``("agents", "loc" | "scale" | "action")``.
    """
    obs_dim, act_dim = observation_action_dims(env)
    net = nn.Sequential(
        MLP(
            in_features=obs_dim,
            out_features=2 * act_dim,
            num_cells=list(hidden),
            activation_class=nn.ReLU,
        ),
        NormalParamExtractor(),
    )
    module = TensorDictModule(
        net, in_keys=[OBSERVATION], out_keys=[(AGENTS, "loc"), (AGENTS, "scale")]
    )
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
    """An MLP of the concatenated observation and action (a critic's body), one output.

    ``layer_norm=True`` puts a ``LayerNorm`` after each hidden layer's linear map, before its
    ReLU (the critics of RLPD, Ball et al. 2023: it bounds the Q extrapolation off the data).
    ``observation_features``: read only the observation's first that many features (all when
    ``None``); ``in_features`` counts the features read.
    """

    def __init__(
        self,
        in_features: int,
        hidden: Sequence[int],
        layer_norm: bool = False,
        observation_features: int | None = None,
    ) -> None:
        super().__init__()
        if observation_features is not None and observation_features < 1:
            raise ValueError(
                f"observation_features must be None or >= 1, got {observation_features!r}"
            )
        self.observation_features = observation_features
        norm = {}
        if layer_norm:
            norm = {
                "norm_class": nn.LayerNorm,
                "norm_kwargs": [{"normalized_shape": width} for width in hidden],
            }
        self.net = MLP(
            in_features=in_features,
            out_features=1,
            num_cells=list(hidden),
            activation_class=nn.ReLU,
            **norm,
        )

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        if self.observation_features is not None:
            obs = obs[..., : self.observation_features]
        return self.net(torch.cat([obs, action], -1))


def critic_layer_norm(cfg: Mapping) -> bool:
    """A recipe config's ``network.layer_norm`` (absent: ``False``): whether its critics put a
    ``LayerNorm`` in each hidden layer (:class:`ObsActionMLP`)."""
    return bool(cfg["network"].get("layer_norm", False))


def make_q_critic(
    env: DataCollectionEnv, hidden: Sequence[int] = (256, 256), layer_norm: bool = False
) -> TensorDictModule:
    """Per-AUV Q(o, a) (shared weights), written to ``("agents", "state_action_value")``;
    ``layer_norm``: :class:`ObsActionMLP`'s.

    A plain ``TensorDictModule`` with an explicit out key: TorchRL's ``ValueOperator`` names its
    output ``state_value`` when the action key is nested.
    """
    obs_dim, act_dim = observation_action_dims(env)
    return TensorDictModule(
        ObsActionMLP(obs_dim + act_dim, hidden, layer_norm),
        in_keys=[OBSERVATION, ACTION],
        out_keys=[Q_VALUE],
    )


def make_lyapunov_critic(
    env,
    hidden: Sequence[int] = (256, 256),
    layer_norm: bool = False,
    inputs: str = "all",
) -> TensorDictModule:
    """Per-AUV Lyapunov critic's raw output z(o, a) (shared weights) at
    ``("agents", "lyapunov_raw")``; the form (e.g. softplus) is applied by the loss and the
    selector; ``layer_norm``: :class:`ObsActionMLP`'s.

    ``inputs`` (:data:`LYAPUNOV_INPUTS`): which observation features it reads, besides the
    action: ``"all"``, or ``"task"``: the task's features only
    (:data:`torchrl_auv.iout.OBSERVATION_FEATURES`: the target's offset and distance, the
    node, the area's edges, the current estimate, ...), not the vehicle's own (its velocities,
    rates and attitude: :data:`torchrl_auv.envs.data_collection.VEHICLE_FEATURES`), which
    waves shake from one decision to the next while the leg's cost-to-go hardly moves.

    Examples:
        >>> from torchrl_auv.training import make_env
        >>> env = make_env("ideal", seed=0, num_envs=1)
        >>> critic = make_lyapunov_critic(env, (8,), inputs="task")
        >>> td = env.reset()
        >>> td["agents", "action"] = torch.zeros(1, 2, 3)
        >>> a = critic(td.clone())["agents", "lyapunov_raw"]
        >>> td["agents", "observation"][..., 24:] += 1.0  # the vehicle's features
        >>> torch.equal(a, critic(td)["agents", "lyapunov_raw"])
        True
    """
    if inputs not in LYAPUNOV_INPUTS:
        raise ValueError(f"inputs must be one of {LYAPUNOV_INPUTS}, got {inputs!r}")
    obs_dim, act_dim = observation_action_dims(env)
    read = len(OBSERVATION_FEATURES) if inputs == "task" else None
    body = ObsActionMLP((read or obs_dim) + act_dim, hidden, layer_norm, observation_features=read)
    return TensorDictModule(
        body,
        in_keys=[OBSERVATION, ACTION],
        out_keys=[LYAPUNOV_RAW],
    )
