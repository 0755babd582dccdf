"""Friction parameters and their checks.

LuGre (Iurian et al. 2005 §1.4.6, eq. 1-3): ż = v - σ0·|v|·z/g(v), g(v) = Fc + (Fs - Fc)·exp(-(v/vs)²),
F = σ0·z + σ1·ż + σ2·v. MuJoCo's dcmotor LuGre element is symmetric; direction-dependent levels
(all three documents have them) are built as symmetric LuGre plus a constant bias torque b
(a dcmotor cogging term with 0 poles), so the friction torque on the joint is -F + b:

    sliding v > 0:  -(g(v) + σ2·v) + b     static limit  +direction: Fs - b
    sliding v < 0:  +(g(v) - σ2·v) + b     static limit  -direction: Fs + b

Exact: Coulomb and static levels of both directions when their Stribeck drops are equal
(Fs+ - Fc+ = Fs- - Fc-); otherwise the static levels are kept exact and each Coulomb level is off by
half the difference of the drops. Not exact: viscous slopes must be equal in both directions, and at
rest the bias is balanced by the bristles, which shifts the presliding equilibrium by b/σ0 (rad).

Friction structures (a scenario's `friction_model`; Iurian et al. 2005's survey, docs/physics.md "Friction
structures"). The preset's LuGreParams describe one static curve and one bristle; a structure says which
native elements carry it on the joint:

    lugre         one LuGre element (§1.4.6).
    dahl          one Dahl element (§1.4.1): LuGre with g(v) = Fc (the survey's "g(v) = Fc/σ0" is a typo:
                  with eq. (1) as printed, σ0/g(v) = σ0/Fc is Dahl's). No Stribeck curve, no stiction, rate
                  independent. Deviation, measured: the survey's σ1 = 0 is not kept, the preset's bristle
                  damping σ1 is: undamped, the bristle spring rings at sqrt(σ0/J) and MuJoCo's explicit
                  step creeps ten times the Radau solution under a held torque (Kang's rotor, half the
                  static level: 2.5e-4 against 2.6e-5 rad after 1 s). The preset's σ2·v stays, as the
                  plant's viscous term.
    maxwell_slip  N parallel LuGre elements (a Maxwell-slip/Leuven-type presliding hysteresis with
                  non-local memory, §1.4.7): element i has a share α_i of the levels and a presliding length
                  r_i·c times LuGre's F_s/σ0; its stiffness and damping are shares of σ0 and σ1 summing to
                  them, so the small-motion stiffness, the damping and the static curve are LuGre's.
    kang          Kang's stick-slip model (Kang 1998 eq. 1-4, Karnopp's stick band): one LuGre element whose
                  Stribeck velocity is KANG_STICK_BAND times the preset's, so the static level holds within
                  the band and the Coulomb level outside it.
    coulomb       Coulomb + viscous (§1.2.1-1.2.2) by MuJoCo's frictionloss constraint (sticks at rest).
    viscous, none the nonlinear part removed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .config import ConfigError, nonneg, positive

FRICTION_MODELS = ("lugre", "dahl", "maxwell_slip", "kang", "coulomb", "viscous", "none")
BRISTLE_MODELS = ("lugre", "dahl", "maxwell_slip", "kang")  # carried by native LuGre elements (dcmotor lugre)
# the structures with a friction level of their own: the sim-to-real study's structural axis and the
# reproduction's native plants (viscous and none have no Coulomb level to shift or compare)
STRUCTURES = (*BRISTLE_MODELS, "coulomb")
# Kang's stick-slip model (Kang 1998 eq. 1-4, after Karnopp 1985): the static level holds within a stick band
# of this fraction of the preset's Stribeck velocity (Kang: 0.01 deg/s, a fifth of §6's 0.05 deg/s
# identification ramp), the Coulomb level outside it
KANG_STICK_BAND = 0.01
# Maxwell-slip elements: shares α_i of the levels and relative presliding lengths r_i (element i slips after
# r_i·c·F_s/σ0 with c = Σ α_j/r_j, so that the stiffness shares (α_i/r_i)/c sum to 1): 0.37 to 10 LuGre
# presliding lengths, so that the friction force builds up over a decade of displacement.
MAXWELL_SLIP_SHARES = (0.25, 0.25, 0.25, 0.25)
MAXWELL_SLIP_LENGTHS = (1.0 / 3.0, 1.0, 3.0, 9.0)


def stribeck(fc: float, fs: float, vs: float, v: float | np.ndarray) -> float | np.ndarray:
    """g(v) = Fc + (Fs - Fc)·exp(-(v/vs)²) (N·m), Iurian et al. 2005 eq. (2): levels in N·m, velocities in
    rad/s. The square is a product, so a number and an array give the same bits."""
    x = v / vs
    return fc + (fs - fc) * np.exp(-(x * x))


@dataclass(frozen=True)
class LuGreParams:
    """Symmetric LuGre parameters (SI, per joint) plus a constant bias torque for asymmetry.

    fc, fs: Coulomb and static levels (N·m); vs: Stribeck velocity (rad/s); sigma0: bristle stiffness
    (N·m/rad); sigma1: bristle damping (N·m·s/rad); sigma2: viscous coefficient (N·m·s/rad);
    bias: constant torque (N·m), positive helps positive motion.
    """

    fc: float
    fs: float
    vs: float
    sigma0: float
    sigma1: float
    sigma2: float
    bias: float = 0.0

    @classmethod
    def from_levels(
        cls,
        fc_pos: float,
        fc_neg: float,
        fs_pos: float,
        fs_neg: float,
        vs: float,
        sigma0: float,
        sigma1: float,
        sigma2: float,
    ) -> LuGreParams:
        """Build from direction-dependent magnitudes (N·m); static levels are reproduced exactly."""
        fs = 0.5 * (fs_pos + fs_neg)
        bias = 0.5 * (fs_neg - fs_pos)
        drop = 0.5 * ((fs_pos - fc_pos) + (fs_neg - fc_neg))
        return cls(fc=fs - drop, fs=fs, vs=vs, sigma0=sigma0, sigma1=sigma1, sigma2=sigma2, bias=bias)

    def levels(self) -> dict[str, float]:
        """Implied magnitudes of the Coulomb and static levels in each direction (N·m)."""
        return {
            "coulomb_pos": self.fc - self.bias,
            "coulomb_neg": self.fc + self.bias,
            "static_pos": self.fs - self.bias,
            "static_neg": self.fs + self.bias,
        }

    def g(self, v: float | np.ndarray) -> float | np.ndarray:
        """Stribeck curve g(v) (N·m), Iurian et al. 2005 eq. (2)."""
        return stribeck(self.fc, self.fs, self.vs, v)

    def steady_state(self, v: float) -> float:
        """Steady sliding friction torque on the joint at velocity v (rad/s), v != 0 (N·m)."""
        g = self.g(v)
        return -(math.copysign(g, v) + self.sigma2 * v) + self.bias

    def scaled(
        self,
        level: float = 1.0,
        sigma0: float = 1.0,
        vs: float = 1.0,
        viscous: float = 1.0,
        extra_bias: float = 0.0,
    ) -> LuGreParams:
        """A copy with levels (fc, fs, bias) scaled, σ0 scaled (σ1 by sqrt, constant damping ratio)."""
        return replace(
            self,
            fc=self.fc * level,
            fs=self.fs * level,
            bias=self.bias * level + extra_bias,
            sigma0=self.sigma0 * sigma0,
            sigma1=self.sigma1 * math.sqrt(sigma0),
            vs=self.vs * vs,
            sigma2=self.sigma2 * viscous,
        )

    def friction_free(self) -> LuGreParams:
        """The friction-free twin: Coulomb, static and bias levels 0 (so no Stribeck curve and no
        presliding force: MuJoCo's LuGre keeps z = 0 when g(v) = 0) and no bristle damping σ1, σ2·v kept:
        the viscous term is part of the linear plant a loop is designed on. σ1 goes because MuJoCo's step
        still differentiates σ1·ż with z pinned at g(v) = 0, which made the twin's response depend on the
        sign of its speed (about 1 % of a pulse's response on Kang's rotor): without it the twin is linear
        to rounding (tests/test_optimum.py). σ0 and vs are kept (σ0 > 0 is required at runtime)."""
        return replace(self, fc=0.0, fs=0.0, bias=0.0, sigma1=0.0)

    @property
    def is_friction_free(self) -> bool:
        return self.fc == 0.0 and self.fs == 0.0 and self.bias == 0.0

    def validate(self, field: str) -> None:
        """Reject unphysical values, naming the field. All three levels 0 is the friction-free twin."""
        positive(self.vs, f"{field}.vs")
        positive(self.sigma0, f"{field}.sigma0")  # σ0 = 0 at runtime is fatal in MuJoCo's dcmotor
        nonneg(self.sigma1, f"{field}.sigma1")
        nonneg(self.sigma2, f"{field}.sigma2")
        if self.is_friction_free:
            return
        positive(self.fc, f"{field}.fc")
        if not math.isfinite(self.fs) or self.fs < self.fc:
            raise ConfigError(
                f"{field}.fs", f"static level {self.fs} must be finite and >= Coulomb {self.fc}"
            )
        if not math.isfinite(self.bias) or abs(self.bias) >= self.fc:
            raise ConfigError(
                f"{field}.bias",
                f"|bias| {abs(self.bias)} must be < the symmetric Coulomb "
                f"level {self.fc} (both directions must keep positive friction)",
            )


@dataclass(frozen=True)
class Element:
    """One native LuGre element on a joint (SI): stiffness σ0 (N·m/rad), damping σ1 (N·m·s/rad), Coulomb
    and static levels fc, fs (N·m), Stribeck velocity vs (rad/s)."""

    sigma0: float
    sigma1: float
    fc: float
    fs: float
    vs: float

    def g(self, v: float | np.ndarray) -> float | np.ndarray:
        """The element's Stribeck curve (N·m)."""
        return stribeck(self.fc, self.fs, self.vs, v)


def elements(model: str, p: LuGreParams) -> tuple[Element, ...]:
    """The native elements that carry friction p on its joint under structure `model` (module docstring);
    the first carries the bias and σ2 as well. Empty where no bristle element is used."""
    if model == "lugre":
        return (Element(p.sigma0, p.sigma1, p.fc, p.fs, p.vs),)
    if model == "dahl":
        return (Element(p.sigma0, p.sigma1, p.fc, p.fc, p.vs),)
    if model == "kang":
        return (Element(p.sigma0, p.sigma1, p.fc, p.fs, KANG_STICK_BAND * p.vs),)
    if model == "maxwell_slip":
        c = sum(a / r for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True))
        return tuple(
            Element(p.sigma0 * a / r / c, p.sigma1 * a / r / c, a * p.fc, a * p.fs, p.vs)
            for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True)
        )
    return ()


