"""References drawn per episode (`reference: {type: random, ...}`): from the episode's seed alone (its own
named stream, envs/sampler.py), a sequence of segments within the scenario's limits, in the tracked
output's unit (rad for an encoder, m for a carriage, V for a tachometer):

- step: a set-point step to a level drawn in ±amplitude, then held;
- ramp: a constant rate drawn in ±speeds (reflected at ±amplitude);
- sine: a sinusoid about the current value, frequency in frequency_hz, its amplitude bounded by the
  speed and the acceleration limits;
- trapezoid: a point-to-point move to a level in ±amplitude (trapezoidal velocity at a speed drawn in
  `speeds` and max_acceleration), then held;
- reversal: a triangle about the current value (half-amplitude 0.1-0.5 amplitude) at a speed drawn in
  `speeds`: velocity reversals;
- hold: the current value held (zero speed), with a load-torque step drawn in ±load_torque on a plant
  with a disturbance motor.

Segments follow each other continuously (a step jumps, by design); each lasts a duration drawn in
segment_s. Ramps, triangles and sines that reach ±amplitude fold back into it (a reversal at the edge).
The generator works on the control-period grid; the reference and the load torque are sample-and-hold
over each period, as every reference of a scenario is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SEGMENT_KINDS = ("step", "ramp", "sine", "trapezoid", "reversal", "hold")


@dataclass(frozen=True)
class RandomReference:
    """The family's parameters (output unit u): kinds drawn uniformly; segment_s (s), amplitude (u),
    speeds (u/s), max_acceleration (u/s²), frequency_hz (Hz) and load_torque (N·m, 0 = none)."""

    kinds: tuple[str, ...]
    segment_s: tuple[float, float]
    amplitude: float
    speeds: tuple[float, float]
    max_acceleration: float
    frequency_hz: tuple[float, float]
    load_torque: float = 0.0

    def draw(self, rng: np.random.Generator, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reference, load torque) on the grid t (s, from 0, evenly spaced), one episode's draw."""
        n = len(t)
        dt = float(t[1] - t[0]) if n > 1 else 1.0
        r, load = np.zeros(n), np.zeros(n)
        i, value = 0, 0.0
        while i < n:
            kind = self.kinds[int(rng.integers(len(self.kinds)))]
            steps = max(1, round(float(rng.uniform(*self.segment_s)) / dt))
            tau = np.arange(1, min(steps, n - i) + 1) * dt  # time into the segment at each sample
            seg, torque = self._segment(kind, rng, value, tau)
            r[i : i + len(tau)], load[i : i + len(tau)] = seg, torque
            i += len(tau)
            value = float(seg[-1])
        return r, load

    def _segment(
        self, kind: str, rng: np.random.Generator, x0: float, tau: np.ndarray
    ) -> tuple[np.ndarray, float]:
        A, a_max = self.amplitude, self.max_acceleration
        speed = float(rng.uniform(*self.speeds))
        if kind == "step":
            return np.full(len(tau), float(rng.uniform(-A, A))), 0.0
        if kind == "hold":
            torque = float(rng.uniform(-self.load_torque, self.load_torque)) if self.load_torque else 0.0
            return np.full(len(tau), x0), torque
        if kind == "ramp":
            direction = 1.0 if rng.random() < 0.5 else -1.0
            return _reflect(x0 + direction * speed * tau, A), 0.0
        if kind == "reversal":  # a triangle of half-amplitude h about x0, slope ±speed
            h = float(rng.uniform(0.1, 0.5)) * A
            tri = (2.0 / math.pi) * np.arcsin(np.sin(speed / h * math.pi / 2 * tau))
            return _reflect(x0 + h * tri, A), 0.0
        if kind == "sine":  # about x0, its amplitude within the speed and acceleration limits
            w = 2 * math.pi * float(rng.uniform(*self.frequency_hz))
            amp = min(A, speed / w, a_max / w**2)
            return _reflect(x0 + amp * np.sin(w * tau), A), 0.0
        if kind == "trapezoid":
            target = float(rng.uniform(-A, A))
            return _trapezoid(x0, target, speed, a_max, tau), 0.0
        raise ValueError(f"segment kind {kind!r} not in {SEGMENT_KINDS}")


def _reflect(x: np.ndarray, bound: float) -> np.ndarray:
    """x folded back into [-bound, bound] (a ramp reverses at the envelope's edge)."""
    period = 4.0 * bound
    y = np.mod(x + bound, period)
    return np.where(y <= 2 * bound, y - bound, 3 * bound - y)


def move_duration(d: float, v: float, a: float) -> float:
    """Duration (s) of a trapezoidal move over distance d at speed v and acceleration a (triangular if it
    never reaches v)."""
    return d / v + v / a if d >= v * v / a else 2.0 * np.sqrt(d / a)


def trapezoid_distance(d: float, v: float, a: float, tau: np.ndarray) -> np.ndarray:
    """Distance covered tau (s, clipped to the move) into a trapezoidal move of length d."""
    T = move_duration(d, v, a)
    tau = np.clip(tau, 0.0, T)
    ta = min(v / a, np.sqrt(d / a))  # acceleration phase
    vp = a * ta  # peak velocity
    return np.where(
        tau < ta,
        0.5 * a * tau**2,
        np.where(tau <= T - ta, 0.5 * a * ta**2 + vp * (tau - ta), d - 0.5 * a * (T - tau) ** 2),
    )


def _trapezoid(x0: float, x1: float, v: float, a: float, tau: np.ndarray) -> np.ndarray:
    """A move x0 -> x1 with a trapezoidal (or triangular) velocity profile, then held at x1."""
    return x0 + math.copysign(1.0, x1 - x0) * trapezoid_distance(abs(x1 - x0), v, a, tau)
