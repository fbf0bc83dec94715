r"""``DiffusionProposer``: a state-conditioned DDPM that proposes K candidate action chunks.

The paper's generator (§III-A). The conditioning state is the observation, optionally followed
by the last ``L`` observations, actions and their validity mask from
:class:`~torchrl_auv.envs.StateActionHistory` (the paper's eq. 5,
:math:`s_t = [o_t, \mathrm{Flatten}(H), \mathrm{Flatten}(A)]`, plus the mask so that the first
decisions of an episode are recognisable). All ``K`` candidates of all batch entries are
denoised in one batched pass; the state encoding is computed once per proposal.

Actions are normalised to ``[-1, 1]`` with the action bounds inside the model and mapped back
on output, so the clipping of the predicted clean chunk at every step keeps every candidate
inside the bounds. The conditioning state is standardised with a per-feature location and
scale kept in the module (identity until :meth:`DiffusionProposer.set_state_normalization`;
:func:`~torchrl_auv.objectives.pretrain_proposer` fits them on its training split): the
observation's features range from rates of 0.01 rad/s to fills of order one, and a noise
model on raw features learns the small ones slowly.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import torch
from tensordict import NestedKey, TensorDictBase, unravel_key
from tensordict.nn import TensorDictModuleBase
from torch import nn
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from torchrl_auv.modules.diffusion_schedule import SAMPLERS, NoiseSchedule
from torchrl_auv.modules.noise_models import make_noise_model

__all__ = ["DiffusionProposer"]


def _prefix(key: NestedKey) -> tuple[str, ...]:
    key = unravel_key(key)
    key = (key,) if isinstance(key, str) else tuple(key)
    return key[:-1]


class DiffusionProposer(TensorDictModuleBase):
    """Proposes ``num_candidates`` action chunks per state with a conditional DDPM.

    Key contract: reads ``state_key`` (and, when ``history_key`` is set, its ``observation``,
    ``action`` and ``mask`` entries) and writes ``candidates_key`` shaped
    ``[*B, K, H, A]``, ``first_actions_key`` ``[*B, K, A]`` (each chunk's first action), when
    ``action_key`` is set the first action of candidate 0 there (the proposer acting alone),
    and with ``num_stages > 0`` the intermediate denoising stages under ``stages_key``
    ``[*B, S, K, H, A]`` (the noisy chunks at ``S`` evenly spaced steps, the last one final,
    clipped to the bounds for display; the paper's Fig. 5/6).

    Args:
        state_dim: size of the conditioning state (with the flattened history if any).
        action_dim: ``A``.
        state_key: the observation (or a flat state) entry.
        history_key: the :class:`~torchrl_auv.envs.StateActionHistory` entry, or ``None``.
        action_low, action_high: action bounds, scalars or ``[A]``.
        num_candidates: ``K >= 1`` (the paper: 5).
        horizon: ``H``, chunk length (default 8; the U-Net needs ``2 ** (levels - 1) | H``).
        num_inference_steps: denoising steps, ``1 <= n <= num_train_steps`` (the paper: 50).
        sampler: ``"ddpm"`` (strided ancestral) or ``"ddim"`` (deterministic).
        noise_model: ``"mlp"`` (default, see ``benchmarks/bench_proposer.py``) or ``"unet"``.
        noise_model_kwargs: widths and depth of the noise model.
        num_train_steps: ``T`` (the paper: 1000); schedule: ``"linear"`` or ``"cosine"``.
        candidates_key, first_actions_key, stages_key: output keys (default under
            ``"proposer"`` next to ``state_key``); action_key: optional output.
        num_stages: how many denoising stages to keep (0: none).
        compile: run the noise model's denoising step through ``torch.compile`` (compiles on
            the first proposal per batch shape; see ``benchmarks/bench_proposer.py``).

    Examples:
        >>> from tensordict import TensorDict
        >>> proposer = DiffusionProposer(6, 2, num_candidates=4, horizon=8,
        ...                              num_inference_steps=10, sampler="ddim")
        >>> td = proposer(TensorDict({"observation": torch.zeros(3, 6)}, batch_size=[3]))
        >>> td["proposer", "candidates"].shape
        torch.Size([3, 4, 8, 2])
    """

    def __init__(
        self,
        state_dim: int,
        action_dim: int,
        *,
        state_key: NestedKey = "observation",
        history_key: NestedKey | None = None,
        action_low: float | Sequence[float] | torch.Tensor = -1.0,
        action_high: float | Sequence[float] | torch.Tensor = 1.0,
        num_candidates: int = 5,
        horizon: int = 8,
        num_inference_steps: int = 50,
        sampler: str = "ddpm",
        noise_model: str = "mlp",
        noise_model_kwargs: dict | None = None,
        num_train_steps: int = 1000,
        schedule: str = "linear",
        candidates_key: NestedKey | None = None,
        first_actions_key: NestedKey | None = None,
        stages_key: NestedKey | None = None,
        action_key: NestedKey | None = None,
        num_stages: int = 0,
        compile: bool = False,
    ) -> None:
        super().__init__()
        for name, value in (
            ("state_dim", state_dim),
            ("action_dim", action_dim),
            ("num_candidates", num_candidates),
            ("horizon", horizon),
        ):
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler must be one of {SAMPLERS}, got {sampler!r}")
        if not (isinstance(num_stages, int) and num_stages >= 0):
            raise ValueError(f"num_stages must be an int >= 0, got {num_stages!r}")
        self.schedule = NoiseSchedule(num_train_steps, schedule)
        self.schedule.timesteps(num_inference_steps)  # validates num_inference_steps
        low = torch.as_tensor(action_low, dtype=torch.float32).expand(action_dim).clone()
        high = torch.as_tensor(action_high, dtype=torch.float32).expand(action_dim).clone()
        if not bool((high > low).all()):
            raise ValueError(f"action_high must exceed action_low, got {low} and {high}")
        self.register_buffer("action_low", low)
        self.register_buffer("action_high", high)
        self.register_buffer("state_loc", torch.zeros(state_dim))
        self.register_buffer("state_scale", torch.ones(state_dim))
        self.state_dim, self.action_dim = state_dim, action_dim
        self.num_candidates, self.horizon = num_candidates, horizon
        self.num_inference_steps, self.sampler = num_inference_steps, sampler
        self.num_stages = num_stages
        self.noise_model_kind = noise_model
        self.noise_model_kwargs = dict(noise_model_kwargs or {})
        self.noise_model = make_noise_model(
            noise_model, state_dim, action_dim, horizon=horizon, **self.noise_model_kwargs
        )
        self.compile = bool(compile)
        self._compiled: dict[int, object] = {}
        self.ema: AveragedModel | None = None
        self.ema_decay: float | None = None
        self.use_ema = False
        self.generator: torch.Generator | None = None

        self.state_key = unravel_key(state_key)
        self.history_key = None if history_key is None else unravel_key(history_key)
        prefix = _prefix(self.state_key)
        self.candidates_key = unravel_key(candidates_key or (*prefix, "proposer", "candidates"))
        self.first_actions_key = unravel_key(
            first_actions_key or (*prefix, "proposer", "first_actions")
        )
        self.stages_key = unravel_key(stages_key or (*prefix, "proposer", "stages"))
        self.action_key = None if action_key is None else unravel_key(action_key)
        self.in_keys = [self.state_key]
        if self.history_key is not None:
            h = self.history_key if isinstance(self.history_key, tuple) else (self.history_key,)
            self.in_keys += [(*h, "observation"), (*h, "action"), (*h, "mask")]
        self.out_keys = [self.candidates_key, self.first_actions_key]
        if num_stages:
            self.out_keys.append(self.stages_key)
        if self.action_key is not None:
            self.out_keys.append(self.action_key)

    def __getstate__(self) -> dict:
        """Pickled without its compiled denoising steps (a worker process or Ray actor
        compiles its own on first use)."""
        state = super().__getstate__()
        state["_compiled"] = {}
        return state

    # -- construction from an env ---------------------------------------------------------
    @staticmethod
    def conditioning_dim(obs_dim: int, action_dim: int, history: int) -> int:
        """Size of the conditioning state: the observation and ``history`` pairs of
        (observation, action, validity flag).

        >>> DiffusionProposer.conditioning_dim(16, 3, 10)
        216
        """
        return obs_dim + history * (obs_dim + action_dim + 1)

    @classmethod
    def for_env(
        cls,
        env,
        *,
        num_candidates: int = 5,
        horizon: int = 8,
        num_inference_steps: int = 50,
        sampler: str = "ddpm",
        history_length: int = 10,
        **kwargs: object,
    ) -> DiffusionProposer:
        """A proposer for an env's specs: its observation key (``("agents", "observation")``
        for the multi-agent data-collection layout), action bounds, and the history key of
        :class:`~torchrl_auv.envs.StateActionHistory` next to the observation (its length read
        from the env's specs when the env is wrapped, else ``history_length``).

        >>> from torchrl_auv.envs import AUVTrackingEnv
        >>> proposer = DiffusionProposer.for_env(AUVTrackingEnv(), num_inference_steps=5)
        >>> proposer.state_dim  # 16 + 10 * (16 + 3 + 1)
        216
        """
        obs_key = unravel_key(getattr(env, "observation_key", "observation"))
        act_key = unravel_key(getattr(env, "agent_action_key", "action"))
        prefix = _prefix(obs_key)
        history_key = (*prefix, "history")
        obs_spec = env.observation_spec
        obs_dim = obs_spec[obs_key].shape[-1]
        action_spec = env.full_action_spec[act_key]
        action_dim = action_spec.shape[-1]
        low = action_spec.space.low.reshape(-1, action_dim)[0]
        high = action_spec.space.high.reshape(-1, action_dim)[0]
        if (*history_key, "observation") in obs_spec.keys(True, True):
            history_length = obs_spec[(*history_key, "observation")].shape[-2]
        state_dim = cls.conditioning_dim(obs_dim, action_dim, history_length)
        return cls(
            state_dim,
            action_dim,
            state_key=obs_key,
            history_key=history_key,
            action_low=low,
            action_high=high,
            num_candidates=num_candidates,
            horizon=horizon,
            num_inference_steps=num_inference_steps,
            sampler=sampler,
            **kwargs,
        )

    def configure_sampling(
        self,
        *,
        num_candidates: int | None = None,
        num_inference_steps: int | None = None,
        sampler: str | None = None,
    ) -> None:
        """Change how the proposer samples (K, denoising steps, sampler) without touching its
        weights: a pretrained proposer serves any of them. ``None`` keeps a value.

        >>> proposer = DiffusionProposer(4, 2, num_inference_steps=10)
        >>> proposer.configure_sampling(num_candidates=16, sampler="ddim")
        >>> proposer.num_candidates, proposer.sampler, proposer.num_inference_steps
        (16, 'ddim', 10)
        """
        if num_candidates is not None:
            if not (isinstance(num_candidates, int) and num_candidates >= 1):
                raise ValueError(f"num_candidates must be an int >= 1, got {num_candidates!r}")
            self.num_candidates = num_candidates
        if num_inference_steps is not None:
            self.schedule.timesteps(num_inference_steps)  # validates it
            self.num_inference_steps = num_inference_steps
        if sampler is not None:
            if sampler not in SAMPLERS:
                raise ValueError(f"sampler must be one of {SAMPLERS}, got {sampler!r}")
            self.sampler = sampler

    # -- state and normalisation ----------------------------------------------------------
    def build_state(self, tensordict: TensorDictBase) -> torch.Tensor:
        """The conditioning state ``[*B, state_dim]`` read from ``tensordict``."""
        state = tensordict.get(self.state_key, None)
        if state is None:
            raise ValueError(f"state_key {self.state_key!r} is missing from the input")
        parts = [state]
        if self.history_key is not None:
            history = tensordict.get(self.history_key, None)
            if history is None:
                raise ValueError(
                    f"history_key {self.history_key!r} is missing from the input: wrap the env "
                    "with torchrl_auv.envs.StateActionHistory (or pass history_key=None)"
                )
            parts += [
                history["observation"].flatten(-2),
                history["action"].flatten(-2),
                history["mask"].to(state.dtype),
            ]
        state = torch.cat(parts, -1)
        if state.shape[-1] != self.state_dim:
            raise ValueError(
                f"the state read from {self.in_keys} has {state.shape[-1]} features, "
                f"state_dim is {self.state_dim}"
            )
        return state

    def set_state_normalization(
        self, loc: torch.Tensor | Sequence[float], scale: torch.Tensor | Sequence[float]
    ) -> None:
        """Standardise the conditioning state as ``(state - loc) / scale`` from now on (both
        ``[state_dim]``, ``scale > 0``); :meth:`fit_state_normalization` computes them."""
        loc = torch.as_tensor(loc, dtype=self.state_loc.dtype, device=self.state_loc.device)
        scale = torch.as_tensor(scale, dtype=self.state_loc.dtype, device=self.state_loc.device)
        for name, value in (("loc", loc), ("scale", scale)):
            if value.shape != (self.state_dim,):
                raise ValueError(
                    f"{name} must be shaped [{self.state_dim}], got {tuple(value.shape)}"
                )
        if not bool((scale > 0).all() and loc.isfinite().all() and scale.isfinite().all()):
            raise ValueError("scale must be finite and > 0 and loc finite")
        self.state_loc.copy_(loc)
        self.state_scale.copy_(scale)

    def fit_state_normalization(self, states: torch.Tensor, *, min_scale: float = 1e-2) -> None:
        """Set the standardisation to the mean and standard deviation of ``states``
        (``[N, state_dim]``, as :meth:`build_state` returns them), each scale at least
        ``min_scale`` (a feature nearly constant in the data is not blown up where it varies
        later)."""
        if states.dim() != 2 or states.shape[-1] != self.state_dim or len(states) < 2:
            raise ValueError(
                f"states must be shaped [N >= 2, {self.state_dim}], got {tuple(states.shape)}"
            )
        states = states.double()
        self.set_state_normalization(states.mean(0), states.std(0).clamp_min(min_scale))

    def normalize_state(self, state: torch.Tensor) -> torch.Tensor:
        """``(state - state_loc) / state_scale``: what the noise model is conditioned on."""
        return (state - self.state_loc.to(state.dtype)) / self.state_scale.to(state.dtype)

    def predict_noise(self, x: torch.Tensor, t: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """The trained noise model's prediction for noisy normalised chunks ``x``
        ``[*B, H, A]`` at steps ``t`` ``[*B]`` given raw states ``[*B, state_dim]``."""
        return self.noise_model(x, t, self.normalize_state(state))

    def normalize(self, action: torch.Tensor) -> torch.Tensor:
        """Actions in the bounds -> ``[-1, 1]``."""
        return 2 * (action - self.action_low) / (self.action_high - self.action_low) - 1

    def unnormalize(self, x: torch.Tensor) -> torch.Tensor:
        """``[-1, 1]`` -> actions in the bounds."""
        return self.action_low + (x.clamp(-1.0, 1.0) + 1) / 2 * (self.action_high - self.action_low)

    # -- EMA -------------------------------------------------------------------------------
    def enable_ema(self, decay: float = 0.995) -> None:
        """Keep an exponential moving average of the noise model's weights (``update_ema``
        after each optimiser step); sampling uses it only when ``use_ema`` is ``True``."""
        if not 0.0 < decay < 1.0:
            raise ValueError(f"decay must be in (0, 1), got {decay}")
        self.ema = AveragedModel(self.noise_model, multi_avg_fn=get_ema_multi_avg_fn(decay))
        self.ema.requires_grad_(False)  # averaged, never trained by an optimiser
        self.ema_decay = float(decay)

    def update_ema(self) -> None:
        if self.ema is None:
            raise RuntimeError("call enable_ema() first")
        self.ema.update_parameters(self.noise_model)

    def _sampling_model(self) -> nn.Module:
        if self.use_ema:
            if self.ema is None:
                raise RuntimeError("use_ema is set but enable_ema() was never called")
            return self.ema.module
        return self.noise_model

    # -- sampling --------------------------------------------------------------------------
    @torch.no_grad()
    def sample(
        self,
        state: torch.Tensor,
        *,
        num_candidates: int | None = None,
        generator: torch.Generator | None = None,
        num_stages: int | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Candidates ``[*B, K, H, A]`` (action units) for states ``[*B, state_dim]``.

        Returns ``(candidates, stages)``; ``stages`` is ``[*B, S, K, H, A]`` or ``None``.
        """
        k = self.num_candidates if num_candidates is None else num_candidates
        if not (isinstance(k, int) and k >= 1):
            raise ValueError(f"num_candidates must be an int >= 1, got {k!r}")
        model = self._sampling_model()
        denoise = model.denoise
        if self.compile:
            if id(model) not in self._compiled:
                self._compiled[id(model)] = torch.compile(model.denoise, dynamic=False)
            denoise = self._compiled[id(model)]
        batch = state.shape[:-1]
        cond = model.condition(self.normalize_state(state)).unsqueeze(-2).expand(*batch, k, -1)
        shape = (*batch, k, self.horizon, self.action_dim)
        kw = {"generator": generator, "dtype": state.dtype, "device": state.device}
        x = torch.randn(shape, **kw)
        steps = self.schedule.timesteps(self.num_inference_steps).tolist()
        n_stages = self.num_stages if num_stages is None else num_stages
        keep = set()
        if n_stages:
            keep = {round(i * (len(steps) - 1) / max(n_stages - 1, 1)) for i in range(n_stages)}
            keep = set(sorted(keep)[:n_stages])
        stages = []
        for i, t in enumerate(steps):
            s = steps[i + 1] if i + 1 < len(steps) else -1
            eps = denoise(x, torch.tensor(t, device=state.device), cond)
            noise = torch.randn(shape, **kw) if self.sampler == "ddpm" and s >= 0 else None
            x = self.schedule.step(x, eps, t, s, sampler=self.sampler, noise=noise)
            if i in keep:
                stages.append(self.unnormalize(x))
        candidates = self.unnormalize(x)
        return candidates, (torch.stack(stages, len(batch)) if stages else None)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        state = self.build_state(tensordict)
        candidates, stages = self.sample(state, generator=self.generator)
        tensordict.set(self.candidates_key, candidates)
        tensordict.set(self.first_actions_key, candidates[..., 0, :])
        if stages is not None:
            tensordict.set(self.stages_key, stages)
        if self.action_key is not None:
            tensordict.set(self.action_key, candidates[..., 0, 0, :])
        return tensordict

    # -- checkpoints -----------------------------------------------------------------------
    def config(self) -> dict:
        """Constructor arguments (JSON-able), for checkpoints."""
        return {
            "state_dim": self.state_dim,
            "action_dim": self.action_dim,
            "state_key": self.state_key,
            "history_key": self.history_key,
            "action_low": self.action_low.tolist(),
            "action_high": self.action_high.tolist(),
            "num_candidates": self.num_candidates,
            "horizon": self.horizon,
            "num_inference_steps": self.num_inference_steps,
            "sampler": self.sampler,
            "noise_model": self.noise_model_kind,
            "noise_model_kwargs": self.noise_model_kwargs,
            "num_train_steps": self.schedule.num_train_steps,
            "schedule": self.schedule.kind,
            "candidates_key": self.candidates_key,
            "first_actions_key": self.first_actions_key,
            "stages_key": self.stages_key,
            "action_key": self.action_key,
            "num_stages": self.num_stages,
            "compile": self.compile,
        }

    def save(self, path: str | Path) -> Path:
        """Write weights (and EMA weights), config and schedule to ``path`` (refuses to
        overwrite an existing file)."""
        path = Path(path)
        if path.exists():
            raise ValueError(f"path {path} exists; choose a new file")
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save(
            {
                "config": self.config(),
                "schedule": self.schedule.config(),
                "noise_model": self.noise_model.state_dict(),
                "state_loc": self.state_loc.clone(),
                "state_scale": self.state_scale.clone(),
                "ema": None if self.ema is None else self.ema.state_dict(),
                "ema_decay": self.ema_decay,
                "use_ema": self.use_ema,
            },
            path,
        )
        return path

    @classmethod
    def load(cls, path: str | Path) -> DiffusionProposer:
        """Rebuild a proposer saved by :meth:`save`: weights, the state standardisation
        (identity for checkpoints that hold none), and the EMA weights with their decay and
        the ``use_ema`` switch (older checkpoints that hold no decay resume at the default
        0.995, with a warning)."""
        data = torch.load(Path(path), weights_only=True)  # plain tensors and containers only
        config = dict(data["config"])
        for key in (
            "state_key",
            "history_key",
            "candidates_key",
            "first_actions_key",
            "stages_key",
            "action_key",
        ):
            if isinstance(config[key], list):
                config[key] = tuple(config[key])
        proposer = cls(**config)
        proposer.noise_model.load_state_dict(data["noise_model"])
        if "state_loc" in data:  # older checkpoints: no standardisation (identity)
            proposer.set_state_normalization(data["state_loc"], data["state_scale"])
        if data["ema"] is not None:
            decay = data.get("ema_decay")
            if decay is None:
                warnings.warn(
                    f"{path} holds EMA weights but no EMA decay (an old checkpoint); "
                    "resuming with the default decay 0.995",
                    stacklevel=2,
                )
                decay = 0.995
            proposer.enable_ema(decay)
            proposer.ema.load_state_dict(data["ema"])
        proposer.use_ema = bool(data.get("use_ema", False))
        return proposer
