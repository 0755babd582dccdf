"""Inverse-model identification of a drive from closed-loop logs: the IDIM-LS method of the EMPS
description (§3, Janot, Gautier, Brunot 2019), and the same inverse model with each friction structure of
the suite, fitted on one log and cross-tested on another.

The method (EMPS §3.1-3.4): the measured position is filtered by a Butterworth filter forward and
backward (zero phase), differentiated twice by central differences, the first samples are dropped, every
column of the observation matrix and the force gτ·ν are low-pass filtered and decimated, and the
parameters are the least-squares solution of y = Φ·θ (eq. 10), with the description's standard deviations
σ̂_e·sqrt(diag((ΦᵀΦ)⁻¹)). `matlab_filtfilt` and `matlab_decimate` follow MATLAB's filtfilt and decimate,
which the published numbers were computed with, so that they are reproduced to their printed digits.

Friction structures (`STRUCTURES`) add columns to [q̈ ...]: the published symmetric (eq. 1-2) and
asymmetric (eq. 12) models, the Stribeck term of LuGre's static map (Iurian et al. 2005 eq. 2), LuGre's
presliding (bristle state, Iurian et al. 2005 eq. 1), the simulator's Maxwell-slip presliding (§1.4.7), Kang's
stick band (Kang 1998 eq. 1-4) and a position-dependent force along the screw. A structure with a nonlinear
parameter (Stribeck velocity, presliding length) is fitted by profiling the least-squares cost over it; its 95
% interval is where N_eff·ln(SSE/SSE_min) <= χ²₁(0.95), and it is resolved by the data when that interval is
bounded inside the searched range.

Intervals of the linear parameters are t-intervals from the description's standard deviations, widened
for the residuals' lag-1 autocorrelation ρ (N_eff = N·(1-ρ)/(1+ρ)); the description's own standard
deviations (column `std`) assume white residuals and are narrower.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cache

import numpy as np
from scipy import optimize, signal, stats

from frictiongym.envs.config import ConfigError
from frictiongym.envs.friction import KANG_STICK_BAND, MAXWELL_SLIP_LENGTHS, MAXWELL_SLIP_SHARES
from frictiongym.envs.plants import plant_spec

from .drive_log import DriveLog, emps_log

ALPHA = 0.05  # 95 % intervals


@dataclass(frozen=True)
class IdimSettings:
    """The data processing of EMPS §3.1-3.2: Butterworth order and cut-off (Hz, ωfq >= 5 ωdyn), decimation
    band (Hz, ωFp >= 2 ωdyn), the first sample kept (1-based, as the script's n_border), and the
    actuation delay in samples (the force at k is gτ·ν(k - delay); 0 in the published processing)."""

    butterworth_order: int = 4
    cutoff_hz: float = 100.0
    decimate_band_hz: float = 40.0
    first_sample: int = 50
    delay_samples: int = 0

    def factor(self, period: float) -> int:
        """The decimation factor round(0.8·f_Nyquist/band) of the EMPS script (10 at 1 kHz, 40 Hz)."""
        return max(1, round(0.8 * 0.5 / period / self.decimate_band_hz))


PUBLISHED = IdimSettings()  # the processing of the published numbers


def matlab_filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Zero-phase filtering as MATLAB's filtfilt: odd reflection of 3·(n-1) samples at each end, where n
    is the filter's length (scipy's default pads 3·n)."""
    return signal.filtfilt(b, a, x, padtype="odd", padlen=3 * (max(len(a), len(b)) - 1))


def matlab_decimate(x: np.ndarray, r: int) -> np.ndarray:
    """MATLAB's decimate(x, r): order-8 Chebyshev I low-pass (0.05 dB ripple, cut-off 0.8/r of Nyquist)
    applied forward and backward, then every r-th sample ending at the last one."""
    if r == 1:
        return np.asarray(x, float)
    b, a = signal.cheby1(8, 0.05, 0.8 / r)
    y = matlab_filtfilt(b, a, np.asarray(x, float))
    first = r - (r * math.ceil(len(x) / r) - len(x))  # 1-based, as MATLAB's nbeg
    return y[first - 1 :: r]


def central_difference(x: np.ndarray, h: float) -> np.ndarray:
    """dx/dt by central differences (one-sided at the ends), as the EMPS script's diffcent."""
    return np.gradient(x, h, edge_order=1)


@dataclass(frozen=True)
class States:
    """Filtered position, velocity, acceleration (unit, /s, /s²) and force (N or N·m) of one log, after
    dropping the first samples; period in s."""

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    force: np.ndarray
    period: float
    source: str


def states(log: DriveLog, settings: IdimSettings = IdimSettings()) -> States:
    """The bandpass-filtered states of EMPS §3.1 and the force gτ·ν (delayed by settings.delay_samples)."""
    h = log.period
    wn = settings.cutoff_hz / (0.5 / h)
    if not 0.0 < wn < 1.0:
        raise ConfigError("cutoff_hz", f"{settings.cutoff_hz} Hz must be below Nyquist ({0.5 / h:g} Hz)")
    b, a = signal.butter(settings.butterworth_order, wn)
    q = matlab_filtfilt(b, a, log.position)
    dq = central_difference(q, h)
    ddq = central_difference(dq, h)
    force = log.force
    if settings.delay_samples:
        force = np.concatenate([np.full(settings.delay_samples, force[0]), force[: -settings.delay_samples]])
    keep = slice(settings.first_sample - 1, None)
    return States(q[keep], dq[keep], ddq[keep], force[keep], h, log.source)


# ------------------------------------------------------------------------------------ structures
def bristle_state(v: np.ndarray, length: float, h: float) -> np.ndarray:
    """Normalised LuGre bristle deflection s = σ0·z/Fc along a velocity record (Iurian et al. 2005 eq. 1 with
    g = Fc and σ0 = Fc/length): ds/dt = (v - |v|·s)/length, integrated exactly over each sample with v
    held. s -> sign(v) in sliding; after a reversal it takes a travel of about `length` to turn."""
    decay = np.exp(-np.abs(v) * h / length)
    target = np.sign(v)
    out = np.empty_like(v)
    x = 0.0
    for k in range(len(v)):
        x = target[k] + (x - target[k]) * decay[k]
        out[k] = x
    return out


def _legendre(q: np.ndarray, n: int) -> np.ndarray:
    """Legendre polynomial P_n over the log's position range mapped to [-1, 1]."""
    lo, hi = float(q.min()), float(q.max())
    return np.polynomial.legendre.Legendre.basis(n)(2.0 * (q - lo) / max(hi - lo, 1e-12) - 1.0)


Columns = Callable[[States, float], list[np.ndarray]]


@dataclass(frozen=True)
class Structure:
    """One inverse-model structure: parameter names (units in the names), its columns of Φ given the
    states and the nonlinear parameter (if any: its name, search range and unit), and its source."""

    name: str
    params: tuple[str, ...]
    columns: Columns
    source: str
    nonlinear: str | None = None
    search: tuple[float, float] = (0.0, 0.0)


def _pos(s: States) -> np.ndarray:
    return (s.dq > 0).astype(float)


def _neg(s: States) -> np.ndarray:
    return (s.dq < 0).astype(float)


def _asym(s: States) -> list[np.ndarray]:
    """eq. (12): Fv+·0+(q̇) + Fc+·sign(0+(q̇)) + Fv-·0-(q̇) + Fc-·sign(0-(q̇)), magnitudes Fc±."""
    return [s.dq * _pos(s), _pos(s), s.dq * _neg(s), -_neg(s)]


def _stribeck(s: States, vs: float) -> list[np.ndarray]:
    """(Fs± - Fc±)·sign(v)·exp(-(v/vs)²) per direction: LuGre's static map minus its Coulomb part."""
    e = np.exp(-((s.dq / vs) ** 2))
    return [_pos(s) * e, -_neg(s) * e]


def _position(s: States) -> list[np.ndarray]:
    """A force varying along the travel (P1..P3) and a Coulomb level varying along it (sign(v)·P1..P3)."""
    return [_legendre(s.q, n) for n in (1, 2, 3)] + [np.sign(s.dq) * _legendre(s.q, n) for n in (1, 2, 3)]


POSITION_PARAMS = ("force_P1_n", "force_P2_n", "force_P3_n", "coulomb_P1_n", "coulomb_P2_n", "coulomb_P3_n")
ASYM_PARAMS = ("viscous_pos_n_s_per_m", "coulomb_pos_n", "viscous_neg_n_s_per_m", "coulomb_neg_n")


def _split(s: States, b: np.ndarray) -> list[np.ndarray]:
    """eq. (12) with sign(q̇) replaced by a presliding state b in [-1, 1]: Fc± on b > 0 / b < 0."""
    return [s.dq * _pos(s), b * (b > 0), s.dq * _neg(s), b * (b < 0)]


def _lugre(s: States, length: float) -> list[np.ndarray]:
    """eq. (12) with sign(q̇) replaced by the bristle state (σ0 = Fc/length)."""
    return _split(s, bristle_state(s.dq, length, s.period))


def _maxwell_slip(s: States, length: float) -> list[np.ndarray]:
    """eq. (12) with sign(q̇) replaced by the simulator's Maxwell-slip state (envs/friction.py): the
    shares α_k of four bristle states with presliding lengths r_k·c·length (c = Σ α_j/r_j)."""
    c = sum(a / r for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True))
    b = sum(
        a * bristle_state(s.dq, r * c * length, s.period)
        for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True)
    )
    return _split(s, b)