def element_levels(els: tuple[Element, ...], bias: float) -> list[tuple[float, float, float]]:
    """(fc, fs, bias) of each of a joint's native elements (N·m): what drift scales. The joint's bias
    rides on the first element."""
    return [(e.fc, e.fs, bias if k == 0 else 0.0) for k, e in enumerate(els)]


def joint_levels(model: str, p: LuGreParams) -> tuple[float, float, float]:
    """The joint's symmetric Coulomb and static levels and bias under `model` (N·m): the elements' sums
    (Dahl: static = Coulomb); Coulomb + viscous sticks and slides at fc."""
    if model == "coulomb":
        return p.fc, p.fc, p.bias
    levels = element_levels(elements(model, p), p.bias)
    fc, fs = levels[0][0], levels[0][1]
    for e in levels[1:]:
        fc, fs = fc + e[0], fs + e[1]
    return fc, fs, p.bias


def element_count(model: str) -> int:
    """Native LuGre elements per frictional joint under structure `model`."""
    return len(MAXWELL_SLIP_SHARES) if model == "maxwell_slip" else 1 if model in BRISTLE_MODELS else 0


@dataclass(frozen=True)
class FrictionDrift:
    """Friction that drifts within an episode (temperature, wear) and changes once (lubrication): the
    Coulomb, static and bias levels of every frictional joint are scaled, over the control period that
    starts at t, by λ(t) = (1 + drift·t/T)·(1 + step·[t >= step_at]), T the episode's length; drift, step
    and step_at are drawn per episode (fractions, s). The σ's and the Stribeck velocity do not change."""

    drift: tuple[float, float]
    step: tuple[float, float]
    step_at_s: tuple[float, float]

    def draw(self, rng: np.random.Generator, t: np.ndarray, episode_s: float) -> np.ndarray:
        """λ at the period starts t (s) of one episode."""
        a = float(rng.uniform(*self.drift))
        s = float(rng.uniform(*self.step))
        at = float(rng.uniform(*self.step_at_s))
        return (1.0 + a * (t / episode_s)) * np.where(t >= at, 1.0 + s, 1.0)


