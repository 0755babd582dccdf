"""Controller design from plant parameters: plain functions over the nominal plant (SI, command units)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from frictiongym.envs.config import load_yaml
from frictiongym.envs.plants import PlantSpec


def controller_config() -> dict:
    """configs/controllers.yaml."""
    from frictiongym.envs.config import configs_dir

    return load_yaml(configs_dir() / "controllers.yaml")


@dataclass(frozen=True)
class PIDGains:
    """u = kp·e + ki·∫e dt + kd·de/dt, e = r - y, in command units per unit of the tracked reading."""

    kp: float
    ki: float
    kd: float


def rigid_position_plant(spec: PlantSpec) -> tuple[float, float, float]:
    """(J, c, b): J·θ'' + c·θ' = b·u for the drive seen as one rigid body (kg·m², N·m·s/rad, N·m per unit)."""
    J = spec.reflected_inertia(spec.actuator_joint)
    ratios = spec.kinematic_ratios()
    c = sum(j.viscous * ratios.get(j.name, 0.0) ** 2 for j in spec.joints)
    c += sum((j.friction.sigma2 if j.friction else 0.0) * ratios.get(j.name, 0.0) ** 2 for j in spec.joints)
    return J, c, spec.actuator_gain


def pd_by_pole_placement(J: float, c: float, b: float, wn: float, zeta: float) -> PIDGains:
    """PD for J s² + c s = b u: closed loop J s² + (c + b·kd) s + b·kp = J (s² + 2ζω_n s + ω_n²)."""
    return PIDGains(kp=J * wn**2 / b, ki=0.0, kd=(2 * zeta * wn * J - c) / b)


def pid_by_pole_placement(J: float, c: float, b: float, wn: float, zeta: float, ratio: float) -> PIDGains:
    """PID for J s² + c s = b u with poles (s + a)(s² + 2ζω_n s + ω_n²), a = ratio·ω_n."""
    a = ratio * wn
    return PIDGains(
        kp=J * (wn**2 + 2 * zeta * wn * a) / b, ki=J * a * wn**2 / b, kd=(J * (2 * zeta * wn + a) - c) / b
    )


def pi_speed_loop(J: float, c: float, b: float, k_sensor: float, wn: float, zeta: float) -> PIDGains:
    """PI on a speed reading y = k_sensor·ω of J ω' + c ω = b u: poles s² + 2ζω_n s + ω_n²."""
    return PIDGains(kp=(2 * zeta * wn * J - c) / (b * k_sensor), ki=J * wn**2 / (b * k_sensor), kd=0.0)


def kang_pd(spec: PlantSpec, zeta: float) -> PIDGains:
    """Kang §6: K_p resolved from θ_H/θ_L (kang_robot.yaml), K_d for damping ζ incl. viscous friction."""
    J, c, b = rigid_position_plant(spec)
    kp = spec.info["kp_nm_per_rad"]
    wn = math.sqrt(kp / J)
    return PIDGains(kp=kp / b, ki=0.0, kd=(2 * zeta * wn * J - c) / b)
