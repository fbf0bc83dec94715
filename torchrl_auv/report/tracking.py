"""The paper's Table III experiment: heading/depth tracking per controller and sea state.

Each controller runs the fixed 300 s :func:`~torchrl_auv.control.scenarios.tracking_schedule`
on the REMUS-100 in the ``ideal``, ``es`` and ``ves`` sea states, seeing the vehicle through
its sensors and the Kalman filter (:class:`KalmanObserver`), and the table reports mean and
standard deviation of the absolute heading error (rad) and depth error (m) between the setpoints and
the *true* state over all physics steps, averaged over independent runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch

from torchrl_auv.control import make_controller, wrap_angle
from torchrl_auv.control.scenarios import Trace, simulate, tracking_errors, tracking_schedule
from torchrl_auv.estimation import (
    Localiser,
    SensorNoise,
    compass,
    depth_sensor,
    dvl,
    dvl_bottom_lock,
    gnss_error_init,
    gnss_error_step,
    usbl_fix_from_asv,
)
from torchrl_auv.physics import ocean
from torchrl_auv.physics.remus100 import rotation_matrix
from torchrl_auv.report.pyplot import pyplot

__all__ = ["KalmanObserver", "plot_tracking", "tracking_table"]


class KalmanObserver:
    """Sensors plus the :class:`~torchrl_auv.estimation.Localiser`, as a ``simulate`` observer.

    Every physics step: KF predict, then a DVL + depth + compass update; every
    ``fix_every`` steps a USBL fix from an ASV at the surface (``asv_offset`` m north of the
    vehicle, keeping station) with the sea state's errors
    (:func:`~torchrl_auv.estimation.usbl_fix_from_asv`: range and bearing noise with the ASV's
    attitude residual, dropouts, and the ASV's Gauss-Markov GNSS error as the fix's bias). The
    DVL has bottom lock everywhere unless ``seabed_depth`` (m) is given; then only where the
    altitude ``seabed_depth - z`` is at most ``noise.dvl_range``. The controller gets
    ``eta_hat = [KF position, roll, pitch, compass heading]`` and
    ``nu_hat = [R^T v_KF, p, q, r]`` (attitude and rates from the AHRS are taken as exact).

    >>> obs = KalmanObserver("es", (2,), generator=torch.Generator().manual_seed(0))
    >>> eta_hat, nu_hat = obs(torch.zeros(2, 6), torch.zeros(2, 6), 0)
    >>> eta_hat.shape
    torch.Size([2, 6])
    """

    def __init__(
        self,
        sea_state,
        batch_shape,
        *,
        generator: torch.Generator,
        dt: float = 0.05,
        fix_every: int = 20,
        asv_offset: float = 30.0,
        noise: SensorNoise | None = None,
        seabed_depth: float | None = None,
    ) -> None:
        self.sea = ocean.get_sea_state(sea_state)
        self.generator = generator
        self.dt = dt
        self.fix_every = fix_every
        self.asv_offset = asv_offset
        self.noise = SensorNoise() if noise is None else noise
        self.localiser = Localiser(self.noise)
        self.seabed_depth = seabed_depth
        self.batch_shape = tuple(batch_shape)
        self.mean = self.cov = self.gnss_error = None
        self.usbl_error_sq: list[float] = []
        self.kf_error_sq: list[float] = []

    def __call__(self, eta: torch.Tensor, nu: torch.Tensor, k: int):
        g, noise, loc = self.generator, self.noise, self.localiser
        if self.mean is None:
            self.mean, self.cov = loc.init(eta[..., :3], position_sigma=1.0)
        else:
            self.mean, self.cov = loc.predict(self.mean, self.cov, self.dt)
        heading = compass(eta[..., 5], noise.compass, g)
        attitude = torch.stack((eta[..., 3], eta[..., 4], heading), -1)
        locked = None
        if self.seabed_depth is not None:
            locked = dvl_bottom_lock(self.seabed_depth - eta[..., 2], noise.dvl_range)
        self.mean, self.cov = loc.update_onboard(
            self.mean,
            self.cov,
            dvl(nu, noise.dvl, g),
            attitude,
            depth_sensor(eta[..., 2], noise.depth, g),
            dvl_valid=locked,
        )
        if k % self.fix_every == 0:
            sea = self.sea
            if self.gnss_error is None:
                self.gnss_error = gnss_error_init(
                    (*eta.shape[:-1], 2), sea.gnss_sigma, g, dtype=eta.dtype
                )
            else:
                self.gnss_error = gnss_error_step(
                    self.gnss_error,
                    sea.gnss_sigma,
                    sea.gnss_time_constant,
                    self.fix_every * self.dt,
                    g,
                )
            asv = torch.zeros_like(eta[..., :3])
            asv[..., 0] = eta[..., 0] + self.asv_offset
            asv[..., 1] = eta[..., 1]
            fix, fix_cov, valid = usbl_fix_from_asv(eta[..., :3], asv, self.gnss_error, sea, g)
            self.mean, self.cov = loc.update_usbl(self.mean, self.cov, fix, fix_cov, valid)
            if valid.any():  # the raw fixes' error, over the fixes that arrived
                self.usbl_error_sq.append(
                    (fix - eta[..., :3])[valid].square().sum(-1).mean().item()
                )
            self.kf_error_sq.append(
                (self.mean[..., :3] - eta[..., :3]).square().sum(-1).mean().item()
            )
        rot = rotation_matrix(attitude)
        v_body = (rot.transpose(-1, -2) @ self.mean[..., 3:].unsqueeze(-1)).squeeze(-1)
        eta_hat = torch.cat([self.mean[..., :3], attitude], -1)
        nu_hat = torch.cat([v_body, nu[..., 3:]], -1)
        return eta_hat, nu_hat

    def rms(self) -> tuple[float, float]:
        """RMS position error (m) of the KF and of the raw USBL fixes (those that arrived), at
        fix times."""
        mean = lambda xs: sum(xs) / max(len(xs), 1)  # noqa: E731
        return mean(self.kf_error_sq) ** 0.5, mean(self.usbl_error_sq) ** 0.5


def tracking_table(
    controllers: Sequence[str] = ("s_surface", "pid", "smc"),
    sea_states: Sequence[str] = ("ideal", "es", "ves"),
    *,
    runs: int = 4,
    seed: int = 0,
    duration: float = 300.0,
    localised: bool = True,
) -> tuple[list[dict[str, object]], dict[tuple[str, str], Trace]]:
    """Run the Table III experiment; return one row per (sea state, controller) and traces.

    Rows hold ``sea_state``, ``controller``, the four error statistics (mean over ``runs``
    independent runs), and, when ``localised``, ``kf_rms`` and ``usbl_rms`` (m).

    >>> rows, _ = tracking_table(("pid",), ("ideal",), runs=1, duration=5.0)
    >>> sorted(rows[0])[:3]
    ['controller', 'depth_error_mean', 'depth_error_std']
    """
    rows, traces = [], {}
    for sea in sea_states:
        for name in controllers:
            generator = torch.Generator().manual_seed(seed)
            observer = KalmanObserver(sea, (runs,), generator=generator) if localised else None
            trace = simulate(
                make_controller(name),
                tracking_schedule(),
                duration,
                sea_state=sea,
                batch_shape=(runs,),
                start_depth=10.0,
                generator=generator,
                observer=observer,
            )
            errors = {k: v.mean().item() for k, v in tracking_errors(trace).items()}
            row: dict[str, object] = {"sea_state": sea, "controller": name, **errors}
            if observer is not None:
                row["kf_rms"], row["usbl_rms"] = observer.rms()
            rows.append(row)
            traces[(sea, name)] = trace
    return rows, traces


def plot_tracking(traces: dict[tuple[str, str], Trace], sea_state: str, path: str | Path) -> Path:
    """Depth and heading of the first run of each controller against the setpoints (PNG)."""
    plt = pyplot()

    fig, (ax_z, ax_psi) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    first = True
    for (sea, name), trace in traces.items():
        if sea != sea_state:
            continue
        t = trace.time.numpy()
        if first:
            ax_z.plot(t, trace.setpoint[:, 0, 0].numpy(), "k--", label="setpoint")
            ax_psi.plot(t, torch.rad2deg(trace.setpoint[:, 0, 1]).numpy(), "k--", label="setpoint")
            first = False
        ax_z.plot(t, trace.eta[:, 0, 2].numpy(), label=name)
        ax_psi.plot(t, torch.rad2deg(wrap_angle(trace.eta[:, 0, 5])).numpy(), ".", ms=1, label=name)
    ax_z.invert_yaxis()
    ax_z.set_ylabel("depth (m)")
    ax_psi.set_ylabel("heading (deg, wrapped)")
    ax_psi.set_xlabel("time (s)")
    ax_z.legend(loc="best")
    ax_z.set_title(f"Tracking, sea state '{sea_state}' (true state, KF in the loop)")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
