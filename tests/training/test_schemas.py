"""The typed config schemas (``torchrl_auv.training.schemas``): one definition of a group that
every recipe composes, its types checked when a config is composed."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigAttributeError, ValidationError

from torchrl_auv.training import SCHEMAS, ProposerConfig, first_stage_values

RECIPES = Path(__file__).resolve().parents[2] / "recipes"
DIFFUSION_RECIPES = ["diffusion", "diffusion_rl", "diffusion_lac"]


ALL_RECIPES = ["sac", *DIFFUSION_RECIPES]
SCHEMA_TYPES = {schema for _, _, schema in SCHEMAS}


def _compose(recipe: str, overrides: list[str], preset: str = "paper"):
    with initialize_config_dir(config_dir=str(RECIPES / recipe), version_base="1.3"):
        return compose(preset, overrides)


@pytest.mark.parametrize("preset", ["paper", "quick", "fast"])
@pytest.mark.parametrize("recipe", ALL_RECIPES)
def test_every_group_of_every_recipe_is_a_registered_schema(recipe, preset):
    cfg = _compose(recipe, [], preset)
    groups = {key: OmegaConf.get_type(cfg[key]) for key in cfg if isinstance(cfg[key], DictConfig)}
    assert groups, "the recipe has no config group"
    assert {key: schema for key, schema in groups.items() if schema not in SCHEMA_TYPES} == {}


@pytest.mark.parametrize("recipe", DIFFUSION_RECIPES)
def test_a_proposer_value_of_the_wrong_type_is_refused_naming_the_key(recipe):
    with pytest.raises(ConfigCompositionException) as error:
        _compose(recipe, ["proposer.hidden=wide"])
    assert "proposer.hidden" in str(error.value.__cause__ or error.value)


@pytest.mark.parametrize("recipe", DIFFUSION_RECIPES)
def test_a_proposer_key_the_schema_lacks_is_refused(recipe):
    with pytest.raises(ConfigCompositionException) as error:
        _compose(recipe, ["proposer.hiden=128"])
    assert "hiden" in str(error.value.__cause__ or error.value)


def test_the_schema_refuses_wrong_types_and_unknown_keys_outside_hydra_too():
    cfg = OmegaConf.structured(ProposerConfig)
    with pytest.raises(ValidationError, match="hidden"):
        cfg.hidden = "wide"
    with pytest.raises(ConfigAttributeError, match="hiden"):
        cfg.hiden = 128


@pytest.mark.parametrize("preset", ["paper", "quick", "fast"])
def test_the_first_stage_of_the_three_diffusion_recipes_is_one_artefact(preset):
    """One definition of the group: the three recipes key the same first stage."""
    values = [first_stage_values(_compose(r, [], preset)) for r in DIFFUSION_RECIPES]
    assert values[0] == values[1] == values[2]


def test_a_plain_config_without_the_group_keys_the_paper_presets_first_stage():
    """The library's defaults for a config without the group (a dict, no Hydra) are the schema's,
    so they key the same first stage as the paper preset."""
    paper = _compose("diffusion", ["env.sea_state=ves"])
    plain = {"seed": 0, "env": {"sea_state": "ves", "controller": "s_surface"}}
    assert first_stage_values(plain) == first_stage_values(paper)


@pytest.mark.parametrize(("sea", "rounds"), [("ideal", 0), ("es", 1), ("ves", 1)])
def test_a_plain_config_takes_the_schemas_dagger_rounds_for_its_sea(sea, rounds):
    values = first_stage_values({"env": {"sea_state": sea}})
    assert values["dagger"]["dagger_rounds"] == rounds


def test_a_sea_without_dagger_rounds_is_named():
    with pytest.raises(ValueError, match=r"proposer\.dagger_rounds_per_sea has no entry.*'es'"):
        first_stage_values(
            {"env": {"sea_state": "es"}, "proposer": {"dagger_rounds_per_sea": {"ves": 1}}}
        )
