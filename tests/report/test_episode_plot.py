"""Episode rendering writes a real PNG for batched and unbatched rollouts."""

from __future__ import annotations

from torchrl_auv.envs import AUVTrackingEnv, ScriptedExpert
from torchrl_auv.report import plot_episode


def test_plot_episode_png(tmp_path):
    env = AUVTrackingEnv(batch_size=[2], sea_state="es", seed=0)
    td = env.rollout(40, ScriptedExpert(env))
    batched = plot_episode(td, tmp_path / "b.png", index=1)
    single = plot_episode(td[0], tmp_path / "s.png")
    for path in (batched, single):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_plot_data_collection_episode_png(tmp_path):
    from torchrl_auv.envs import DataCollectionEnv

    env = DataCollectionEnv(batch_size=[1], seed=0, rate_model="paper")
    td = env.rollout(60, ScriptedExpert(env))
    path = plot_episode(td, tmp_path / "fleet.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
