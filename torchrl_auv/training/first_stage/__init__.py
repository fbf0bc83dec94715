"""The diffusion recipes' first stage: the scripted expert's demonstrations, the proposer's
pretraining and DAgger rounds, built once per set of first-stage values and cached.

==========================  ========================================================================
module                      job
==========================  ========================================================================
``from_config``             the config's first-stage values, the cached build or ``proposer.path``
``build``                   building one: demonstrations, pretraining, DAgger rounds, into a folder
``artefacts``               :class:`ArtefactCache`: one folder per set of values, safe across
                            processes
==========================  ========================================================================

Examples:
    >>> from torchrl_auv.training.first_stage import values_key
    >>> values_key({"a": 1}) == values_key({"a": 1})
    True
"""

from __future__ import annotations

from torchrl_auv.training.first_stage.artefacts import (
    VALUES_FILE,
    ArtefactCache,
    check_values,
    differing_keys,
    values_key,
)
from torchrl_auv.training.first_stage.build import (
    build_first_stage,
    demonstrations_with_env_keys,
    untrained_proposer,
)
from torchrl_auv.training.first_stage.from_config import (
    FIRST_STAGE_DEFAULTS,
    FIRST_STAGE_FRAMES_FACT,
    FIRST_STAGE_VERSION,
    FirstStage,
    first_stage_frames,
    first_stage_from_config,
    first_stage_values,
    proposer_from_config,
)

__all__ = [
    "FIRST_STAGE_DEFAULTS",
    "FIRST_STAGE_FRAMES_FACT",
    "FIRST_STAGE_VERSION",
    "VALUES_FILE",
    "ArtefactCache",
    "FirstStage",
    "build_first_stage",
    "check_values",
    "demonstrations_with_env_keys",
    "differing_keys",
    "first_stage_frames",
    "first_stage_from_config",
    "first_stage_values",
    "proposer_from_config",
    "untrained_proposer",
    "values_key",
]
