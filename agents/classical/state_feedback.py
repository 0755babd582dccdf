"""Wallenborg's state feedback + observer for the flexible servo (Wallenborg 1987 §4, Appendix B CSFNL/DSFNL),
designed by pole placement (continuous §4.1, digital §4.2) with python-control, with the friction
compensation variants of §6.3: none, relay with dead zone, high gain with saturation. Also the analyses
of §5-6 on the same design: regulator poles and stability limits, the friction loop's frequency response
and its describing-function limit cycle."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import control
import numpy as np
from scipy.optimize import brentq

from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.plants.flexible_servo import state_space, tacho_gains
from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import Controller, EpisodeContext, decoded_rows, observation_columns

COMPENSATION = ("none", "relay", "highgain")


@dataclass(frozen=True)
class StateFeedbackSettings(cfg.FamilySettings):
    """Wallenborg §4.1-4.2 (controllers.yaml `state_feedback`): closed-loop poles (s + ω_cl)(s² + 2ζω_cl s
    + ω_cl²) (rad/s), observer poles at alpha·ω_cl; u_max_v: clip of the linear part (V, Appendix B);
    eps_v: the compensation's ε on ŷ (V, SIMNON code, ERRATA 002); continuous_max_period_s: the
    continuous design is used at or below this sampling period (s), the digital one above."""

    SECTION: ClassVar[str] = "state_feedback"
    w_cl: float
    zeta: float
    alpha: float
    u_max_v: float
    eps_v: float
    continuous_max_period_s: float

    @classmethod
    @cache
    def defaults(cls) -> StateFeedbackSettings:
        return cfg.read(
            cls.SECTION,
            lambda s: cls(
                s.positive("w_cl", 1e4),
                s.positive("zeta", 10.0),
                s.positive("alpha", 100.0),
                s.positive("u_max_v", 1e3),
                s.positive("eps_v", 10.0),
                s.positive("continuous_max_period_s", 1.0),
            ),
        )


@dataclass(frozen=True)
class ResidualBaseSettings(cfg.FamilySettings):
    """controllers.yaml `state_feedback_residual_base`: w_cl (rad/s), the closed-loop design of the residual
    base SF+relay/residual-base (agents/registry.py BASES), not a baseline."""

    SECTION: ClassVar[str] = "state_feedback_residual_base"
    w_cl: float

    @classmethod
    @cache
    def defaults(cls) -> ResidualBaseSettings:
        return cfg.read(cls.SECTION, lambda s: cls(s.positive("w_cl", 1e4)))


def wallenborg_poles(w: float, zeta: float):
    """(s + w)(s² + 2ζw s + w²), the pole pattern of §4.1 (α_cl = ω_cl)."""

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

    A, B, C = state_space(spec, sensor)
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
    """Poles of the (continuous) regulator itself, det(sI - A + BL + KC) = 0 (Wallenborg 1987 eq. 6.1)."""

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    return np.linalg.eigvals(d.A - d.B @ d.L - d.K @ d.C)


def regulator_stability_boundary(
    spec: PlantSpec, lo: float, hi: float, sensor: str = "y1", tol: float = 1e-4
) -> float:
    """ω_cl at which the regulator's stability changes between lo and hi (bisection; §6.1-6.2)."""

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
    """G(jω) of Wallenborg 1987 eq. (5.3): friction torque on shaft 1 (N·m) -> y1 (V), regulator in the loop.
    """

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    J1 = spec.joints[0].inertia
    Bf = np.array([[1.0 / J1], [0.0], [0.0]])
    Acl = np.block([[d.A, -d.B @ d.L], [d.K @ d.C, d.A - d.B @ d.L - d.K @ d.C]])
    Bcl = np.vstack([Bf, np.zeros((3, 1))])
    C1 = np.hstack([np.array([[tacho_gains(spec)[0], 0.0, 0.0]]), np.zeros((1, 3))])
    return np.array(
        [(C1 @ np.linalg.solve(1j * w * np.eye(6) - Acl, Bcl)).item() for w in np.atleast_1d(omega)]
    )


def describing_function_cycle(spec: PlantSpec, w_cl: float, F: float, sensor: str = "y1") -> dict[str, float]:
    """Nyquist crossing of the negative real axis and the relay describing-function prediction (§5.1):
    arg G(jω) = -180°, C = -4F·G(jω)/π (V), frequency ω (rad/s)."""

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

    d = state_feedback_design(spec, w_cl, zeta, alpha, sensor)
    return control.ss(d.A - d.B @ d.L - d.K @ d.C, d.K, -d.L, 0)


