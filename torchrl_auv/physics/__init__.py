"""Vehicle and ocean physics, as plain batched torch (no TorchRL import, no global RNG).

Owns the REMUS-100 6-DoF model (:mod:`torchrl_auv.physics.remus100`), the environment limits
that the model itself lacks (:mod:`torchrl_auv.physics.limits`), the ocean sea states
(:mod:`torchrl_auv.physics.ocean`), the vehicle in its ocean
(:mod:`torchrl_auv.physics.simulation`), the underwater acoustic link
(:mod:`torchrl_auv.physics.acoustics`) and the energy models used by the task metrics
(:mod:`torchrl_auv.physics.energy`). Every function takes tensors shaped ``[*B, ...]``,
follows the dtype and device of its inputs, and draws randomness only from a passed
:class:`torch.Generator`.
"""
