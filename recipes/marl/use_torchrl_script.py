"""Run TorchRL's own multi-agent scripts on the data-collection env, the constructor swapped.

TorchRL's ``sota-implementations/multiagent/`` scripts (``mappo_ippo.py``: MAPPO and IPPO,
``maddpg_iddpg.py``: MADDPG and IDDPG, ``sac.py``: MASAC) build their envs with two
``VmasEnv(...)`` calls. This command copies one script, with its ``.yaml`` and ``utils/``, from a
TorchRL checkout into ``--out`` and replaces each of those two calls, and nothing else, by
:class:`~torchrl_auv.envs.DataCollectionEnv`::

    env = DataCollectionEnv(batch_size=[cfg.env.vmas_envs], num_auvs=cfg.env.scenario.n_agents,
                            per_agent_done=False, max_steps=cfg.env.max_steps, seed=cfg.seed,
                            device=cfg.env.device)

(``env_test`` the same with ``batch_size=[cfg.eval.evaluation_episodes]``). The env exposes
what the scripts read: ``reward_key``, ``action_key``, ``n_agents``, the ``("agents", ...)``
group, and with ``per_agent_done=False`` VMAS's scene-level ``done_keys``, which the scripts'
``DoneTransform`` expands over the agents. Example (a TorchRL checkout in ``rl/``)::

    python recipes/marl/use_torchrl_script.py --torchrl rl --script mappo_ippo --out runs/marl
    cd runs/marl && python mappo_ippo.py logger.backend= collector.frames_per_batch=2000 \\
        collector.n_iters=10 train.minibatch_size=500

The scripts' evaluation (every ``eval.evaluation_interval`` iterations, with a logger) renders
VMAS scenes and is not supported: run with ``logger.backend=`` or ``eval.evaluation_episodes=0``
(our own evaluation of a trained policy is :func:`torchrl_auv.training.evaluate`).
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from pathlib import Path

SCRIPTS = ("mappo_ippo", "maddpg_iddpg", "sac")

_ENVS = {
    "env": "cfg.env.vmas_envs",
    "env_test": "cfg.eval.evaluation_episodes",
}
_IMPORT = "from torchrl.envs.libs.vmas import VmasEnv\n"


def _call_end(source: str, start: int) -> int:
    """The index just past the parenthesis closing the call that opens at ``start``."""
    depth = 0
    for i in range(start, len(source)):
        depth += {"(": 1, ")": -1}.get(source[i], 0)
        if depth == 0 and source[i] == ")":
            return i + 1
    raise ValueError("unbalanced parentheses after VmasEnv(")


def swap_constructor(source: str) -> str:
    """``source`` with its ``env = VmasEnv(...)`` and ``env_test = VmasEnv(...)`` calls replaced
    by :class:`~torchrl_auv.envs.DataCollectionEnv` ones, and the import added.

    >>> swap_constructor("from torchrl.envs.libs.vmas import VmasEnv\\n"
    ...                  "env = VmasEnv(scenario=s, num_envs=f(a, b))\\n").splitlines()[1:3]
    ['from torchrl_auv.envs import DataCollectionEnv', 'env = DataCollectionEnv(']
    """
    if _IMPORT not in source:
        raise ValueError("the script does not import VmasEnv: not one of TorchRL's VMAS scripts")
    out = source.replace(_IMPORT, _IMPORT + "from torchrl_auv.envs import DataCollectionEnv\n", 1)
    for name, batch in _ENVS.items():
        match = re.search(rf"^([ \t]*){name} = VmasEnv\(", out, re.M)
        if match is None:
            raise ValueError(f"no `{name} = VmasEnv(` call in the script")
        indent = match.group(1)
        end = _call_end(out, match.end() - 1)
        call = (
            f"{indent}{name} = DataCollectionEnv(\n"
            f"{indent}    batch_size=[{batch}],\n"
            f"{indent}    num_auvs=cfg.env.scenario.n_agents,\n"
            f"{indent}    per_agent_done=False,\n"
            f"{indent}    max_steps=cfg.env.max_steps,\n"
            f"{indent}    seed=cfg.seed,\n"
            f"{indent}    device=cfg.env.device,\n"
            f"{indent})"
        )
        out = out[: match.start()] + call + out[end:]
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--torchrl", required=True, help="a TorchRL checkout (its root)")
    parser.add_argument("--script", choices=SCRIPTS, required=True)
    parser.add_argument("--out", required=True, help="a new folder for the swapped copy")
    args = parser.parse_args(argv)
    folder = Path(args.torchrl) / "sota-implementations" / "multiagent"
    script = folder / f"{args.script}.py"
    if not script.is_file():
        parser.error(f"--torchrl {args.torchrl}: no {script.relative_to(args.torchrl)} in it")
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        parser.error(f"--out {out} exists and is not empty; choose a new folder")
    out.mkdir(parents=True, exist_ok=True)
    try:
        (out / script.name).write_text(swap_constructor(script.read_text()))
    except ValueError as error:
        parser.error(f"--script {args.script}: {error}")
    shutil.copy(folder / f"{args.script}.yaml", out)
    shutil.copytree(folder / "utils", out / "utils")
    print(out / script.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
