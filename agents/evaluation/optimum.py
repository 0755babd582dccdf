"""The friction-free optimum: per episode, the lowest value of the scenario's main metric that any command
sequence within the actuator's limits reaches on the episode's friction-free twin, knowing the whole
reference (and the episode's load torque) in advance. No controller, causal or not, can do better there:
the limit a row's friction penalty is read against (docs/envs.md, "The friction-free optimum").

How it is computed, for one episode:

1. The twin (scenario key nonlinear_friction false: the episode's own draws, no Coulomb, static, bias or
   bristle damping) is linear in the commands. The evaluation loop itself plays two command sequences on
   it: none (the free response y0, from the episode's initial state and load torque) and one full-scale
   pulse in the first period (the pulse response g). The twin is time-invariant (no jitter: a scenario
   that draws jitter is refused), so y = y0 + g * u (a convolution).
2. A minimal state-space realisation (A, B, C) of g (Ho-Kalman: the singular value decomposition of a
   Hankel matrix of g; the plants are of order 2 to 5, the drive's delay included) makes the episode a
   sparse linear program in the commands u, the states x and the error bounds t, solved by HiGHS
   (scipy.optimize.linprog): |u| <= 1 (the action's clip: the command limit), x(k+1) = A x(k) + B u(k),
   |y0 + C x - r| <= t, minimising the main metric written in t: IAE (Σ t·dt), final_error (the mean t
   over the last 10 %) or reversal_peak_error (one t over every sample near a reversal).
3. The optimal commands are played on the twin by the evaluation loop and the metric computed as any
   row's (envs/metrics.py): that is the reported value. The program's own objective must agree with it
   to `AGREE` of the error scale, else the realisation was not the twin and the episode is an error.

A tracking output of a speed (the flexible servo's tachometers) is as linear as a position.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, run_episode
from frictiongym.envs.metrics import FINAL_FRACTION, reversal_half_window, reversal_windows
from frictiongym.envs.scenario import Scenario
from frictiongym.envs.suites import Episode

METRICS = ("iae", "final_error", "reversal_peak_error")  # the main metrics the program writes
HANKEL = 60  # rows and columns of the Hankel matrix the realisation is taken from
RANK_TOL = 1e-10  # singular values below this fraction of the largest are rounding (the order is cut there)
AGREE = 1e-6  # the program's objective and the played metric agree to this fraction of the error scale


class Commands(Controller):
    """Plays a fixed sequence of actions (one per control period, in [-1, 1]) on the friction-free twin,
    whatever it observes: how the optimum's commands and its pulse responses are run through the one
    evaluation loop."""

    name: ClassVar[str] = "Commands"

    def __init__(self, actions: np.ndarray):
        self.actions = np.asarray(actions, dtype=np.float64)
        self.k = 0

    def scenario_overrides(self) -> dict:
        return {"nonlinear_friction": False}

    def reset(self, ctx: EpisodeContext) -> None:
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        a = self.actions[self.k] if self.k < len(self.actions) else 0.0
        self.k += 1
        return np.array([a])


@dataclass(frozen=True)
class Optimum:
    """One episode's friction-free optimum: the main metric's value (the played commands' metric, in the
    metric's unit), the program's own objective, whether the two agree (to AGREE of the error scale: the
    twin was the realised linear system, so `value` is the optimum; else it is what the program's
    commands reach, an upper bound), the optimal actions ([-1, 1], one per period), the realisation's
    order and the wall time (s)."""

    scenario: str
    seed: int
    metric: str
    value: float
    objective: float
    exact: bool
    actions: np.ndarray
    order: int
    wall_s: float


def why_not(scenario: Scenario) -> str | None:
    """None if the optimum is computed for this scenario, else a one-line reason."""
    if scenario.main_metric not in METRICS:
        return f"main metric {scenario.main_metric} is not one the program writes ({list(METRICS)})"
    return None


def realisation(g: np.ndarray, size: int = HANKEL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) with g[m] = C A^m B (Ho-Kalman): the order is the number of singular values of the Hankel
    matrix of g above RANK_TOL of the largest."""
    size = min(size, (len(g) - 1) // 2)
    H0 = np.array([g[i : i + size] for i in range(size)])
    H1 = np.array([g[i + 1 : i + 1 + size] for i in range(size)])
    U, s, Vt = np.linalg.svd(H0)
    n = int(np.count_nonzero(s > RANK_TOL * s[0]))
    root, inv = np.sqrt(s[:n]), 1.0 / np.sqrt(s[:n])
    A = (inv[:, None] * (U[:, :n].T @ H1 @ Vt[:n].T)) * inv[None, :]
    return A, root * Vt[:n, 0], U[0, :n] * root


def weights(metric: str, t: np.ndarray, r: np.ndarray, h: float) -> tuple[np.ndarray, bool]:
    """The main metric as Σ w·t over the samples where w > 0 (IAE, final_error), or as one bound over
    them (reversal_peak_error: `peak` True)."""
    n = len(t)
    w = np.zeros(n)
    if metric == "iae":
        w[:] = float(np.mean(np.diff(t))) if n > 1 else 0.0
        return w, False
    if metric == "final_error":
        last = max(1, round(n * FINAL_FRACTION))
        w[-last:] = 1.0 / last
        return w, False
    return reversal_windows(t, r, reversal_half_window(h)).astype(float), True


def solve(d: np.ndarray, g: np.ndarray, w: np.ndarray, peak: bool) -> tuple[np.ndarray, float]:
    """The actions u (N,) in [-1, 1] minimising Σ w·|g*u - d| (or the largest |g*u - d| where w > 0, with
    `peak`) and that minimum, in d's unit; d = r - y0, the error with no command."""
    A, B, C = realisation(g)
    n, N = len(B), len(d)
    scale = max(float(np.max(np.abs(d))), np.finfo(float).tiny)  # the program in O(1) numbers
    rows = np.flatnonzero(w > 0)
    m = len(rows)
    nt = 1 if peak else m
    # variables [u (N), x(1..N) (N·n), t (nt)], x(0) = 0: the free response is in d
    dynamics = sp.hstack(  # x(k+1) - A x(k) - B u(k) = 0, k = 0..N-1
        [
            -sp.kron(sp.identity(N), sp.csr_matrix(B[:, None])),
            sp.identity(N * n) - sp.kron(sp.eye(N, k=-1), sp.csr_matrix(A)),
            sp.csr_matrix((N * n, nt)),
        ],
        format="csr",
    )
    pick = sp.csr_matrix((np.ones(m), (np.arange(m), rows)), shape=(m, N))
    out = sp.kron(pick, sp.csr_matrix(C[None, :] / scale))  # (g*u)(k) / scale at the metric's samples
    bound = sp.csr_matrix(np.ones((m, 1))) if peak else sp.identity(m, format="csr")
    no_u = sp.csr_matrix((m, N))
    error = sp.vstack([sp.hstack([no_u, out, -bound]), sp.hstack([no_u, -out, -bound])], format="csr")
    cost = np.concatenate([np.zeros(N + N * n), np.ones(1) if peak else w[rows]])
    res = linprog(
        cost,
        A_ub=error,
        b_ub=np.concatenate([d[rows], -d[rows]]) / scale,
        A_eq=dynamics,
        b_eq=np.zeros(N * n),
        bounds=[(-1.0, 1.0)] * N + [(None, None)] * (N * n) + [(0.0, None)] * nt,
        method="highs",
    )
    if res.status != 0:
        raise ValueError(f"optimum: HiGHS did not solve the program ({res.message})")
    return res.x[:N], float(res.fun) * scale


def optimum(episode: Episode, envs: EnvCache | None = None) -> Optimum:
    """The friction-free optimum of one episode (module docstring)."""
    envs = envs or EnvCache()
    sc = envs.scenario(episode)
    why = why_not(sc)
    where = f"optimum: {episode.scenario} seed {episode.seed}"
    if why is not None:
        raise ValueError(f"{where}: {why}")
    start = time.perf_counter()
    N = sc.episode_steps
    core = envs.env(Commands(np.zeros(0)), episode).core
    if core.draw(episode.seed, dict(episode.params) or None)[0].jitter_steps(sc.spec) > 0:
        raise ValueError(f"{where}: its jitter makes the twin vary in time")

    def play(u: np.ndarray) -> tuple[np.ndarray, EpisodeResult]:
        res = run_episode(Commands(u), episode, True, envs=envs)
        return res.log["output"][1:], res

    y0, free = play(np.zeros(N))
    r, t = free.log["reference"][1:], free.log["t"][1:]
    g = play(np.eye(1, N)[0])[0] - y0
    w, peak = weights(sc.main_metric, t, r, sc.control_period)
    u, objective = solve(r - y0, g, w, peak)
    value = play(u)[1].metrics[sc.main_metric]
    tol = AGREE * float(np.max(np.abs(r - y0))) * (1.0 if peak else float(np.sum(w)))
    return Optimum(
        episode.scenario,
        episode.seed,
        sc.main_metric,
        value,
        objective,
        abs(value - objective) <= tol,
        u,
        len(realisation(g)[1]),
        time.perf_counter() - start,
    )