def _kang(s: States) -> list[np.ndarray]:
    """Seed 001 eq. 1-4: eq. (12) plus the static levels' excess within the simulator's stick band,
    KANG_STICK_BAND times the EMPS preset's Stribeck velocity."""
    return [*_asym(s), *_stribeck(s, KANG_STICK_BAND * _emps_stribeck_velocity())]


@cache
def _emps_stribeck_velocity() -> float:

    return plant_spec("emps").drive_friction.vs


STRUCTURES: dict[str, Structure] = {
    st.name: st
    for st in (
        Structure(
            "coulomb_viscous",
            ("mass_kg", "viscous_n_s_per_m", "coulomb_n", "offset_n"),
            lambda s, _: [s.ddq, s.dq, np.sign(s.dq), np.ones_like(s.dq)],
            "EMPS eq. (1)-(2), the published IDIM-LS model",
        ),
        Structure(
            "coulomb_viscous_asym",
            ("mass_kg", *ASYM_PARAMS),
            lambda s, _: [s.ddq, *_asym(s)],
            "EMPS eq. (12), §4.2",
        ),
        Structure(
            "coulomb_viscous_asym_offset",
            ("mass_kg", *ASYM_PARAMS, "offset_n"),
            lambda s, _: [s.ddq, *_asym(s), np.ones_like(s.dq)],
            "eq. (12) plus the offset of eq. (1)",
        ),
        Structure(
            "stribeck_asym",
            ("mass_kg", *ASYM_PARAMS, "stribeck_pos_n", "stribeck_neg_n"),
            lambda s, vs: [s.ddq, *_asym(s), *_stribeck(s, vs)],
            "eq. (12) plus the Stribeck term of LuGre's static map (Iurian et al. 2005 eq. 2), per direction",
            "stribeck_velocity_m_s",
            (1e-4, 0.1),
        ),
        Structure(
            "lugre_asym",
            ("mass_kg", *ASYM_PARAMS),
            lambda s, length: [s.ddq, *_lugre(s, length)],
            "eq. (12) with LuGre's bristle state for sign(v) (Iurian et al. 2005 eq. 1, g = Fc: Dahl's "
            "state, §1.4.1; the Stribeck part is stribeck_asym's): presliding length Fc/σ0",
            "presliding_length_m",
            (1e-7, 1e-3),
        ),
        Structure(
            "maxwell_slip_asym",
            ("mass_kg", *ASYM_PARAMS),
            lambda s, length: [s.ddq, *_maxwell_slip(s, length)],
            "eq. (12) with the simulator's Maxwell-slip presliding (four elements, Iurian et al. 2005 "
            "§1.4.7): LuGre-equivalent presliding length",
            "presliding_length_m",
            (1e-7, 1e-3),
        ),
        Structure(
            "kang_asym",
            ("mass_kg", *ASYM_PARAMS, "stick_excess_pos_n", "stick_excess_neg_n"),
            lambda s, _: [s.ddq, *_kang(s)],
            "Kang 1998 eq. 1-4 (Kang's stick-slip model): eq. (12) plus the static excess within the "
            "simulator's stick band",
        ),
        Structure(
            "position_asym",
            ("mass_kg", *ASYM_PARAMS, *POSITION_PARAMS),
            lambda s, _: [s.ddq, *_asym(s), *_position(s)],
            "eq. (12) plus a force and a Coulomb level varying along the screw (Legendre P1-P3 in position)",
        ),
        Structure(
            "stribeck_position_asym",
            ("mass_kg", *ASYM_PARAMS, "stribeck_pos_n", "stribeck_neg_n", *POSITION_PARAMS),
            lambda s, vs: [s.ddq, *_asym(s), *_stribeck(s, vs), *_position(s)],
            "stribeck_asym and position_asym together",
            "stribeck_velocity_m_s",
            (1e-4, 0.1),
        ),
    )
}
CONDITION_LIMIT = 1e4  # Φ this ill-conditioned (the published Φ: 26): the structure is not identifiable


