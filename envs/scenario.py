"""Scenarios (configs/scenarios/*.yaml): plant preset, friction model, sampling, reference, initial-state
distribution, randomisation, episode length and reward weights, loaded and checked into a Scenario.

Every scenario file extends configs/scenarios/_defaults.yaml, or another scenario named by `extends:`,
and gives only what differs. A `reference` with another `type` replaces the inherited one whole (each
type has its own keys), in a file and in overrides alike. Every key is read through config.Node: unknown
and missing keys, wrong types and out-of-range values are errors naming the file and the field.
"""

from __future__ import annotations

import copy
import itertools
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from . import measured
from .config import (
    ConfigError,
    Node,
    deep_merge,
    interval,
    load_extending,
    merge,
    number,
    preset_path,
)
from .friction import BRISTLE_MODELS, FRICTION_MODELS, FrictionDrift
from .metrics import METRIC_NAMES, metric_unit
from .plants import PlantSpec, plant_names, plant_spec
from .plants.mjcf import friction_joints
from .references import SEGMENT_KINDS, RandomReference, move_duration, trapezoid_distance
from .sampler import REFERENCE as REFERENCE_STREAM
from .sampler import stream
from .step import REWARD_WEIGHTS, ObservationLayout, observation_layout

REFERENCE_TYPES = (
    "constant",
    "steps",
    "ramps",
    "sine",
    "triangle",
    "chirp",
    "trapezoid",
    "scurve",
    "recorded",
    "random",
)
REGULATION, TRACKING = "regulation", "tracking"  # Scenario.task: a constant reference, any other
TASKS = (REGULATION, TRACKING)
DEFAULTS = "_defaults"  # configs/scenarios/_defaults.yaml, which every scenario extends
MAX_EPISODE_S = 3600.0  # one hour of simulated time
MAX_EPISODE_STEPS = 1_000_000  # the per-episode logs hold 3 floats per step and simulation
MAX_REWARD_WEIGHT = 1e6  # keeps every reward, and the diverged-step reward, finite
# task.output_scale normalises the tracked output (rad or V) in observations and rewards: outside this
# range the observation leaves its ±1e6 clip for any output the plant can reach, or rounds to 0
OUTPUT_SCALE_RANGE = (1e-6, 1e6)
SETTLE_BAND_RANGE = (1e-12, 1e6)  # the settling band (rad or V): from below any encoder's resolution
MIN_FREQUENCY_HZ = 1e-6  # a period of 11 days: slower is a constant reference (type: constant)
MIN_ACTION_SCALE_FRACTION = 1e-6  # an action may not scale to less than a millionth of the command limit
# How the leaderboard scores the friction penalty removed on the main metric (docs/envs.md, "Scores"):
# linear g = (m_unc - m)/(m_unc - m_ideal); log: decades, log10(m_unc/m)/log10(m_unc/m_ideal), where the
# friction-free loop reaches ~0; none: not scored (friction costs the uncompensated loop nothing).
LIMIT_SCORES = ("linear", "log", "none")


