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

**Cached per episode, across runs**: step 2's program is a pure function of what the plays measured
(d = r - y0, g, the metric's weights) and of this module's code, so its answer (u, the program's
minimum, the metric through g) is kept on disk under the SHA-256 of those inputs, this file's bytes and
scipy's version (HiGHS comes with it): `cache_dir()`, FRICTIONGYM_CACHE or the user's cache folder
(`off`: none). A rerun of a leaderboard plays the twin again and reads the rest; an entry that does not
load as the arrays it should be (no pickle is ever read) is solved again and replaced.
"""

from __future__ import annotations

import hashlib
import os
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import ClassVar

import numpy as np
import scipy
import scipy.sparse as sp
from scipy.optimize import linprog
from scipy.signal import fftconvolve

from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, run_episode
from frictiongym.envs.metrics import FINAL_FRACTION, reversal_half_window, reversal_windows
from frictiongym.envs.records import atomic_write
from frictiongym.envs.scenario import Scenario
from frictiongym.envs.suites import Episode

METRICS = ("iae", "final_error", "reversal_peak_error")  # the main metrics the program writes
HANKEL = 60  # rows and columns of the Hankel matrix the realisation is taken from
RANK_TOL = 1e-10  # singular values below this fraction of the largest are rounding (the order is cut there)
METHODS = ("highs-ipm", "highs-ds")  # HiGHS's interior point method, then its dual simplex
ROUNDS = 3  # programs solved, each on the error the last one's commands leave through g itself
AGREE = 1e-6  # the program's objective and the played metric agree to this fraction of the error scale


class Commands(Controller):
    """Plays fixed actions (in [-1, 1], one per control period: (N,) for one episode, (n, N) for each of
    the n episodes of a lockstep) on the friction-free twin, whatever it observes: how the optimum's
    commands and its pulse responses are run through the one evaluation loop."""

    name: ClassVar[str] = "Commands"
    steps_arrays: ClassVar[bool] = True

    def __init__(self, actions: np.ndarray):
        self.actions = np.atleast_2d(np.asarray(actions, dtype=np.float64))
        self.k = 0

    def scenario_overrides(self) -> dict:
        return {"nonlinear_friction": False}

    def reset(self, ctx: EpisodeContext) -> None:
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.act_episodes(obs[None])[0]

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        k = min(self.k, self.actions.shape[1] - 1)
        self.k += 1
        return self.actions[:, k : k + 1]


@dataclass(frozen=True)
class EpisodeOptimum:
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
    spec = scenario.spec
    jitter = spec.randomization.get("jitter_s") if scenario.randomize else None
    if spec.jitter > 0 or (jitter is not None and max(jitter) > 0):
        return "its jitter makes the twin vary in time"
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


def response(A: np.ndarray, B: np.ndarray, C: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The realisation's output after each period under the actions u, from rest: C x(k), k = 1..N."""
    x, out = np.zeros(len(B)), np.empty(len(u))
    for k, uk in enumerate(u):
        x = A @ x + B * uk
        out[k] = C @ x
    return out


def cost(e: np.ndarray, w: np.ndarray, peak: bool) -> float:
    """The main metric of the error e as the program writes it: Σ w·|e|, or the largest |e| where w > 0."""
    return float(np.max(np.abs(e[w > 0]))) if peak else float(np.sum(w * np.abs(e)))


def deadbeat(A: np.ndarray, B: np.ndarray, C: np.ndarray, d: np.ndarray, lag: int) -> np.ndarray:
    """The actions that put the realisation's output on d at every sample the commands reach (from sample
    lag + 1 on: the first `lag` samples of the pulse response are 0), each computed from the state; they
    end at the first beyond the command limit."""
    N = len(d)
    ahead = np.linalg.matrix_power(A, lag + 1)
    gain = float(C @ np.linalg.matrix_power(A, lag) @ B)
    x, u = np.zeros(len(B)), np.zeros(N)
    for k in range(N - lag):
        u[k] = (d[k + lag] - C @ ahead @ x) / gain
        if abs(u[k]) > 1.0:  # beyond the limit (or an unstable inverse): not the optimum, stop here
            break
        x = A @ x + B * u[k]
    return u


def solve(
    d: np.ndarray,
    g: np.ndarray,
    w: np.ndarray,
    peak: bool,
    model: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, float, float]:
    """The actions u (N,) in [-1, 1] minimising the metric of d - g*u (`cost`), the program's minimum and
    the metric of u's error through g itself, in d's unit; d = r - y0, the error with no command. Where
    the deadbeat commands (the output on d from the first sample a command reaches) stay within the
    limit, they are the optimum, and no program is solved. Otherwise the program runs on the realisation
    of g; where it and g differ on u by more than AGREE of the error scale, it is solved again with d
    moved by that difference (at most ROUNDS times). `model`: g's realisation, if already taken."""
    A, B, C = model if model is not None else realisation(g)
    n, N = len(B), len(d)
    scale = max(float(np.max(np.abs(d))), np.finfo(float).tiny)  # the program in O(1) numbers
    tol = AGREE * scale * (1.0 if peak else float(np.sum(w)))
    lag = int(np.argmax(np.abs(g) > RANK_TOL * np.max(np.abs(g))))  # samples no command reaches
    reach = np.arange(N) >= lag
    floor = cost(np.where(reach, 0.0, d), w, peak)  # what no command changes
    u = deadbeat(A, B, C, d, lag)
    if np.max(np.abs(u)) <= 1.0:  # the reference is followed exactly within the limit: nothing is lower
        value = cost(d - fftconvolve(u, g)[:N], w, peak)
        if abs(value - floor) <= tol:
            return u, floor, value
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
    program = {
        "c": np.concatenate([np.zeros(N + N * n), np.ones(1) if peak else w[rows]]),
        "A_ub": sp.vstack([sp.hstack([no_u, out, -bound]), sp.hstack([no_u, -out, -bound])], format="csr"),
        "A_eq": dynamics,
        "b_eq": np.zeros(N * n),
        "bounds": [(-1.0, 1.0)] * N + [(None, None)] * (N * n) + [(0.0, None)] * nt,
    }
    target = d
    for _ in range(ROUNDS):
        b_ub = np.concatenate([target[rows], -target[rows]]) / scale
        for method in METHODS:  # the interior point fails on some programs the simplex solves, and back
            res = linprog(**program, b_ub=b_ub, method=method)
            if res.status == 0:
                break
        else:
            raise ValueError(f"optimum: HiGHS did not solve the program ({res.message})")
        u, objective = res.x[:N], float(res.fun) * scale
        through_g = fftconvolve(u, g)[:N]
        value = cost(d - through_g, w, peak)
        if abs(value - objective) <= tol:
            break
        target = d + response(A, B, C, u) - through_g
    return u, objective, value


CACHE_VARIABLE = "FRICTIONGYM_CACHE"  # the folder the solved programs are kept in; CACHE_OFF: not kept
CACHE_OFF = "off"


def cache_dir() -> Path | None:
    """Where solved programs are kept: $FRICTIONGYM_CACHE/optimum, else $XDG_CACHE_HOME (or ~/.cache)
    /frictiongym/optimum; None when FRICTIONGYM_CACHE is CACHE_OFF."""
    root = os.environ.get(CACHE_VARIABLE, "")
    if root == CACHE_OFF:
        return None
    if root:
        return Path(root) / "optimum"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "frictiongym" / "optimum"


@cache
def _code_digest() -> bytes:
    """The SHA-256 of this module's code, read once per process."""
    return hashlib.sha256(Path(__file__).read_bytes()).digest()


def program_key(d: np.ndarray, g: np.ndarray, w: np.ndarray, peak: bool) -> str:
    """The SHA-256 of everything `solve` reads: its inputs' float64 bytes, this module's code and scipy's
    version."""
    h = hashlib.sha256(_code_digest())
    h.update(scipy.__version__.encode())
    for a in (d, g, w):
        a = np.ascontiguousarray(a, dtype=np.float64)
        h.update(str(a.shape).encode() + a.tobytes())
    h.update(b"peak" if peak else b"sum")
    return h.hexdigest()


def cached_solve(d: np.ndarray, g: np.ndarray, w: np.ndarray, peak: bool, model: tuple) -> tuple:
    """`solve`'s answer, read from the cache where it holds this program's, else solved and kept."""
    folder = cache_dir()
    if folder is None:
        return solve(d, g, w, peak, model)
    path = folder / f"{program_key(d, g, w, peak)}.npz"
    try:
        with np.load(path, allow_pickle=False) as f:
            u, objective, value = f["u"], float(f["objective"]), float(f["value"])
        if u.shape == d.shape and u.dtype == np.float64 and np.all(np.abs(u) <= 1.0):
            return u, objective, value
    except (OSError, EOFError, ValueError, KeyError, TypeError, zipfile.BadZipFile):
        pass  # not kept yet, or not what it should be: solved again below and replaced
    u, objective, value = solve(d, g, w, peak, model)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda p: np.savez_compressed(p, u=u, objective=objective, value=value))
    except OSError:
        pass  # a read-only or full cache: the answer is the same, only not kept
    return u, objective, value