# ------------------------------------------------------------------------------------------ fits
@dataclass(frozen=True)
class Interval:
    """A value with its 95 % interval (inf bounds: not resolved by the data)."""

    value: float
    low: float
    high: float

    @property
    def resolved(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)

    def __format__(self, spec: str) -> str:
        f = spec or ".5g"
        return f"{self.value:{f}} [{self.low:{f}}, {self.high:{f}}]"


@dataclass(frozen=True)
class Fit:
    """An inverse-model fit: parameters (value, description-style std, 95 % interval), the nonlinear
    parameter's profile interval (if any), and the direct-validation figures of EMPS §3.4 on the decimated
    data: relative error (%, eq. 11), error norm, standard deviation of the error, condition number of Φ."""

    structure: str
    names: tuple[str, ...]
    theta: np.ndarray
    std: np.ndarray
    intervals: tuple[Interval, ...]
    nonlinear: tuple[str, Interval] | None
    relative_error_pct: float
    error_norm: float
    error_std: float
    condition_number: float
    samples: int
    settings: IdimSettings

    @property
    def identifiable(self) -> bool:
        """Φ is well conditioned and the nonlinear parameter (if any) is resolved by the data."""
        ok = self.condition_number < CONDITION_LIMIT
        return ok and (self.nonlinear is None or self.nonlinear[1].resolved)

    def value(self, name: str) -> float:
        return float(self.theta[self.names.index(name)])

    def extra(self) -> float:
        """The nonlinear parameter's value (nan without one)."""
        return self.nonlinear[1].value if self.nonlinear else math.nan


