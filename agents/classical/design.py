"""Controller design from plant parameters: plain functions over the nominal plant (SI, command units)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from frictiongym.envs.plants import PlantSpec


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


def pd_from_stiffness(J: float, c: float, b: float, kp_nm_per_rad: float, zeta: float) -> PIDGains:
    """PD for a given position stiffness K_p (N·m/rad), ω_n = sqrt(K_p/J), K_d for damping ζ incl. c
    (Kang §6: K_p resolved from the printed bounds θ_H/θ_L)."""
    wn = math.sqrt(kp_nm_per_rad / J)
    return PIDGains(kp=kp_nm_per_rad / b, ki=0.0, kd=(2 * zeta * wn * J - c) / b)


def pid_by_pole_placement(J: float, c: float, b: float, wn: float, zeta: float, ratio: float) -> PIDGains:
    """PID for J s² + c s = b u with poles (s + a)(s² + 2ζω_n s + ω_n²), a = ratio·ω_n."""
    a = ratio * wn
    return PIDGains(
        kp=J * (wn**2 + 2 * zeta * wn * a) / b, ki=J * a * wn**2 / b, kd=(J * (2 * zeta * wn + a) - c) / b
    )


def pi_speed_loop(J: float, c: float, b: float, k_sensor: float, wn: float, zeta: float) -> PIDGains:
    """PI on a speed reading y = k_sensor·ω of J ω' + c ω = b u: poles s² + 2ζω_n s + ω_n²."""
    return PIDGains(kp=(2 * zeta * wn * J - c) / (b * k_sensor), ki=J * wn**2 / (b * k_sensor), kd=0.0)