def optimum(episode: Episode, envs: EnvCache | None = None) -> EpisodeOptimum:
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
    model = realisation(g)
    u, objective, through_g = cached_solve(r - y0, g, w, peak, model)
    value = play(u)[1].metrics[sc.main_metric]
    tol = AGREE * float(np.max(np.abs(r - y0))) * (1.0 if peak else float(np.sum(w)))
    if abs(value - through_g) > tol:  # the twin is not its pulse response's convolution: not LTI
        raise ValueError(f"{where}: the twin gave {value:.6g} where its pulse response gives {through_g:.6g}")
    return EpisodeOptimum(
        episode.scenario,
        episode.seed,
        sc.main_metric,
        value,
        objective,
        abs(value - objective) <= tol,
        u,
        len(model[1]),
        time.perf_counter() - start,
    )


class Optimum(Commands):
    """The friction-free optimum as a reference row: on each episode, the optimal commands (`optimum`)
    played on its friction-free twin, every episode of a lockstep at once. Computed before the episodes
    start (Controller.plan), once per episode and process; never an entry."""

    name: ClassVar[str] = "Optimum"
    plans: ClassVar[bool] = True

    def __init__(self) -> None:
        super().__init__(np.zeros((0, 1)))
        self.envs = EnvCache()
        self.solved: dict[Episode, EpisodeOptimum] = {}
        self.exact = True

    def why_not(self, scenario: Scenario) -> str | None:
        return why_not(scenario) or super().why_not(scenario)

    def plan(self, episodes: Sequence[Episode]) -> None:
        for e in episodes:
            if e not in self.solved:
                self.solved[e] = optimum(e, self.envs)
        found = [self.solved[e] for e in episodes]
        self.actions = np.stack([o.actions for o in found])
        self.exact = all(o.exact for o in found)

    def params(self) -> dict:
        return {"exact": self.exact}