@dataclass(frozen=True)
class Validation:
    """EMPS §3.4 cross-test: the force of another log rebuilt with a fit's parameters."""

    relative_error_pct: float
    error_norm: float
    error_std: float
    condition_number: float
    force: np.ndarray  # measured, decimated (N)
    predicted: np.ndarray  # Φ·θ (N)
    t: np.ndarray  # time of the decimated samples (s, from the first kept sample)


def relative_error(y: np.ndarray, y_hat: np.ndarray) -> float:
    """EMPS eq. (11): 100·‖y - ŷ‖/‖y‖ (%)."""
    return 100.0 * float(np.linalg.norm(y - y_hat) / np.linalg.norm(y))


def observation(
    structure: Structure, s: States, extra: float, settings: IdimSettings
) -> tuple[np.ndarray, np.ndarray]:
    """Decimated Φ and y (EMPS §3.2) of one structure on one log's states."""
    r = settings.factor(s.period)
    cols = structure.columns(s, extra)
    return np.column_stack([matlab_decimate(c, r) for c in cols]), matlab_decimate(s.force, r)


def _solve(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    theta = np.linalg.lstsq(X, y, rcond=None)[0]
    e = y - X @ theta
    return theta, float(e @ e)


def effective_samples(e: np.ndarray) -> float:
    """N·(1-ρ)/(1+ρ) for the lag-1 autocorrelation ρ >= 0 of the residuals e."""
    e = e - e.mean()
    rho = max(0.0, float(e[1:] @ e[:-1] / (e @ e)))
    return len(e) * (1 - rho) / (1 + rho)


def fit(structure: str | Structure, s: States, settings: IdimSettings = IdimSettings()) -> Fit:
    """Least squares of one structure on one log's states (profiling the nonlinear parameter, if any)."""
    st = STRUCTURES[structure] if isinstance(structure, str) else structure
    nonlinear = None
    extra = math.nan
    if st.nonlinear is not None:
        extra, interval = _profile(st, s, settings)
        nonlinear = (st.nonlinear, interval)
    X, y = observation(st, s, extra, settings)
    theta = _solve(X, y)[0]
    e = y - X @ theta
    n, p = X.shape
    cond = float(np.linalg.cond(X))
    try:
        cov = np.linalg.inv(X.T @ X)
        std = float(np.std(e, ddof=1)) * np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        std = np.full(p, math.inf)
    n_eff = effective_samples(e)
    q = stats.t.ppf(1 - ALPHA / 2, max(n_eff - p, 1)) * math.sqrt(n / n_eff)
    intervals = tuple(
        Interval(float(v), float(v - q * sd), float(v + q * sd)) for v, sd in zip(theta, std, strict=True)
    )
    return Fit(
        st.name,
        st.params,
        theta,
        std,
        intervals,
        nonlinear,
        relative_error(y, X @ theta),
        float(np.linalg.norm(e)),
        float(np.std(e, ddof=1)),
        cond,
        n,
        settings,
    )


def _profile(st: Structure, s: States, settings: IdimSettings) -> tuple[float, Interval]:
    """The nonlinear parameter minimising the least-squares cost (log-spaced search, then Brent), and its
    profile-likelihood 95 % interval (unbounded on a side where the cost stays below the threshold up to
    the searched range's end)."""
    lo, hi = st.search

    def cost(log_x: float) -> float:
        return _solve(*observation(st, s, math.exp(log_x), settings))[1]

    grid = np.linspace(math.log(lo), math.log(hi), 31)
    costs = np.array([cost(g) for g in grid])
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = optimize.minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-4})
    x0, c0 = float(best.x), float(best.fun)
    X, y = observation(st, s, math.exp(x0), settings)
    n_eff = effective_samples(y - X @ _solve(X, y)[0])
    limit = c0 * math.exp(stats.chi2.ppf(1 - ALPHA, 1) / n_eff)

    def edge(side: int) -> float:
        pts = grid[grid > x0] if side > 0 else grid[grid < x0][::-1]
        prev = x0
        for g in pts:
            if cost(g) > limit:
                return math.exp(
                    optimize.brentq(lambda z: cost(z) - limit, min(prev, g), max(prev, g), xtol=1e-4)
                )
            prev = g
        return math.inf if side > 0 else -math.inf

    low, high = edge(-1), edge(+1)
    return math.exp(x0), Interval(math.exp(x0), low, high)


