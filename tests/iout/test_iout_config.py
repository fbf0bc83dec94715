"""IoUTConfig: spec defaults and bad input naming the field."""

from __future__ import annotations

import pytest

from torchrl_auv.iout import CostWeights, ExpertConfig, IoUTConfig


def test_defaults_are_the_spec_values():
    cfg = IoUTConfig()
    assert cfg.area_m == (200.0, 200.0)
    assert cfg.seabed_depth_range_m == (39.0, 58.0)
    assert (cfg.num_sensors, cfg.num_auvs) == (60, 2)
    assert cfg.arrival_rates == (4.0, 6.0, 9.0, 12.0)
    assert cfg.buffer_capacity == 5000 and cfg.initial_fill_range == (0, 1000)
    assert (cfg.priority_rate_weight, cfg.priority_distance_weight) == (1.0, 0.05)
    assert cfg.service_radius_m == 18.0 and cfg.data_volume_bits == 2e6
    assert (cfg.carrier_khz, cfg.bandwidth_hz, cfg.shipping, cfg.wind_mps) == (20, 1000, 0.5, 0)
    assert (cfg.source_power_w, cfg.source_level_offset_db) == (0.09, 170.77)
    assert cfg.rate_model == "shannon"
    assert (cfg.collision_distance_m, cfg.clearance_m) == (5.0, 1.0)
    assert cfg.packet_bits == 400.0  # Q / C_max
    assert cfg.episode_decisions == 1000


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"num_auvs": 0}, "num_auvs"),
        ({"num_auvs": -2}, "num_auvs"),
        ({"num_sensors": 0}, "num_sensors"),
        ({"area_m": (-200.0, 200.0)}, "area_m"),
        ({"area_m": (200.0, 0.0)}, "area_m"),
        ({"rate_model": "magic"}, "rate_model"),
        ({"seabed_depth_range_m": (58.0, 39.0)}, "seabed_depth_range_m"),
        ({"buffer_capacity": 0}, "buffer_capacity"),
        ({"initial_fill_range": (0, 6000)}, "initial_fill_range"),
        ({"arrival_rates": ()}, "arrival_rates"),
        ({"arrival_rates": (4.0, -1.0)}, "arrival_rates"),
        ({"service_radius_m": 0.0}, "service_radius_m"),
        ({"data_volume_bits": -1.0}, "data_volume_bits"),
        ({"decision_dt_s": 0.0}, "decision_dt_s"),
        ({"priority_distance_weight": -0.05}, "priority_distance_weight"),
        ({"clearance_m": -1.0}, "clearance_m"),
        ({"shipping": 2.0}, "shipping"),
        ({"terrain_grid_points": 1}, "terrain_grid_points"),
        ({"auv_start_margin_m": 150.0}, "auv_start_margin_m"),
        ({"auv_start_depth_range_m": (5.0, 45.0)}, "auv_start_depth_range_m"),
    ],
)
def test_bad_config_names_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        IoUTConfig(**kwargs)


def test_bad_weights_name_the_field():
    with pytest.raises(ValueError, match="collision"):
        CostWeights(collision=-1.0)
    with pytest.raises(ValueError, match="reference_power_w"):
        CostWeights(reference_power_w=0.0)
    with pytest.raises(ValueError, match="repulsion_radius_m"):
        ExpertConfig(repulsion_radius_m=0.0)


def test_config_is_frozen():
    cfg = IoUTConfig()
    with pytest.raises(AttributeError):
        cfg.num_auvs = 3  # type: ignore[misc]
