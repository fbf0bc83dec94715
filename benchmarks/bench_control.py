"""Controller + Kalman filter cost per physics step next to the dynamics step (float32).

Per physics step the environment runs one controller call, the onboard sensor draws (DVL,
depth, compass) and one KF predict + onboard update; a USBL fix and update happen once per
decision (every 20 physics steps) and are amortised here. Target (issue [3/9]): controller +
KF cost no more than the dynamics step itself at N = 1024.
"""

from __future__ import annotations

from _runner import measure, print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    import torch

    from torchrl_auv.control import make_controller
    from torchrl_auv.estimation import Localiser, SensorNoise, compass, depth_sensor, dvl, usbl_fix
    from torchrl_auv.physics import remus100

    min_time = 0.3 if args.quick else 1.0
    rows, ratios = [], {}
    for n in (1, 1024):
        gen = torch.Generator().manual_seed(0)
        eta = torch.zeros(n, 6)
        eta[:, 2] = 10.0
        nu = torch.zeros(n, 6)
        nu[:, 0] = 1.5
        act = torch.zeros(n, 3)
        setpoint = torch.tensor([12.0, 0.5, 1200.0]).expand(n, 3)
        current = torch.tensor([0.5, 1.0]).expand(n, 2)
        noise = SensorNoise()
        loc = Localiser(noise)
        mean, cov = loc.init(eta[:, :3])
        asv = torch.zeros(n, 3)

        def dynamics_step():
            return remus100.step(eta, nu, act, setpoint, current, 0.05)

        def kf_step():
            m, c = loc.predict(mean, cov, 0.05)
            att = torch.stack((eta[:, 3], eta[:, 4], compass(eta[:, 5], noise.compass, gen)), -1)
            return loc.update_onboard(
                m, c, dvl(nu, noise.dvl, gen), att, depth_sensor(eta[:, 2], noise.depth, gen)
            )

        def usbl_step():
            fix, fcov, ok = usbl_fix(eta[:, :3], asv, 0.005, 0.0017, gen)
            return loc.update_usbl(mean, cov, fix, fcov, ok)

        t_step = measure(dynamics_step, min_time=min_time).median
        t_kf = measure(kf_step, min_time=min_time).median
        t_usbl = measure(usbl_step, min_time=min_time).median / 20
        for name in ("s_surface", "pid", "smc"):
            ctrl = make_controller(name)
            memory = ctrl.init_memory((n,))
            t_ctrl = measure(
                lambda c=ctrl, m=memory: c(setpoint, eta, nu, m, 0.05), min_time=min_time
            ).median
            total = t_ctrl + t_kf + t_usbl
            ratios[(name, n)] = total / t_step
            rows.append(
                [
                    n,
                    name,
                    f"{t_step * 1e6:.0f}",
                    f"{t_ctrl * 1e6:.0f}",
                    f"{t_kf * 1e6:.0f}",
                    f"{t_usbl * 1e6:.1f}",
                    f"{total / t_step:.2f}",
                ]
            )
    print_table(
        "Per physics step, 1 thread, float32 (us); ratio = (controller + KF) / dynamics step",
        ["N", "controller", "step", "ctrl", "KF+sensors", "USBL/20", "ratio"],
        rows,
    )
    print_summary(
        "bench_control",
        **{f"ratio_{name}_N{n}": v for (name, n), v in ratios.items()},
    )


if __name__ == "__main__":
    main()
