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


# ---------------------------------------------------------------------------------------------------------
# Wallenborg (seed 002): state feedback + observer by pole placement, continuous (§4.1) and digital (§4.2)


def flexible_state_space(spec: PlantSpec, sensor: str = "y1"):
    """(A, B, C) of seed 002 eq. (3.1) from the plant parameters; x = (ω1, ω2, θ2 - θ1), u in V, y in V."""
    import numpy as np

    J1, J2 = (j.inertia for j in spec.joints)
    d1, d2 = (j.viscous for j in spec.joints)
    k, d = spec.springs[0].stiffness, spec.springs[0].damping
    A = np.array([[-(d1 + d) / J1, d / J1, k / J1], [d / J2, -(d2 + d) / J2, -k / J2], [-1.0, 1.0, 0.0]])
    B = np.array([[spec.actuator_gain / J1], [0.0], [0.0]])
    C = (
        np.array([[spec.info["k_w1"], 0.0, 0.0]])
        if sensor == "y1"
        else np.array([[0.0, spec.info["k_w2"], 0.0]])
    )
    return A, B, C


def wallenborg_poles(w: float, zeta: float):
    """(s + w)(s² + 2ζw s + w²), the pole pattern of §4.1 (α_cl = ω_cl)."""
    import numpy as np

    wd = w * np.sqrt(1 - zeta**2)
    return np.array([-w, -zeta * w + 1j * wd, -zeta * w - 1j * wd])


@dataclass(frozen=True)
class StateFeedbackDesign:
    """u = l_r·y_r - L x̂; continuous observer x̂' = A x̂ + B u + K (y - C x̂), or for h > 0 the digital
    observer with the latest measurement (eq. 4.3): x̂(k|k) = x̂(k|k-1) + K (y - C x̂(k|k-1)),
    x̂(k+1|k) = Φ x̂(k|k) + Γ u (Φ, Γ the ZOH sampling of A, B)."""

    A: object
    B: object
    C: object
    L: object
    K: object
    lr: float
    h: float = 0.0
    Phi: object = None
    Gamma: object = None


def state_feedback_design(
    spec: PlantSpec, w_cl: float, zeta: float = 0.7, alpha: float = 1.5, sensor: str = "y1", h: float = 0.0
) -> StateFeedbackDesign:
    """Pole placement of §4.1 (h = 0) or §4.2 (h > 0, poles mapped by z = e^{sh}); l_r gives unit
    steady-state gain from y_r to the measured output."""
    import control
    import numpy as np

    A, B, C = flexible_state_space(spec, sensor)
    pc, po = wallenborg_poles(w_cl, zeta), wallenborg_poles(alpha * w_cl, zeta)
    if h == 0:
        L = control.place(A, B, pc)
        K = control.place(A.T, C.T, po).T
        lr = 1.0 / (C @ np.linalg.solve(B @ L - A, B)).item()
        return StateFeedbackDesign(A, B, C, L, K, lr)
    sysd = control.c2d(control.ss(A, B, C, 0), h, method="zoh")
    Phi, Gamma = np.asarray(sysd.A), np.asarray(sysd.B)
    L = control.place(Phi, Gamma, np.exp(pc * h))
    M = control.place(Phi.T, C.T, np.exp(po * h)).T  # eig(Φ - M C), M = Φ K
    K = np.linalg.solve(Phi, M)
    lr = 1.0 / (C @ np.linalg.solve(np.eye(3) - Phi + Gamma @ L, Gamma)).item()
    return StateFeedbackDesign(A, B, C, L, K, lr, h, Phi, Gamma)


def regulator_poles(spec: PlantSpec, w_cl: float, zeta: float = 0.7, alpha: float = 1.5, sensor: str = "y1"):
    """Poles of the (continuous) regulator itself, det(sI - A + BL + KC) = 0 (seed 002 eq. 6.1)."""
    import numpy as np

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    return np.linalg.eigvals(d.A - d.B @ d.L - d.K @ d.C)


def regulator_stability_boundary(
    spec: PlantSpec, lo: float, hi: float, sensor: str = "y1", tol: float = 1e-4
) -> float:
    """ω_cl at which the regulator's stability changes between lo and hi (bisection; §6.1-6.2)."""
    import numpy as np

    def stable(w: float) -> bool:
        return bool(np.all(regulator_poles(spec, w, sensor=sensor).real < 0))

    s_lo = stable(lo)
    if stable(hi) == s_lo:
        raise ValueError(f"regulator stability does not change between {lo} and {hi} rad/s")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) == s_lo else (lo, mid)
    return 0.5 * (lo + hi)


def friction_loop_response(
    spec: PlantSpec, w_cl: float, omega, sensor: str = "y1", zeta: float = 0.7, alpha: float = 1.5
):
    """G(jω) of seed 002 eq. (5.3): friction torque on shaft 1 (N·m) -> y1 (V), regulator in the loop."""
    import numpy as np

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    J1 = spec.joints[0].inertia
    Bf = np.array([[1.0 / J1], [0.0], [0.0]])
    Acl = np.block([[d.A, -d.B @ d.L], [d.K @ d.C, d.A - d.B @ d.L - d.K @ d.C]])
    Bcl = np.vstack([Bf, np.zeros((3, 1))])
    C1 = np.hstack([np.array([[spec.info["k_w1"], 0.0, 0.0]]), np.zeros((1, 3))])
    return np.array(
        [(C1 @ np.linalg.solve(1j * w * np.eye(6) - Acl, Bcl)).item() for w in np.atleast_1d(omega)]
    )


def describing_function_cycle(spec: PlantSpec, w_cl: float, F: float, sensor: str = "y1") -> dict[str, float]:
    """Nyquist crossing of the negative real axis and the relay describing-function prediction (§5.1):
    arg G(jω) = -180°, C = -4F·G(jω)/π (V), frequency ω (rad/s)."""
    import numpy as np
    from scipy.optimize import brentq

    w = np.logspace(-1, 2.5, 4000)
    G = friction_loop_response(spec, w_cl, w, sensor)
    crossing = np.flatnonzero((G.imag[:-1] * G.imag[1:] < 0) & (G.real[:-1] < 0))
    if len(crossing) == 0:
        return {"omega": float("nan"), "G": float("nan"), "amplitude_v": float("nan")}
    i = crossing[0]
    wc = brentq(lambda x: friction_loop_response(spec, w_cl, x, sensor)[0].imag, w[i], w[i + 1])
    g = friction_loop_response(spec, w_cl, wc, sensor)[0].real
    return {"omega": float(wc), "G": float(g), "amplitude_v": float(-4 * F * g / np.pi)}


def regulator_transfer(
    spec: PlantSpec, w_cl: float, zeta: float = 0.7, alpha: float = 1.5, sensor: str = "y1"
):
    """The continuous regulator (4.1)-(4.2) as a python-control system from the measured y to u (y_r = 0):
    x̂' = (A - BL - KC) x̂ + K y, u = -L x̂. Its poles are the regulator poles of §6.1."""
    import control

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    return control.ss(d.A - d.B @ d.L - d.K @ d.C, d.K, -d.L, 0)