class StateFeedback(Controller):
    """u = u0 + u_f, u0 = clip(l_r·y_r - L x̂, ±u_max); the observer is fed u0 (as in CSFNL/DSFNL) and the
    friction torque estimate u_f = M_f/(k_m k_i) acts on the estimated output ŷ = C x̂:
    high gain: M_f = F·ŷ/ε (|ŷ| < ε) else F·sgn(ŷ); relay: 0 (|ŷ| < ε) else F·sgn(ŷ).
    Continuous design (§4.1, its observer discretised exactly over the hold period) when the scenario
    samples fast, else the digital design (§4.2) with the latest-measurement observer.

    observe_residual (a residual base, not Wallenborg's loop): the observer is also fed what a residual
    added to this loop's command, read one sample later from the held command in the observation (the
    observer's update for a period is made at the next sample, with the same arithmetic). Wallenborg's
    observer sees u0 only, so a residual reaches the plant but not the estimate x̂ the state feedback and
    the relay act on (docs/research.md, flexible attempt 2). With no residual the commands are this
    loop's without it, bit for bit."""

    name: ClassVar[str] = "SF"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("tacho",)
    steps_arrays: ClassVar[bool] = True

    def __init__(
        self,
        compensation: str = "none",
        w_cl: float | None = None,
        sensor: str = "y1",
        *,
        settings: StateFeedbackSettings | None = None,
        observe_residual: bool = False,
        name: str | None = None,
    ):
        if compensation not in COMPENSATION:
            raise ValueError(f"compensation {compensation!r} not in {COMPENSATION}")
        if sensor not in ("y1", "y2"):
            raise ValueError(f"sensor {sensor!r} not in ['y1', 'y2']")
        self.settings = cfg.with_overrides(
            settings or StateFeedbackSettings.defaults(), {} if w_cl is None else {"w_cl": w_cl}
        )
        self.compensation, self.sensor, self.w_cl = compensation, sensor, self.settings.w_cl
        suffix = {"none": "", "relay": "+relay", "highgain": "+highgain"}[compensation]
        self.observe_residual = observe_residual
        self.name = name or (
            (f"SF{suffix}" if (w_cl is None and sensor == "y1") else f"SF(w{self.w_cl:g},{sensor}){suffix}")
            + ("/residual-observed" if observe_residual else "")
        )

    def why_not(self, scenario: Scenario) -> str | None:
        spec = scenario.spec
        if len(spec.joints) != 2 or len(spec.springs) != 1 or {s.kind for s in spec.sensors} != {"tacho"}:
            return "needs a two-inertia plant with one shaft spring and tachometers (Wallenborg §3)"
        return super().why_not(scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        sc = self.sc = ctx.scenario
        h = sc.control_period
        c = self.settings
        self.continuous = h <= c.continuous_max_period_s
        d = self.design = state_feedback_design(
            ctx.plant, self.w_cl, c.zeta, c.alpha, self.sensor, 0.0 if self.continuous else h
        )
        if self.continuous:  # exact ZOH of x̂' = (A - KC) x̂ + [B K] [u0; y] over one period
            obs = control.c2d(
                control.ss(d.A - d.K @ d.C, np.hstack([d.B, d.K]), np.eye(3), 0), h, method="zoh"
            )
            self.Ad, self.Bd = np.asarray(obs.A), np.asarray(obs.B)
        spec = ctx.plant
        F = (
            spec.joints[0].friction.levels()
            if spec.joints[0].friction
            else {"static_pos": 0.0, "static_neg": 0.0}
        )
        scale = ctx.knowledge.get("static_friction_scale", 1.0)
        self.F_pos, self.F_neg = scale * F["static_pos"], scale * F["static_neg"]
        self.gain = spec.actuator_gain  # k_m·k_i, N·m/V
        self.x = np.zeros((ctx.episodes, 3))  # x̂(k|k-1) (digital) or x̂(t_k) (continuous), per episode
        # the last sample's update inputs: x̂, u0, the reading, the command the env holds if none is added
        self.pending: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self.tacho = "tacho1" if self.sensor == "y1" else "tacho2"
        self.columns = observation_columns(sc, self.tacho)
        self.held_column = sc.layout.slice("previous_action").start

    def friction_command(self, y_est: np.ndarray) -> np.ndarray:
        """u_f (V) from the estimated outputs (V), eq. (6.13)/(6.14) as coded in CSFNL/DSFNL."""
        if self.compensation == "none":
            return np.zeros_like(y_est)
        eps = self.settings.eps_v
        F = np.where(y_est > 0, self.F_pos, self.F_neg)
        inside = F * y_est / eps / self.gain if self.compensation == "highgain" else 0.0
        return np.where(np.abs(y_est) < eps, inside, np.sign(y_est) * F / self.gain)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.act_episodes(obs[None])[0]

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        sc, d = self.sc, self.design
        y, yr, _ = decoded_rows(sc, self.columns, obs)  # y stays float32, as the reading is
        yr = yr.astype(np.float64)
        if self.pending is not None:  # the last period's observer update, with what was held over it
            xe, u0, y_last, held = self.pending
            if self.observe_residual:  # the residual's part of the held command (V)
                u0 = u0 + ((obs[:, self.held_column] * sc.action_scale).astype(np.float64) - held)
            if self.continuous:
                self.x = np.matvec(self.Ad, xe) + np.matvec(self.Bd, np.stack([u0, y_last], axis=1))
            else:
                self.x = np.matvec(d.Phi, xe) + d.Gamma.ravel() * u0[:, None]
        umax = self.settings.u_max_v
        if self.continuous:
            xe = self.x
        else:  # the innovation in the reading's float32, as the reading meets the estimate
            innovation = y - np.matvec(d.C, self.x)[:, 0].astype(np.float32)
            xe = self.x + d.K.ravel() * innovation[:, None]
        u0 = np.clip(d.lr * yr - np.matvec(d.L, xe)[:, 0], -umax, umax)
        u = u0 + self.friction_command(np.matvec(d.C, xe)[:, 0])
        action = (u / sc.action_scale).astype(np.float32)[:, None]
        # what the env will hold if nothing is added (its clip, read back as decode_observation reads it)
        held = (np.clip(action[:, 0], -1.0, 1.0) * sc.action_scale).astype(np.float64)
        self.pending = (xe, u0, y, held)
        return action

    def params(self) -> dict[str, Any]:
        d = getattr(self, "design", None)
        return (
            {}
            if d is None
            else {
                "L": d.L.ravel().tolist(),
                "K": d.K.ravel().tolist(),
                "lr": d.lr,
                "continuous": self.continuous,
                "compensation": self.compensation,
            }
        )
