"""Identification experiments run on a simulated plant as a lab would run them on the rig (Iurian et al. 2005
§2.2-2.3, generalised): the same sensors (quantised encoders, noisy tachometers), the same sampled command,
the plant's delay. Each returns a fits.Log, as read from a hardware CSV log.

- step: open-loop command step v from rest (§2.2).
- holds: PI velocity control at a list of speeds, both directions, one segment per hold (§2.3).
- breakaway: a slow command ramp from rest, each direction, until the drive moves (static levels).
- presliding: a small sinusoidal command well below breakaway (bristle stiffness σ0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from frictiongym.envs.plants import plant_module, plant_spec
from frictiongym.envs.plants.identified import drive_friction, speed_ratios
from frictiongym.envs.plants.params import EpisodeParams, spec_with
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.plants.spec import PlantSpec

from .fits import Log


@dataclass
class Rig:
    """A simulated rig: the plant (nominal, or the randomised draw of `seed`) and its drive sensor."""

    sim: PlantSim
    spec: PlantSpec  # the true spec of this rig (with the draw's parameters)
    params: EpisodeParams
    provenance: list[str]
    clock: float = 0.0  # log time (s): continues across the experiment's parts

    @classmethod
    def of(
        cls, plant: str | PlantSpec, seed: int = 0, randomize: bool = False, overrides: dict | None = None
    ) -> Rig:
        """The rig of a plant preset (or a built spec, e.g. a scenario's): the nominal plant, or with
        `randomize` the draw of `seed`, the same draw an env makes for that episode seed."""
        spec = plant_spec(plant, overrides) if isinstance(plant, str) else plant
        params = EpisodeParams.draw(spec, seed) if randomize else EpisodeParams.nominal(spec)
        params.validate(spec)
        sim = PlantSim(spec)
        sim.reset(params, seed=seed)
        prov = [
            f"simulated plant {spec.name}, seed {seed}, randomize {randomize} "
            "(frictiongym.agents.lab.experiments)"
        ]
        return cls(sim, spec_with(spec, params), params, prov)

    @property
    def sensor(self) -> int:
        """Index of the drive's sensor (an encoder if there is one, else a tachometer)."""
        sens = [i for i, s in enumerate(self.spec.sensors) if s.joint == self.spec.actuator_joint]
        enc = [i for i in sens if self.spec.sensors[i].kind == "encoder"]
        return (enc or sens)[0]

    @property
    def has_position(self) -> bool:
        return self.spec.sensors[self.sensor].kind == "encoder"

    def read(self, measurement: np.ndarray) -> float:
        """The drive reading in SI: angle (rad) from an encoder, speed (rad/s) from a tachometer."""
        s = self.spec.sensors[self.sensor]
        y = float(measurement[self.sensor])
        return y if s.kind == "encoder" else y / s.gain

    def run(self, command, steps: int, segment: int = -1) -> tuple[list, list, list, list]:
        """Run `steps` control periods with u_k = command(k, reading); rows of (t, u, reading, segment)."""
        t0, h = self.clock, self.spec.control_period
        self.clock += steps * h
        y = self.read(self.sim.read().measurement)
        ts, us, ys, ss = [], [], [], []
        for k in range(steps):
            u = float(np.clip(command(k, y), -self.spec.command_limit, self.spec.command_limit))
            ts.append(t0 + k * h)
            us.append(u)
            ys.append(y)
            ss.append(segment)
            res = self.sim.step(u)
            if res.diverged:
                raise RuntimeError("the simulation diverged during the experiment")
            y = self.read(res.measurement)
        return ts, us, ys, ss

    def log(self, rows: tuple[list, list, list, list], what: str) -> Log:
        t, u, y, s = (np.asarray(x) for x in rows)
        unit = "V" if self.spec.command_unit == "V" else "Nm"
        pos = y if self.has_position else None
        spd = None if self.has_position else y
        return Log(t, u, unit, pos, spd, s.astype(int), [*self.provenance, f"experiment: {what}"])

    def rest(self) -> None:
        """Back to rest at the origin, parameters kept (bristles relaxed)."""
        self.sim.reset(self.params)

    # ------------------------------------------------------------------ drive-referred nominal numbers
    def inertia(self) -> float:
        """Drive-referred inertia at low frequency (kg·m²): every joint turns with the drive."""
        r = speed_ratios(self.spec)
        return sum(j.inertia * r[j.name] ** 2 for j in self.spec.joints)


def step(rig: Rig, v: float, duration_s: float) -> Log:
    """Open-loop command step v from rest (Iurian et al. 2005 §2.2)."""
    rig.rest()
    n = round(duration_s / rig.spec.control_period)
    return rig.log(rig.run(lambda k, y: v, n, 0), f"step of {v} {rig.spec.command_unit} for {duration_s} s")


def holds(rig: Rig, speeds: Sequence[float], hold_s: float, bandwidth: float | None = None) -> Log:
    """PI velocity holds (Iurian et al. 2005 §2.3) at each speed (rad/s, signed), one segment each, from rest.
    The PI is designed on the drive-referred inertia J and gain G: crossover ω_c (default 0.2/h rad/s), k_p =
    ω_c·J/G, integral time 4/ω_c. Speed is measured from the encoder (position difference over one period) or
    the tachometer."""
    h, g, J = rig.spec.control_period, rig.spec.actuator_gain, rig.inertia()
    wc = bandwidth or 0.2 / h
    kp, ki = wc * J / g, wc * J / g * wc / 4.0
    rows: tuple[list, list, list, list] = ([], [], [], [])
    n = round(hold_s / h)
    for i, w in enumerate(speeds):
        rig.rest()
        state = {"prev": None, "integral": 0.0}

        def pi(k: int, y: float, w: float = w, state: dict = state) -> float:
            if rig.has_position:
                speed = 0.0 if state["prev"] is None else (y - state["prev"]) / h
                state["prev"] = y
            else:
                speed = y
            e = w - speed
            state["integral"] += ki * e * h
            return kp * e + state["integral"]

        for acc, part in zip(rows, rig.run(pi, n, i), strict=True):
            acc += part
    log = rig.log(rows, f"PI velocity holds at {list(speeds)} rad/s, {hold_s} s each")
    log.reference = np.repeat(np.asarray(speeds, float), n)
    return log


def breakaway(rig: Rig, rate: float, limit: float, threshold: float) -> Log:
    """A command ramp u = ±rate·t from rest (segment 0: positive, 1: negative) until the drive has moved
    2·threshold (rad, or rad/s for a tachometer) or |u| reaches `limit`. breakaway_levels(log, threshold)
    then reads the static levels."""
    rows: tuple[list, list, list, list] = ([], [], [], [])
    h = rig.spec.control_period
    for seg, sign in enumerate((1.0, -1.0)):
        rig.rest()
        y0 = rig.read(rig.sim.read().measurement)
        n = math.ceil(limit / rate / h)
        part = rig.run(lambda k, y, sign=sign: sign * rate * k * h, n, seg)
        moved = [abs(y - y0) >= 2 * threshold for y in part[2]]
        end = moved.index(True) + 1 if any(moved) else n
        for acc, p in zip(rows, part, strict=True):
            acc += p[:end]
    return rig.log(rows, f"breakaway ramps at {rate} {rig.spec.command_unit}/s, threshold {threshold}")


def presliding(rig: Rig, amplitude: float, frequency_hz: float, cycles: int = 2) -> Log:
    """A sinusoidal command amplitude·sin(2π·f·t) from rest, well below breakaway: presliding only."""
    rig.rest()
    h = rig.spec.control_period
    n = round(cycles / frequency_hz / h)
    w = 2 * math.pi * frequency_hz
    return rig.log(
        rig.run(lambda k, y: amplitude * math.sin(w * k * h), n, 0),
        f"presliding: {amplitude} {rig.spec.command_unit} at {frequency_hz} Hz, {cycles} cycles",
    )


@dataclass(frozen=True)
class Protocol:
    """A lab's experiment settings for one plant (SI, command units), from its document and nominal preset."""

    speeds: tuple[float, ...]  # hold speeds (rad/s, positive; both directions are run)
    hold_s: float
    step_v: float  # step command (cu)
    step_s: float
    ramp_rate: float  # breakaway ramp (cu/s)
    ramp_limit: float  # (cu)
    threshold: float  # breakaway: drive motion (rad, or rad/s with a tachometer)
    presliding_amplitude: float  # (cu)
    presliding_hz: float
    breakaway: bool  # False where a ramp measures only the motor side (a compliant shaft)


def protocol(plant: str | PlantSpec) -> Protocol:
    """Default experiments: hold speeds over the range the document worked in, long enough to settle, a
    breakaway ramp at 1/20 of the nominal static level per second, presliding at 1/10 of it (nearly
    linear bristles). On the flexible servo the weak shaft (resonance near 4 rad/s, lightly damped)
    needs 12 s holds, and a ramp breaks the motor shaft away while the load still sticks (it measures
    the motor side only): no breakaway there, the static levels come from the holds."""
    spec = plant_spec(plant) if isinstance(plant, str) else plant
    plant = spec.name
    nominal = drive_friction(spec)
    fs = max(nominal.static_pos, nominal.static_neg)
    sensor = [s for s in spec.sensors if s.joint == spec.actuator_joint]
    encoder = [s for s in sensor if s.kind == "encoder"]
    # hold speeds: the plant module's, from its document (a plant without them: 0.05-5 rad/s)
    lo, hi = getattr(plant_module(plant), "IDENTIFICATION_SPEEDS_RAD_S", (0.05, 5.0))
    speeds = tuple(float(x) for x in np.geomspace(lo, hi, 8))
    # breakaway: motion beyond presliding. LuGre's presliding displacement grows as -(Fs/σ0)·ln(1 - F/Fs)
    # while the force nears Fs, so a threshold of n·Fs/σ0 fires at F = (1 - e^-n)·Fs: n = 50 keeps that
    # exact for σ0 down to a fifth of the nominal (n = 5 read 8-11 % low on Kang draws with soft bristles)
    threshold = max(10 * encoder[0].resolution, 50 * fs / nominal.sigma0) if encoder else 0.05 * lo
    compliant = bool(spec.springs)
    return Protocol(
        speeds=speeds,
        hold_s=12.0 if compliant else 2.0,
        step_v=getattr(spec.document, "step_input_v", 2.5 * fs),  # the document's step (M220 §2.2), if any
        step_s=5.0,
        ramp_rate=fs / 20.0,
        ramp_limit=3.0 * fs,
        threshold=threshold,
        presliding_amplitude=0.1 * min(nominal.static_pos, nominal.static_neg),
        presliding_hz=0.1,
        breakaway=not compliant,
    )


def run_all(
    rig: Rig, p: Protocol, which: tuple[str, ...] = ("step", "holds", "breakaway", "presliding")
) -> dict[str, Log]:
    """The protocol's experiments on the rig (those in `which`; breakaway only where the protocol has it)."""
    runs = {
        "step": lambda: step(rig, p.step_v, p.step_s),
        "holds": lambda: holds(rig, [*p.speeds, *(-v for v in p.speeds)], p.hold_s),
        "breakaway": lambda: breakaway(rig, p.ramp_rate, p.ramp_limit, p.threshold),
        "presliding": lambda: presliding(rig, p.presliding_amplitude, p.presliding_hz),
    }
    return {k: runs[k]() for k in which if k != "breakaway" or p.breakaway}
