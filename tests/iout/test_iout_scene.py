"""Terrain, nodes, Poisson arrivals and overflow, start positions, determinism, global RNG."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.iout import (
    IoUTConfig,
    data_arrivals,
    make_terrain,
    reset_state,
    sample_auv_start,
    sample_nodes,
    seabed_depth,
    step,
)


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_terrain_range_smoothness_and_dtype():
    cfg = IoUTConfig()
    terrain = make_terrain(cfg, (5, 2), generator=_gen(), dtype=torch.float64)
    depth = terrain["depth"]
    assert depth.shape == (5, 2, 41, 41) and depth.dtype == torch.float64
    torch.testing.assert_close(
        depth.flatten(-2).amin(-1), torch.full((5, 2), 39.0, dtype=torch.float64)
    )
    torch.testing.assert_close(
        depth.flatten(-2).amax(-1), torch.full((5, 2), 58.0, dtype=torch.float64)
    )
    # smooth: neighbouring grid points (5 m apart) differ by far less than the 19 m range
    step_x = (depth[..., 1:, :] - depth[..., :-1, :]).abs().amax()
    step_y = (depth[..., :, 1:] - depth[..., :, :-1]).abs().amax()
    assert max(step_x, step_y) < 4.0
    # not flat: each scene uses its range
    assert (depth.flatten(-2).std(-1) > 1.0).all()


def test_seabed_lookup_is_bilinear_and_clamped():
    cfg = IoUTConfig()
    terrain = make_terrain(cfg, (3,), generator=_gen(1), dtype=torch.float64)
    grid = terrain["depth"]
    h = cfg.area_m[0] / (cfg.terrain_grid_points - 1)  # 5 m
    x = torch.tensor([[0.0, 5 * h, 2.5 * h, 200.0, -30.0]] * 3, dtype=torch.float64)
    y = torch.tensor([[0.0, 7 * h, 3.5 * h, 200.0, 250.0]] * 3, dtype=torch.float64)
    got = seabed_depth(terrain, x, y, cfg)
    assert got.shape == (3, 5)
    torch.testing.assert_close(got[:, 0], grid[:, 0, 0])
    torch.testing.assert_close(got[:, 1], grid[:, 5, 7])
    mid = (grid[:, 2, 3] + grid[:, 3, 3] + grid[:, 2, 4] + grid[:, 3, 4]) / 4
    torch.testing.assert_close(got[:, 2], mid)
    torch.testing.assert_close(got[:, 3], grid[:, -1, -1])
    torch.testing.assert_close(got[:, 4], grid[:, 0, -1])  # outside: clamped onto the edge
    points = 200.0 * torch.rand(3, 4, 6, generator=_gen(2), dtype=torch.float64)
    many = seabed_depth(terrain, points, points.flip(-1), cfg)
    assert many.shape == (3, 4, 6) and (many >= 39.0).all() and (many <= 58.0).all()
    with pytest.raises(ValueError, match="x and y"):
        seabed_depth(terrain, x, y[:, :2], cfg)


def test_a_nan_position_has_a_nan_seabed_and_leaves_the_others_alone():
    """A diverged vehicle (NaN x or y) gets NaN depth, not a garbage grid index."""
    cfg = IoUTConfig()
    terrain = make_terrain(cfg, (2,), generator=_gen(1), dtype=torch.float64)
    x = torch.tensor([[float("nan"), 0.0, 50.0], [10.0, float("nan"), 200.0]], dtype=torch.float64)
    y = torch.tensor([[0.0, float("nan"), 50.0], [10.0, float("nan"), 200.0]], dtype=torch.float64)
    got = seabed_depth(terrain, x, y, cfg)
    lost = x.isnan() | y.isnan()
    assert got[lost].isnan().all() and not got[~lost].isnan().any()
    finite_x, finite_y = x.nan_to_num(0.0), y.nan_to_num(0.0)
    torch.testing.assert_close(got[~lost], seabed_depth(terrain, finite_x, finite_y, cfg)[~lost])


def test_nodes_lie_on_the_seabed_with_spec_rates_and_fill():
    cfg = IoUTConfig()
    g = _gen(3)
    terrain = make_terrain(cfg, (16,), generator=g)
    nodes = sample_nodes(terrain, cfg, generator=g)
    pos = nodes["position"]
    assert nodes.batch_size == (16, 60)
    assert ((pos[..., :2] >= 0) & (pos[..., :2] <= 200)).all()
    torch.testing.assert_close(pos[..., 2], seabed_depth(terrain, pos[..., 0], pos[..., 1], cfg))
    rates = nodes["rate"]
    assert set(rates.unique().tolist()) == {4.0, 6.0, 9.0, 12.0}
    buffer = nodes["buffer"]
    assert (buffer >= 0).all() and (buffer <= 1000).all() and (buffer == buffer.round()).all()
    assert abs(buffer.mean().item() - 500.0) < 30.0  # 960 draws of U{0..1000}: sd of mean ~9.3
    assert (nodes["services"] == 0).all() and nodes["services"].dtype == torch.long


def test_poisson_arrivals_mean_matches_rate():
    rates = torch.tensor([4.0, 6.0, 9.0, 12.0], dtype=torch.float64)
    n = 20_000
    buffer = torch.zeros(n, 4, dtype=torch.float64)
    new, lost = data_arrivals(buffer, rates.expand(n, 4), 1e9, generator=_gen(4))
    assert (lost == 0).all() and (new == new.round()).all()
    mean = new.mean(0)
    sigma = torch.sqrt(rates / n)
    assert ((mean - rates).abs() < 5 * sigma).all(), (mean, rates)
    var = new.var(0)
    assert ((var / rates - 1).abs() < 0.1).all()  # Poisson: variance = mean


def test_overflow_counted_exactly_at_capacity():
    capacity = 5000.0
    buffer = torch.tensor([0.0, 4990.0, 4995.0, 5000.0, 4000.0] * 200, dtype=torch.float64)
    rate = torch.full_like(buffer, 9.0)
    # the same draws, once into an unbounded buffer to read the arrivals
    arrivals, _ = data_arrivals(torch.zeros_like(buffer), rate, 1e12, generator=_gen(5))
    new, lost = data_arrivals(buffer, rate, capacity, generator=_gen(5))
    expected_lost = (buffer + arrivals - capacity).clamp_min(0.0)
    torch.testing.assert_close(lost, expected_lost, rtol=0, atol=0)
    torch.testing.assert_close(
        new,
        torch.minimum(buffer + arrivals, torch.tensor(capacity, dtype=torch.float64)),
        rtol=0,
        atol=0,
    )
    torch.testing.assert_close(new + lost, buffer + arrivals, rtol=0, atol=0)
    assert (lost[3::5] == arrivals[3::5]).all()  # full buffer: every arrival overflows
    assert (lost[0::5] == 0).all() and (lost[1::5] > 0).any()  # 4990 + Poisson(9) > 5000 sometimes


def test_auv_start_positions_inside_and_apart():
    cfg = IoUTConfig(num_auvs=4)
    terrain = make_terrain(cfg, (32,), generator=_gen(6))
    pos = sample_auv_start(terrain, cfg, generator=_gen(7))
    assert pos.shape == (32, 4, 3)
    assert ((pos[..., :2] > 0) & (pos[..., :2] < 200)).all()
    assert ((pos[..., 2] >= 5.0) & (pos[..., 2] <= 10.0)).all()
    gap = (pos[:, :, None, :2] - pos[:, None, :, :2]).norm(dim=-1) + 1e9 * torch.eye(4)
    assert gap.amin() > 2 * 10.0 * math.sin(math.pi / 4) - 1e-3


def test_same_seed_same_scenes_and_global_rng_untouched(global_rng_guard):
    cfg = IoUTConfig()
    before = torch.random.get_rng_state().clone()
    with global_rng_guard:
        runs = []
        for _ in range(2):
            g = _gen(42)
            state, pos = reset_state(cfg, (4,), generator=g)
            for _ in range(5):
                state, events = step(state, pos, cfg, generator=g)
            runs.append((state, pos, events))
    assert torch.equal(torch.random.get_rng_state(), before)
    (s1, p1, e1), (s2, p2, e2) = runs
    assert torch.equal(p1, p2)
    assert (s1 == s2).all() and (e1 == e2).all()
    other, _ = reset_state(cfg, (4,), generator=_gen(43))
    assert not torch.equal(other["nodes", "position"], s1["nodes", "position"])


@pytest.mark.parametrize("batch", [(), (2, 3)])
def test_step_any_batch_shape_and_dtype(batch):
    from torchrl_auv.iout import TaskMetrics, task_cost

    cfg = IoUTConfig()
    g = _gen(8)
    state, pos = reset_state(cfg, batch, generator=g, dtype=torch.float64)
    assert state.batch_size == batch and state["nodes"].batch_size == (*batch, 60)
    metrics = TaskMetrics(cfg)
    acc = metrics.init(batch, dtype=torch.float64)
    for _ in range(3):
        state, events = step(state, pos, cfg, generator=g)
        speed = torch.ones(*batch, 2, dtype=torch.float64)
        acc = metrics.update(acc, events, speed, speed)
        cost, _ = task_cost(events, speed, cfg)
        assert cost.shape == (*batch, 2) and cost.dtype == torch.float64
    assert events["rate"].dtype == torch.float64 and events["overflow"].shape == batch
    out = metrics.finalize(acc)
    assert all(out[k].shape == batch for k in out.keys())


def test_collisions_and_violations_flags():
    from torchrl_auv.iout import collision_mask, violation_mask

    cfg = IoUTConfig(num_auvs=3)
    terrain = make_terrain(cfg, (), generator=_gen(9), dtype=torch.float64)
    bed = seabed_depth(
        terrain,
        torch.tensor([50.0], dtype=torch.float64),
        torch.tensor([60.0], dtype=torch.float64),
        cfg,
    ).item()
    pos = torch.tensor(
        [[50.0, 60.0, bed - 0.9], [50.0, 63.0, bed - 3.9], [150.0, 100.0, 1.5]],
        dtype=torch.float64,
    )
    assert violation_mask(pos, terrain, cfg).tolist() == [True, False, False]
    assert collision_mask(pos, cfg).tolist() == [True, True, False]  # 4.24 m: 3 m east, 3 m up
    pos[1, 1] = 64.1  # now 5.02 m apart
    assert collision_mask(pos, cfg).tolist() == [False, False, False]
    pos[1, 1] = 63.0
    pos[2, 1] = 200.5  # east of the area
    assert violation_mask(pos, terrain, cfg).tolist() == [True, False, True]
    pos[2, 1], pos[2, 2] = 100.0, 0.99  # too close to the surface
    assert violation_mask(pos, terrain, cfg)[2].item()