def cross_test(f: Fit, s: States) -> Validation:
    """EMPS §3.4: the force of another log (its states s) rebuilt as Φ·θ with the fit's parameters."""
    st = STRUCTURES[f.structure]
    X, y = observation(st, s, f.extra(), f.settings)
    y_hat = X @ f.theta
    e = y - y_hat
    r = f.settings.factor(s.period)
    t = matlab_decimate(np.arange(len(s.force)) * s.period, r)
    return Validation(
        relative_error(y, y_hat),
        float(np.linalg.norm(e)),
        float(np.std(e, ddof=1)),
        float(np.linalg.cond(X)),
        y,
        y_hat,
        t,
    )


# ------------------------------------------------------------------------------------ the table
@dataclass(frozen=True)
class ModelRow:
    """One row of the friction-model table: a structure under one processing (actuation delay), fitted on
    the estimation log, cross-tested on the validation log."""

    fit: Fit
    validation: Validation | None  # None without a validation log

    @property
    def delay_samples(self) -> int:
        return self.fit.settings.delay_samples


def model_table(
    estimation: DriveLog,
    validation: DriveLog | None,
    structures: tuple[str, ...] = tuple(STRUCTURES),
    delays: tuple[int, ...] = (0, 1),
    settings: IdimSettings = IdimSettings(),
) -> list[ModelRow]:
    """Every structure under every actuation delay: fitted on `estimation` only, cross-tested on
    `validation` if there is one (the validation log never enters a fit)."""
    rows = []
    for d in delays:
        cfg = replace(settings, delay_samples=d)
        se = states(estimation, cfg)
        sv = states(validation, cfg) if validation is not None else None
        for name in structures:
            f = fit(name, se, cfg)
            rows.append(ModelRow(f, cross_test(f, sv) if sv is not None else None))
    return rows


