"""The paper's published numbers (§IV), to print next to ours.

Table II: SDR (the paper's unit, "MBit/s", of its link-rate formula), EC (W) and SSN, mean and
standard deviation, per framework, controller and sea. Table III: yaw (rad) and depth (m)
tracking error, mean and standard deviation. Fig. 8: the episode return of each action
strategy (the paper's text, in units of 10^3). The paper defines neither its ES/VES seas nor
how many runs its ± covers; ours are in ``recipes/README.md``.

Examples:
    >>> TABLE2[("diffusion_lac", "s_surface", "ves")]["ssn"]
    (54.8, 5.9)
    >>> TABLE3[("sac", "pid")]["heading_error_mean"]
    0.58
    >>> FIG9["OA"]["ssn"], FIG9["CA4"]["sdr_mbit"]
    (67.0, 53.0)
"""

from __future__ import annotations

__all__ = ["FIG8_RETURN_E3", "FIG9", "TABLE2", "TABLE3"]


def _t2(sdr, sdr_std, ec, ec_std, ssn, ssn_std) -> dict[str, tuple[float, float]]:
    return {"sdr_mbit": (sdr, sdr_std), "ec_w": (ec, ec_std), "ssn": (ssn, ssn_std)}


#: (framework, controller, sea) -> metric -> (mean, std)
TABLE2 = {
    ("diffusion_rl", "s_surface", "es"): _t2(105.1, 14.7, 362.5, 22.8, 55.4, 9.5),
    ("diffusion_rl", "s_surface", "ves"): _t2(101.0, 7.5, 352.2, 6.5, 54.4, 6.5),
    ("diffusion_rl", "pid", "es"): _t2(88.6, 7.2, 257.1, 17.6, 44.5, 4.3),
    ("diffusion_rl", "pid", "ves"): _t2(86.1, 7.6, 246.7, 20.5, 43.6, 4.6),
    ("diffusion_rl", "smc", "es"): _t2(41.9, 7.0, 225.7, 13.5, 22.4, 3.1),
    ("diffusion_rl", "smc", "ves"): _t2(12.8, 5.2, 173.0, 11.8, 6.6, 2.7),
    ("diffusion_lac", "s_surface", "es"): _t2(110.6, 13.5, 371.9, 23.5, 57.1, 9.3),
    ("diffusion_lac", "s_surface", "ves"): _t2(102.3, 8.4, 349.0, 6.3, 54.8, 5.9),
    ("diffusion_lac", "pid", "es"): _t2(93.3, 6.1, 265.2, 16.2, 45.8, 4.4),
    ("diffusion_lac", "pid", "ves"): _t2(89.9, 7.2, 250.4, 18.7, 44.0, 4.2),
    ("diffusion_lac", "smc", "es"): _t2(50.2, 8.1, 240.5, 17.8, 25.4, 4.0),
    ("diffusion_lac", "smc", "ves"): _t2(23.7, 6.6, 201.8, 12.9, 13.4, 4.5),
}


def _t3(yaw, yaw_std, depth, depth_std) -> dict[str, float]:
    return {
        "heading_error_mean": yaw,
        "heading_error_std": yaw_std,
        "depth_error_mean": depth,
        "depth_error_std": depth_std,
    }


#: (framework, controller) -> metric -> value (the paper names no sea for Table III)
TABLE3 = {
    ("diffusion_rl", "smc"): _t3(0.25, 0.13, 2.05, 1.49),
    ("diffusion_rl", "pid"): _t3(0.51, 0.37, 1.95, 1.31),
    ("diffusion_rl", "s_surface"): _t3(0.12, 0.06, 1.59, 1.03),
    ("diffusion", "smc"): _t3(0.28, 0.14, 2.17, 1.48),
    ("diffusion", "pid"): _t3(0.57, 0.40, 2.08, 1.39),
    ("diffusion", "s_surface"): _t3(0.13, 0.05, 1.67, 1.15),
    ("diffusion_lac", "smc"): _t3(0.23, 0.10, 1.89, 1.42),
    ("diffusion_lac", "pid"): _t3(0.47, 0.32, 1.86, 1.21),
    ("diffusion_lac", "s_surface"): _t3(0.11, 0.05, 1.52, 0.94),
    ("sac", "smc"): _t3(0.27, 0.16, 2.12, 1.43),
    ("sac", "pid"): _t3(0.58, 0.42, 2.11, 1.37),
    ("sac", "s_surface"): _t3(0.10, 0.05, 1.70, 1.13),
}

#: Fig. 8: episode return (x 10^3) per action strategy, from the paper's text
FIG8_RETURN_E3 = {
    "OA": -4620.9,
    "CA1": -4931.1,
    "RL": -5193.4,
    "CA2": -5327.7,
    "CA3": -5665.0,
    "CA4": -8330.8,
}

#: Fig. 9: SDR ("MBit/s"), SSN and EC (W) per action strategy, from the paper's text (it gives
#: no CA3 numbers, and EC only for OA and CA4)
FIG9 = {
    "OA": {"sdr_mbit": 128.0, "ssn": 67.0, "ec_w": 417.0},
    "CA1": {"sdr_mbit": 121.0, "ssn": 64.0},
    "CA2": {"sdr_mbit": 113.0, "ssn": 60.0},
    "CA3": {},
    "CA4": {"sdr_mbit": 53.0, "ssn": 27.0, "ec_w": 378.0},
    "RL": {"sdr_mbit": 105.0, "ssn": 55.0},
}