@dataclass(frozen=True)
class Reference:
    """Reference generator r(t) in the tracked sensor's unit (rad or V).

    - constant: value.
    - steps: schedule of [t_start, value] (0 before the first).
    - ramps: offset plus the integral of a piecewise-constant rate, schedule of [t_start, rate per s].
    - sine, triangle: offset + amplitude·wave(2π·frequency_hz·t + phase_rad).
    - chirp: offset + amplitude·sin(φ(t)), the frequency swept linearly from frequency_hz to
      end_frequency_hz over sweep_s (then held).
    - trapezoid: point-to-point moves from offset, schedule of [t_start, target], each with a trapezoidal
      velocity profile limited by max_velocity and max_acceleration (units per s, per s²), finished
      before the next starts.
    - scurve: the same moves with an S-curve (cycloidal) profile, s(τ) = d·(τ/T - sin(2πτ/T)/(2π)):
      continuous acceleration, peak velocity 2d/T and peak acceleration 2πd/T² within the limits.
    - recorded: a measured signal replayed, scale·x(t), each sample held until the next (t from the
      recording's first sample; a log at the control rate replays sample for sample): `signal` of the log
      `file` (envs/measured.py: a .mat or CSV, a path relative to configs/ or absolute), time in
      `time_signal`.
    - random: drawn per episode from its seed (envs/references.py, `family`): `episode(seed, t)`.
    """

    type: str
    value: float = 0.0
    schedule: tuple[tuple[float, float], ...] = ()
    amplitude: float = 0.0
    frequency_hz: float = 0.0
    offset: float = 0.0
    phase_rad: float = 0.0
    max_velocity: float = 0.0
    max_acceleration: float = 0.0
    file: str = ""
    signal: str = ""
    time_signal: str = ""
    scale: float = 1.0
    end_frequency_hz: float = 0.0
    sweep_s: float = 0.0
    family: RandomReference | None = None

    @property
    def per_episode(self) -> bool:
        """Whether each episode draws its own reference (type random)."""
        return self.family is not None

    def episode(self, seed: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reference, load torque N·m) of the episode `seed` on the grid t (type random)."""
        return self.family.draw(stream(seed, REFERENCE_STREAM), t)

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """A recorded reference's sample times (s, from 0) and values (scaled)."""
        rec = measured.load(self.file)
        t = rec.time(self.time_signal)
        return t - t[0], self.scale * rec.signal(self.signal)

    def move_duration(self, distance: float) -> float:
        """Duration (s) of a move over distance: trapezoidal (triangular if it never reaches v_max), or
        S-curve (the shortest cycloid within v_max and a_max)."""
        v, a = self.max_velocity, self.max_acceleration
        if self.type == "scurve":
            return max(2.0 * distance / v, np.sqrt(2.0 * np.pi * distance / a))
        return move_duration(distance, v, a)

    def _profile(self, d: float, tau: np.ndarray) -> np.ndarray:
        """Distance covered τ (s, clipped to the move) into a move of length d."""
        if self.type != "scurve":
            return trapezoid_distance(d, self.max_velocity, self.max_acceleration, tau)
        T = self.move_duration(d)
        tau = np.clip(tau, 0.0, T)
        return d * (tau / T - np.sin(2 * np.pi * tau / T) / (2 * np.pi)) if T > 0 else np.zeros_like(tau)

    def _sweep(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A chirp's phase (rad, without phase_rad) and frequency (Hz) at t: the frequency swept linearly,
        f(t) = f0 + (f1 - f0)·min(t, T)/T, then held at f1; the phase is 2π∫f."""
        f0, f1, T = self.frequency_hz, self.end_frequency_hz, self.sweep_s
        ts = np.minimum(t, T)
        phase = 2 * np.pi * (f0 * ts + 0.5 * (f1 - f0) / T * ts**2 + f1 * (t - ts))
        return phase, f0 + (f1 - f0) * ts / T

    def frequency_hz_at(self, t: np.ndarray | float) -> np.ndarray:
        """The reference's frequency (Hz) at t: a chirp's swept frequency, a sine's or triangle's
        frequency_hz; nan for a reference without one (constant, moves, ramps, recorded, random)."""
        t = np.asarray(t, dtype=float)
        if self.type == "chirp":
            return self._sweep(t)[1]
        if self.type in ("sine", "triangle"):
            return np.full_like(t, self.frequency_hz)
        return np.full_like(t, np.nan)

    def _moves(self, t: np.ndarray) -> np.ndarray:
        out = np.full_like(t, self.offset)
        start = self.offset
        for ts, target in self.schedule:
            s = self._profile(abs(target - start), t - ts)
            out = np.where(t >= ts, start + np.sign(target - start) * s, out)
            start = target
        return out

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.per_episode:
            raise ValueError("a random reference is drawn per episode: Reference.episode(seed, t)")
        if self.type == "constant":
            return np.full_like(t, self.value)
        if self.type == "steps":
            starts = np.array([s for s, _ in self.schedule])
            values = np.array([0.0] + [v for _, v in self.schedule])
            return values[np.searchsorted(starts, t + 1e-12, side="right")]
        if self.type in ("trapezoid", "scurve"):
            return self._moves(t)
        if self.type == "chirp":
            return self.offset + self.amplitude * np.sin(self._sweep(t)[0] + self.phase_rad)
        if self.type == "recorded":  # the last sample at or before t (clock jitter up to 1 % of a period)
            ts, x = self.samples()
            slack = 0.01 * float(np.median(np.diff(ts)))
            return x[np.clip(np.searchsorted(ts, t + slack, side="right") - 1, 0, len(x) - 1)]
        if self.type == "ramps":
            starts = np.array([s for s, _ in self.schedule])
            rates = np.array([r for _, r in self.schedule])
            at_start = self.offset + np.concatenate([[0.0], np.cumsum(rates[:-1] * np.diff(starts))])
            i = np.searchsorted(starts, t + 1e-12, side="right") - 1
            ic = np.maximum(i, 0)
            return np.where(i >= 0, at_start[ic] + rates[ic] * (t - starts[ic]), self.offset)
        w = 2.0 * np.pi * self.frequency_hz * t + self.phase_rad
        if self.type == "sine":
            return self.offset + self.amplitude * np.sin(w)
        return self.offset + self.amplitude * (2.0 / np.pi) * np.arcsin(np.sin(w))  # triangle


@dataclass(frozen=True)
class Scenario:
    """A checked scenario; `spec` is the plant at the scenario's control period."""

    name: str
    spec: PlantSpec
    episode_steps: int
    randomize: bool
    tracked_sensor: int
    output_scale: float
    action_scale: float
    settle_band: float
    reference: Reference
    preview_steps: int
    qpos_range: np.ndarray  # (nv, 2)
    qvel_range: np.ndarray  # (nv, 2)
    random_sign: bool  # the drawn initial state is mirrored (x -1) with probability 1/2
    history: int
    privileged: bool
    reward_weights: dict[str, float]
    disturbance: Reference | None = None  # load torque (N·m) of the rig's disturbance motor, unmeasured
    main_metric: str = "iae"  # what the leaderboard ranks by (every metric: lower is better)
    secondary_metrics: tuple[str, ...] = ()
    why: str = ""  # the friction phenomenon the scenario exercises, and where in the documents
    # False: the friction-free twin: every draw the same, the nonlinear friction (Coulomb, static,
    # Stribeck, presliding, asymmetry bias) removed, the viscous term kept (EpisodeParams.friction_free)
    nonlinear_friction: bool = True
    friction_drift: FrictionDrift | None = None  # friction levels that drift within an episode
    held_out: bool = False  # a generalisation scenario: never trained or selected on (agents/training/)
    uncompensated: str = ""  # name of the loop the physical-limit rows build on (benchmark.uncompensated)
    limit_score: str = "linear"  # how the friction penalty removed is scored (benchmark.limit_score)

    @property
    def control_period(self) -> float:
        return self.spec.control_period

    @cached_property
    def layout(self) -> ObservationLayout:
        """Named slices of this scenario's observation (envs/step.py)."""
        return observation_layout(
            len(self.spec.sensors),
            self.preview_steps,
            self.history,
            self.privileged,
            len(friction_joints(self.spec)),
        )

    @property
    def task(self) -> str:
        """REGULATION (a constant reference) or TRACKING (any other)."""
        return REGULATION if self.reference.type == "constant" else TRACKING

    @property
    def output_unit(self) -> str:
        """The tracked sensor's unit (rad, m or V): the unit of the reference, the output and the error."""
        return self.spec.sensor_unit(self.spec.sensor_names[self.tracked_sensor])

    def metric_unit(self, metric: str) -> str:
        """The unit of one of METRIC_NAMES on this scenario (e.g. iae in rad·s, effort_rms in V rms)."""
        return metric_unit(metric, self.output_unit, self.spec.command_unit)


@dataclass(frozen=True)
class Limits:
    """What a reference (or the load torque) may ask, in its own unit: |value|, |rate| per s, |second
    derivative| per s², start times (s) up to the longest episode the suite allows (a segment after a
    shortened episode's end never comes), frequencies up to Nyquist (Hz)."""

    value: float
    rate: float
    accel: float
    t_max: float
    f_max: float

    @classmethod
    def of_output(cls, spec: PlantSpec, tracked: int) -> Limits:
        """The plant's envelope in the tracked sensor's unit: rad for an encoder, V for a tachometer."""
        env, period = spec.envelope, spec.control_period
        if spec.sensors[tracked].kind == "encoder":
            return cls(env.position_rad, env.speed_rad_s, env.accel_rad_s2, MAX_EPISODE_S, 0.5 / period)
        gain = spec.sensors[tracked].gain
        rate = gain * env.accel_rad_s2
        return cls(gain * env.speed_rad_s, rate, rate / period, MAX_EPISODE_S, 0.5 / period)

    @classmethod
    def of_load_torque(cls, spec: PlantSpec) -> Limits:
        """A load torque up to 10x the drive's peak torque (N·m): beyond it no compensator can hold."""
        tau = 10.0 * spec.command_limit * spec.actuator_gain
        period = spec.control_period
        return cls(tau, tau / period, tau / period**2, MAX_EPISODE_S, 0.5 / period)


def _schedule(r: Node, lim: Limits, rates: bool = False) -> tuple[tuple[float, float], ...]:
    """reference.schedule: a non-empty list of [t_start, value] pairs with increasing start times
    within the episode, values (or rates, for ramps) within the limits."""
    sched = r["schedule"]
    if not isinstance(sched, list) or not sched:
        raise r.error("schedule", "expected a non-empty list of [t_start, value] pairs")
    bound = lim.rate if rates else lim.value
    pairs = []
    for i, p in enumerate(sched):
        f = r.field(f"schedule[{i}]")
        if not isinstance(p, list | tuple) or len(p) != 2:
            raise ConfigError(f, f"expected [t_start, value], got {p!r}", r.source)
        pairs.append(
            (
                r.check(number, p[0], f"{f}[0]", 0.0, lim.t_max),
                r.check(number, p[1], f"{f}[1]", -bound, bound),
            )
        )
    if any(b[0] <= a[0] for a, b in itertools.pairwise(pairs)):
        raise r.error("schedule", "start times must increase")
    return tuple(pairs)


def _reference(r: Node, lim: Limits, load_limit: float = 0.0) -> tuple[Reference, int]:
    """The reference generator and its preview length (steps), every parameter within `lim` (a random
    reference's load torque within load_limit, N·m: 0 on a plant without a disturbance motor)."""
    kind = r.choice("type", REFERENCE_TYPES)
    preview = r.integer("preview_steps", 0, 1000, default=0)
    offset = r.number("offset", -lim.value, lim.value, default=0.0) if kind != "constant" else 0.0
    if kind == "constant":
        return Reference("constant", value=r.number("value", -lim.value, lim.value, default=0.0)), preview
    if kind == "steps":
        return Reference("steps", schedule=_schedule(r, lim)), preview
    if kind == "ramps":
        return Reference("ramps", schedule=_schedule(r, lim, rates=True), offset=offset), preview
    if kind == "recorded":
        ref = Reference(
            "recorded",
            file=r.string("file"),
            signal=r.string("signal"),
            time_signal=r.string("time_signal"),
            scale=r.number("scale", -1e6, 1e6, default=1.0),
        )
        try:
            ts, x = ref.samples()
        except ConfigError as e:
            raise r.error("file", str(e)) from None
        peak, rate = float(np.abs(x).max()), float(np.abs(np.diff(x) / np.diff(ts)).max())
        if peak > lim.value:
            raise r.error(
                "signal", f"the recording reaches {peak:.6g}, beyond the plant's envelope {lim.value}"
            )
        if rate > lim.rate:
            raise r.error(
                "signal", f"the recording moves at {rate:.6g}/s, beyond the envelope's {lim.rate}/s"
            )
        return ref, preview
    if kind == "random":
        return _random(r, lim, load_limit), preview
    if kind == "chirp":
        ref = Reference(
            "chirp",
            amplitude=r.nonneg("amplitude", lim.value),
            frequency_hz=r.number("frequency_hz", MIN_FREQUENCY_HZ, lim.f_max),
            end_frequency_hz=r.number("end_frequency_hz", MIN_FREQUENCY_HZ, lim.f_max),
            sweep_s=r.positive("sweep_s", lim.t_max),
            offset=offset,
            phase_rad=r.number("phase_rad", -2 * np.pi, 2 * np.pi, default=0.0),
        )
        w = 2 * np.pi * max(ref.frequency_hz, ref.end_frequency_hz)
        if abs(ref.offset) + ref.amplitude > lim.value:
            raise r.error("amplitude", f"|offset| + amplitude > {lim.value}")
        if ref.amplitude * w > lim.rate or ref.amplitude * w * w > lim.accel:
            raise r.error("amplitude", "the sweep's peak rate or acceleration exceeds the plant's envelope")
        return ref, preview
    if kind in ("trapezoid", "scurve"):
        ref = Reference(
            kind,
            schedule=_schedule(r, lim),
            offset=offset,
            max_velocity=r.positive("max_velocity", lim.rate),
            max_acceleration=r.positive("max_acceleration", lim.accel),
        )
        start = ref.offset
        for i, ((ts, target), nxt) in enumerate(itertools.zip_longest(ref.schedule, ref.schedule[1:])):
            end = ts + ref.move_duration(abs(target - start))
            if nxt is not None and end > nxt[0]:
                raise r.error(f"schedule[{i}]", f"the move ends at {end:.4g} s, after the next starts")
            start = target
        return ref, preview
    ref = Reference(
        kind,
        amplitude=r.nonneg("amplitude", lim.value, default=0.0),
        frequency_hz=r.number("frequency_hz", MIN_FREQUENCY_HZ, lim.f_max),  # up to the control's Nyquist
        offset=offset,
        phase_rad=r.number("phase_rad", -2 * np.pi, 2 * np.pi, default=0.0),
    )
    if abs(ref.offset) + ref.amplitude > lim.value:
        raise r.error("amplitude", f"|offset| + amplitude = {abs(ref.offset) + ref.amplitude} > {lim.value}")
    return ref, preview


def _load_torque(r: Node, limit: float) -> float:
    """A random reference's load torque during holds (N·m, or N on a carriage), within the plant's
    disturbance-motor limit; any other than 0 is refused on a plant without one."""
    if limit == 0 and r.get("load_torque", 0.0) != 0.0:
        raise r.error("load_torque", f"{r['load_torque']!r}: the plant has no disturbance motor")
    return r.number("load_torque", 0.0, limit, default=0.0)


def _random(r: Node, lim: Limits, load_limit: float) -> Reference:
    """A random reference family (envs/references.py) within the limits."""
    kinds = r["segments"]
    if not isinstance(kinds, list) or not kinds or any(k not in SEGMENT_KINDS for k in kinds):
        raise r.error("segments", f"expected a non-empty list of segment kinds from {list(SEGMENT_KINDS)}")
    seg = r.interval("segment_s", 1e-3, MAX_EPISODE_S)  # s: at least a millisecond
    family = RandomReference(
        kinds=tuple(kinds),
        segment_s=seg,
        amplitude=r.positive("amplitude", lim.value),
        speeds=r.interval("speeds", 0.0, lim.rate),
        max_acceleration=r.positive("max_acceleration", lim.accel),
        frequency_hz=r.interval("frequency_hz", MIN_FREQUENCY_HZ, lim.f_max),
        load_torque=_load_torque(r, load_limit),
    )
    if family.speeds[0] <= 0 and any(k in kinds for k in ("ramp", "sine", "trapezoid", "reversal")):
        raise r.error("speeds", "moving segments need speeds above 0")
    return Reference("random", family=family)


# A drift or step may lower the levels to 10 % (1 - 0.9) or raise them to 4x: beyond, the friction is
# another machine's. Both factors stay positive, so every level keeps its sign and |bias| < fc.
DRIFT_FRACTION_RANGE = (-0.9, 3.0)


def _drift(c: Node) -> FrictionDrift | None:
    """The scenario's friction_drift section (null: constant friction within an episode)."""
    if c.get("friction_drift") is None:
        return None
    if c["friction_model"] not in BRISTLE_MODELS:
        raise c.error(
            "friction_drift", f"drifting friction levels need a friction_model of {list(BRISTLE_MODELS)}"
        )
    d = c.section("friction_drift")
    return FrictionDrift(
        drift=d.interval("drift", *DRIFT_FRACTION_RANGE),
        step=d.interval("step", *DRIFT_FRACTION_RANGE),
        step_at_s=d.interval("step_at_s", 0.0, MAX_EPISODE_S),  # a step after the end never comes
    )


def _new_reference(base: dict, extra: Mapping) -> dict | None:
    """extra's reference if it changes the reference type (it then replaces base's whole), else None."""
    ref = extra.get("reference")
    if (
        isinstance(ref, Mapping)
        and "type" in ref
        and ref["type"] != (base.get("reference") or {}).get("type")
    ):
        return copy.deepcopy(dict(ref))
    return None


def _extend(base: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
    """A scenario over the one it extends: deep-merged, except that a reference of another type
    replaces the parent's instead of merging into it."""
    ref = _new_reference(base, data)
    out = deep_merge(base, data)
    if ref is not None:
        out["reference"] = ref
    return out


def scenario_config(name_or_path: str | Path) -> dict[str, Any]:
    """The scenario's YAML over what it extends (another scenario, or the defaults file)."""
    return load_extending(name_or_path, "scenarios", DEFAULTS, _extend)


def _ranges(init: Node, key: str, nv: int, bound: float) -> np.ndarray:
    """(nv, 2) [low, high] per joint of initial_state.<key>, within ±bound (the plant's envelope)."""
    value = init[key]
    if not isinstance(value, list) or len(value) != nv:
        raise init.error(key, f"expected {nv} [low, high] pairs (one per joint), got {value!r}")
    return np.array(
        [init.check(interval, v, f"{init.field(key)}[{i}]", -bound, bound) for i, v in enumerate(value)]
    )


def _plant(c: Node) -> str:
    """The scenario's plant: a preset of configs/plants, or the path of a preset file (a lab's own drive,
    e.g. the plant.yaml that scripts/identify.py idim drafts)."""
    plant = c["plant"]
    if isinstance(plant, str) and (
        plant in plant_names() or (plant.endswith(".yaml") and Path(plant).is_file())
    ):
        return plant
    raise c.error(
        "plant", f"{plant!r} is neither a preset of configs/plants {plant_names()} nor a preset file"
    )


def load_scenario(name_or_path: str | Path, overrides: dict | None = None, **kwargs: Any) -> Scenario:
    """Load a scenario by name or path; `overrides` deep-merges YAML keys (a reference with a new type
    replaces the scenario's), kwargs set top-level keys (e.g. control_period_s=0.04, randomize=True,
    episode_s=5); None values are ignored."""
    path = preset_path(name_or_path, "scenarios")
    src = path.name
    cfg = scenario_config(path)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError("overrides", f"expected a mapping of scenario keys, got {overrides!r}", src)
    overrides = dict(overrides or {})
    # plant overrides are checked against the plant preset (plant_spec), not the scenario's own dict
    plant_extra = overrides.pop("plant_overrides", None) or {}
    if not isinstance(plant_extra, Mapping):
        raise ConfigError("plant_overrides", f"expected a mapping of plant keys, got {plant_extra!r}", src)
    ref = _new_reference(cfg, overrides)
    if ref is not None:
        cfg["reference"] = ref
        overrides.pop("reference")
    cfg = merge(cfg, overrides, source=src)
    cfg = merge(cfg, {k: v for k, v in kwargs.items() if v is not None}, source=src)
    c = Node(cfg, src)
    plant_ov = c["plant_overrides"]
    if not isinstance(plant_ov, Mapping):
        raise c.error("plant_overrides", f"expected a mapping of plant keys, got {plant_ov!r}")
    plant_ov = deep_merge(dict(plant_ov), plant_extra)
    if c.get("control_period_s") is not None:  # else the plant preset's own period
        period = c.positive("control_period_s", 1.0)
        plant_ov["sampling"] = {**plant_ov.get("sampling", {}), "control_period_s": period}
    randomize = c.boolean("randomize")
    spec = plant_spec(
        _plant(c),
        plant_ov,
        c.choice("friction_model", FRICTION_MODELS),
        check_ranges=randomize,  # ranges that are never drawn from are not checked
        prefix="plant_overrides.",
    )
    period = spec.control_period
    task = c.section("task")
    names = spec.sensor_names
    tracked = names.index(task.choice("tracked_sensor", names))
    unit_key = "action_scale_nm" if spec.command_unit == "N·m" else "action_scale_v"
    action_scale = task.number(unit_key, MIN_ACTION_SCALE_FRACTION * spec.command_limit, spec.command_limit)
    episode = c.positive("episode_s", MAX_EPISODE_S)
    steps = round(episode / period)
    if abs(steps * period - episode) > 1e-9 * episode:
        raise c.error("episode_s", f"{episode} must be a whole number of control periods ({period})")
    if steps > MAX_EPISODE_STEPS:
        raise c.error("episode_s", f"{steps} control periods > {MAX_EPISODE_STEPS}")
    load_limit = Limits.of_load_torque(spec).value if spec.disturbance_joint is not None else 0.0
    reference, preview = _reference(c.section("reference"), Limits.of_output(spec, tracked), load_limit)
    init = c.section("initial_state")
    n_init = 1 if spec.belts else len(spec.joints)
    obs, rw = c.section("observation"), c.section("reward")
    scenario = Scenario(
        name=path.stem,
        spec=spec,
        episode_steps=steps,
        randomize=randomize,
        tracked_sensor=tracked,
        output_scale=task.number("output_scale", *OUTPUT_SCALE_RANGE),
        action_scale=action_scale,
        settle_band=task.number("settle_band", *SETTLE_BAND_RANGE),
        reference=reference,
        preview_steps=preview,
        qpos_range=_ranges(init, "qpos", n_init, spec.envelope.position_rad),
        qvel_range=_ranges(init, "qvel", n_init, spec.envelope.speed_rad_s),
        random_sign=init.boolean("random_sign"),
        history=obs.integer("history", 0, 1000),
        privileged=obs.boolean("privileged"),
        reward_weights={k: rw.nonneg(k, MAX_REWARD_WEIGHT) for k in REWARD_WEIGHTS},
        nonlinear_friction=c.boolean("nonlinear_friction"),
        friction_drift=_drift(c),
        held_out=c.boolean("held_out"),
    )
    if c.get("disturbance") is not None:
        if spec.disturbance_joint is None:
            raise c.error("disturbance", f"plant {spec.name} has no disturbance motor")
        if reference.per_episode and reference.family.load_torque > 0:
            raise c.error("disturbance", "a random reference with a load_torque draws its own load torque")
        load = Limits.of_load_torque(spec)
        scenario = replace(scenario, disturbance=_reference(c.section("disturbance"), load)[0])
    for key, ref in (("reference", scenario.reference), ("disturbance", scenario.disturbance)):
        if ref is None or ref.type != "recorded":
            continue
        recorded_s = float(ref.samples()[0][-1])
        if recorded_s < (steps - 1) * period - 1e-9:
            raise c.error("episode_s", f"{episode} s is longer than the recorded {key} ({recorded_s:.6g} s)")
    b = c.section("benchmark")
    main = b.choice("main_metric", METRIC_NAMES)
    secondary = b["secondary_metrics"]
    if not isinstance(secondary, list) or any(m not in METRIC_NAMES for m in secondary):
        raise b.error("secondary_metrics", f"expected a list of metrics from {list(METRIC_NAMES)}")
    why = b["why"]
    if not isinstance(why, str) or not why.strip():
        raise b.error("why", "expected one line saying which friction phenomenon, and where in the documents")
    loop = b["uncompensated"]
    if not isinstance(loop, str) or not loop.strip():
        raise b.error("uncompensated", "expected the name of the scenario's uncompensated loop, e.g. PD")
    b.get("uncompensated_why")
    scenario = replace(
        scenario,
        main_metric=main,
        secondary_metrics=tuple(secondary),
        why=why.strip(),
        uncompensated=loop,
        limit_score=b.choice("limit_score", LIMIT_SCORES),
    )
    c.get("description")
    c.done()
    return scenario