@cache
def emps_table() -> tuple[ModelRow, ...]:
    """The model table of the EMPS logs (cached per process: the reproduction report and the identify
    front end both read it)."""

    return tuple(model_table(emps_log("estimation"), emps_log("validation")))


def markdown_table(rows: list[ModelRow] | tuple[ModelRow, ...]) -> str:
    """The friction-model table: per structure and actuation delay, the relative errors (%) of the fit on
    the estimation log and of the cross-test on the validation log (rows that have one), the condition
    number of Φ, the nonlinear parameter with its 95 % profile interval, and whether the data identify
    the structure."""
    lines = [
        "| structure | delay (samples) | estimation rel. error % | cross-test rel. error % | cond(Φ) | "
        "nonlinear parameter [95 %] | identifiable |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in (r for r in rows if r.validation is not None):
        f = r.fit
        nl = f"{f.nonlinear[0]} = {f.nonlinear[1]:.3g}" if f.nonlinear else ""
        lines.append(
            f"| {f.structure} | {r.delay_samples} | {f.relative_error_pct:.3f} | "
            f"{r.validation.relative_error_pct:.3f} | {f.condition_number:.3g} | {nl} | "
            f"{'yes' if f.identifiable else '**no**'} |"
        )
    return "\n".join(lines)


def markdown_parameters(f: Fit) -> str:
    """A fit's parameters: value, the description-style standard deviation, and the 95 % interval."""
    lines = ["| parameter | value | std (white residuals) | 95 % interval (autocorrelation-adjusted) |"]
    lines.append("|---|---|---|---|")
    for name, v, sd, iv in zip(f.names, f.theta, f.std, f.intervals, strict=True):
        lines.append(f"| {name} | {v:.6g} | {sd:.4g} | [{iv.low:.5g}, {iv.high:.5g}] |")
    if f.nonlinear:
        lines.append(f"| {f.nonlinear[0]} | {f.nonlinear[1].value:.4g} | | {f.nonlinear[1]:.4g} |")
    return "\n".join(lines)