# Admissible region of the integrators for the bristle dynamics (docs/physics.md, "Numerics").
# Euler/RK4 are explicit in the bristle force: the bristle spring-damper (σ0, σ1) on the joint
# inertia J must be resolved, h·sqrt(σ0/J) <= 0.2 and h·σ1/J <= 0.5 (Euler diverges near 2;
# validated against Radau within 2 % inside this region). The implicit integrators treat σ1 as a
# damping derivative, which acts like an extra inertia h·σ1 while sliding: they are accepted only
# where that is below 1 % of J.
EXPLICIT_LIMITS = {"h_omega": 0.2, "h_sigma1_over_J": 0.5}
IMPLICIT_LIMIT_H_SIGMA1_OVER_J = 0.01


def joint_friction_torque(actuator_force: Any, sigma2: Any, velocity: Any) -> Any:
    """The friction torque on a joint (N·m), -F + b above: the friction actuator's force
    (-(σ0·z + σ1·ż) + b) minus σ2·v, because MuJoCo applies an actuator's damping as a passive force,
    outside actuator_force. Floats or arrays (one entry per frictional joint)."""
    return actuator_force - sigma2 * velocity


def check_numerics(p: LuGreParams, inertia: float, timestep: float, integrator: str, field: str) -> None:
    """Reject (σ0, σ1, J, h, integrator) combinations outside the stable and accurate region."""
    h_omega = timestep * math.sqrt(p.sigma0 / inertia)
    h_s1 = timestep * p.sigma1 / inertia
    if integrator in ("Euler", "RK4"):
        if h_omega > EXPLICIT_LIMITS["h_omega"]:
            raise ConfigError(
                f"{field}.sigma0",
                f"h·sqrt(σ0/J) = {h_omega:.3g} > {EXPLICIT_LIMITS['h_omega']} "
                f"(σ0={p.sigma0:g}, J={inertia:g}, h={timestep:g}): reduce σ0 or the timestep",
            )
        if h_s1 > EXPLICIT_LIMITS["h_sigma1_over_J"]:
            raise ConfigError(
                f"{field}.sigma1",
                f"h·σ1/J = {h_s1:.3g} > {EXPLICIT_LIMITS['h_sigma1_over_J']} "
                f"(σ1={p.sigma1:g}, J={inertia:g}, h={timestep:g}): reduce σ1 or the timestep",
            )
    elif integrator in ("implicit", "implicitfast"):
        if h_s1 > IMPLICIT_LIMIT_H_SIGMA1_OVER_J:
            raise ConfigError(
                f"{field}.sigma1",
                f"{integrator}: h·σ1/J = {h_s1:.3g} > "
                f"{IMPLICIT_LIMIT_H_SIGMA1_OVER_J} adds > 1 % inertia while sliding",
            )
    else:
        raise ConfigError(
            "sampling.integrator", f"{integrator!r} not in ['Euler', 'RK4', 'implicit', 'implicitfast']"
        )
