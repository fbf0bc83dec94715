r"""Ocean disturbances: sea-state presets, a Gauss-Markov current and JONSWAP waves, batched.

The paper names three sea states (ideal, extreme, very extreme) without defining them; the values
here are the project's choices recorded in ``docs/spec/data_collection.md`` ("Disturbances").
Everything is batched over scene dims ``[*B]``, follows the requested dtype and device, and draws
randomness only from the ``torch.Generator`` passed in (never from the global RNG).

**Current** (horizontal, NED). Speed :math:`V` and direction :math:`\beta` (rad, the direction
the water flows *towards*, clockwise from north, as :func:`torchrl_auv.physics.remus100.step`
reads it) are each a first-order Gauss-Markov process around their means, discretised exactly,

.. math::

    x_{k+1} = \mu + e^{-h/T}(x_k - \mu) + \sigma\sqrt{1 - e^{-2h/T}}\,w_k,\qquad
    w_k \sim \mathcal N(0, 1),

and started from the stationary distribution :math:`\mathcal N(\mu, \sigma^2)`, so the process is
stationary from the first step. Both share the time constant :math:`T`. The mean direction
:math:`\bar\beta` is drawn uniformly in :math:`[-\pi, \pi)` per scene unless
:attr:`SeaState.current_direction_mean` fixes it. The direction's spread (0.2 rad in ``es``,
0.3 rad in ``ves``) is ours. ``current_time_constant=math.inf`` gives a current that is constant
within an episode but drawn per episode.

**Waves.** A JONSWAP spectrum :math:`S(\omega)` (:func:`jonswap_spectrum`) with
:math:`\cos^2` spreading :math:`D(\theta) = \tfrac{2}{\pi}\cos^2(\theta - \bar\theta)` over
:math:`|\theta - \bar\theta| < \pi/2`, sampled once per episode into
``n_frequencies x n_directions`` components :math:`j = (i, l)`:

* frequency: the spectrum is cut into ``n_frequencies`` bins of equal energy
  :math:`m_0/N_f`; every component draws its own frequency from the spectral density inside its
  bin (stratified inverse-CDF sampling, :math:`\omega_{il} = F^{-1}((i + U_{il})/N_f)`,
  :math:`U_{il} \sim \mathcal U(0, 1)`). Distinct frequencies keep the sea ergodic (time
  averages at a point equal the spectral moments), and :math:`\mathbb E[\sum_j a_j^2\omega_j^2/2]
  = m_2` exactly;
* direction: bin centres :math:`\theta_l = \bar\theta - \pi/2 + (l + \tfrac12)\pi/N_d` with
  weights :math:`D(\theta_l)\Delta\theta` normalised to sum to one (for :math:`N_d \ge 2` the
  normalisation is already exact);
* amplitude :math:`a_j = \sqrt{2\,S(\omega)\Delta\omega\,D(\theta_l)\Delta\theta}
  = \sqrt{2\,(m_0/N_f)\,D(\theta_l)\Delta\theta}`, hence :math:`\sum_j a_j^2/2 = m_0 = H_s^2/16`
  exactly in every scene;
* wavenumber :math:`k_j` from the linear dispersion relation in water of depth :math:`h`
  (:func:`wavenumber`), :math:`\omega_j^2 = g k_j \tanh(k_j h)`, solved once per episode; deep
  water (``water_depth=None``, the default, or :math:`h = \infty`) gives :math:`k_j =
  \omega_j^2/g`; and a uniform random phase :math:`\varphi_j`.

The mean wave direction :math:`\bar\theta` equals the mean current direction :math:`\bar\beta`
(ours: wind sea and wind-driven current run together). With the phase
:math:`\chi_j = k_j(x\cos\theta_j + y\sin\theta_j) - \omega_j t + \varphi_j`, the water depth
:math:`h` (m) and :math:`d = \min(\max(z, 0), h)` the depth of the point (NED :math:`z`, positive
down; points above the surface get the surface value, points below the seabed the seabed
value), linear finite-depth (Airy) theory gives (spec v2, "Disturbances")

.. math::

    \eta = \sum_j a_j\cos\chi_j,\qquad
    \begin{bmatrix}u_N \ u_E\end{bmatrix} = V\begin{bmatrix}\cos\beta \ \sin\beta\end{bmatrix}
    + \sum_j a_j\omega_j\,\frac{\cosh k_j(h - d)}{\sinh k_j h}\,\cos\chi_j
    \begin{bmatrix}\cos\theta_j \ \sin\theta_j\end{bmatrix},\qquad
    u_D = -\sum_j a_j\omega_j\,\frac{\sinh k_j(h - d)}{\sinh k_j h}\,\sin\chi_j .

The depth profiles are evaluated with decaying exponentials only (no overflow, and exactly the
deep-water :math:`e^{-k_j d}` for :math:`h = \infty`):

.. math::

    \frac{\cosh k(h - d)}{\sinh kh} = \frac{e^{-kd} + e^{-k(2h - d)}}{1 - e^{-2kh}},\qquad
    \frac{\sinh k(h - d)}{\sinh kh} = \frac{e^{-kd} - e^{-k(2h - d)}}{1 - e^{-2kh}},\qquad
    e^{-k(2h - d)} = \frac{e^{-2kh}}{e^{-kd}} ;

the depth-only factors :math:`e^{-2kh}` and :math:`1/(1 - e^{-2kh})` can be computed once for a
fixed depth (:func:`seabed_factors`), leaving one exponential per component per evaluation.
At the seabed (:math:`d = h`) the vertical velocity is zero (to rounding) and the horizontal
one is :math:`a\omega/\sinh kh`; in deep water both decay as :math:`e^{-kd}` and the orbits are
circles. At the project's depths (39-58 m, :math:`T_p` 10-12 s, :math:`kh \approx 1.3`-2.4 at
the peak) deep-water theory underestimates the near-bed horizontal orbital velocity: at the
``ves`` peak (12 s) in 45 m of water by 37 % 5 m above the bed and 45 % at the bed.

*Slowly varying depth.* :func:`reset_ocean` takes one depth per scene (``water_depth``, e.g.
the scene's mean seabed depth) and solves the dispersion relation with it; the velocity
functions take an optional *local* depth (the seabed under the vehicle) for the profiles
only, while the phases keep the scene's wavenumbers. This is the slowly-varying-depth
approximation without refraction or shoaling (no change of :math:`k`, direction or amplitude
over the terrain): fine for seabeds that vary by 39-58 m over 80-400 m wavelengths, not for
steep slopes.

**Ideal.** ``ideal`` has zero current (mean and spread) and :math:`H_s = 0`: every velocity is
exactly zero, :func:`current_at` returns exactly ``[0, 0, 0]`` (all ``+0``), and the state keeps
its full batched shape (the same keys and random draws as the other sea states).

**Common random numbers.** :func:`reset_ocean` and :func:`step_ocean` draw the same random
numbers in the same order for every sea state, so one seed gives matching scenes across
``ideal``, ``es`` and ``ves`` (same phases, frequency quantiles and normalised current anomaly).

:func:`current_at` returns what :func:`torchrl_auv.physics.remus100.step` takes: the total
water velocity at the vehicle as ``[speed, direction, w_down]`` (the horizontal part as speed
and direction, plus the vertical orbital velocity, m/s positive down).
"""

from __future__ import annotations

from torchrl_auv.physics.ocean.fields import (
    current_at,
    current_from_state,
    seabed_factors,
    surface_elevation_at,
    water_velocity_at,
)
from torchrl_auv.physics.ocean.sea_states import SEA_STATES, SeaState, get_sea_state
from torchrl_auv.physics.ocean.spectrum import GRAVITY, jonswap_spectrum, wavenumber
from torchrl_auv.physics.ocean.state import advance_current, reset_ocean, step_ocean

__all__ = [
    "GRAVITY",
    "SEA_STATES",
    "SeaState",
    "advance_current",
    "current_at",
    "current_from_state",
    "get_sea_state",
    "jonswap_spectrum",
    "reset_ocean",
    "seabed_factors",
    "step_ocean",
    "surface_elevation_at",
    "water_velocity_at",
    "wavenumber",
]
