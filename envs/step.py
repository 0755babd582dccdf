"""What one env step computes, as small pure functions shared by the single env's plain-float path and the
vectorised path (ServoCore): sensor readings, observation layout and packing, reward terms and info.

Each function takes Python floats or numpy arrays (one row per simulation) and does the same IEEE
operations in the same order either way; where a primitive differs (floor, min) the caller passes the
float or the array version (`FLOAT`, `ARRAY`). That is how the n = 1 fast path stays bit-identical to the
vector env (tests check it) without a second copy of the arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property, reduce
from operator import iadd, itemgetter
from typing import Any, NamedTuple

import numpy as np

OBS_CLIP = 1e6  # observations are clipped here and never NaN (a diverged simulation ends the episode)


class Ops(NamedTuple):
    """The primitives that differ between floats and arrays."""

    floor: Callable[[Any], Any]
    minimum: Callable[[Any, Any], Any]
    sin: Callable[[Any], Any]
    abs: Callable[[Any], Any]


FLOAT = Ops(math.floor, min, math.sin, abs)
ARRAY = Ops(np.floor, np.minimum, np.sin, np.abs)


# ---------------------------------------------------------------------------------------------- sensors
def encoder_reading(theta: Any, resolution: Any, ops: Ops) -> Any:
    """Incremental encoder: whole lines passed, floor(θ/res)·res (rad); θ includes any noise."""
    return ops.floor(theta / resolution) * resolution


def tacho_reading(omega: Any, gain: Any, noise: Any) -> Any:
    """Tachometer: gain·ω + noise (V); ripple, when configured, is added by the caller."""
    return gain * omega + noise


# ---------------------------------------------------------------------------------------------- observation
@dataclass(frozen=True)
class ObservationLayout:
    """Named slices of the flat observation (like Gymnasium's observation_structure), in order.

    entries: (name, size, meaning) per block; `slice(name)` gives its place; `size` the total length.
    """

    entries: tuple[tuple[str, int, str], ...]

    @property
    def size(self) -> int:
        return sum(n for _, n, _ in self.entries)

    @cached_property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, n, _ in self.entries if n)

    def slice(self, name: str) -> slice:
        try:
            return self._slices[name]
        except KeyError:
            blocks = [e[0] for e in self.entries]
            raise KeyError(f"no block {name!r} in the observation; blocks: {blocks}") from None

    @cached_property
    def _slices(self) -> dict[str, slice]:
        """Each block's place, computed once (every classical controller decodes an observation per step)."""
        out, start = {}, 0
        for entry, n, _ in self.entries:
            out[entry] = slice(start, start + n)
            start += n
        return out

    def structure(self) -> dict[str, int]:
        """{block name: size}, the sizes of every block (0 for blocks this scenario leaves out)."""
        return {name: n for name, n, _ in self.entries}

    def pack(self, parts: Mapping[str, Any]) -> Any:
        """Concatenate the blocks in layout order: lists of floats give a list, (n, k) arrays an array."""
        blocks = self._blocks(parts)
        if isinstance(blocks[0], list):
            return reduce(iadd, blocks, [])  # extends one new list: the cheapest for a few short lists
        return np.concatenate(blocks, axis=1)

    @cached_property
    def _blocks(self) -> Callable[[Mapping[str, Any]], tuple[Any, ...]]:
        """The non-empty blocks of a parts mapping, in order (a tuple: there are always at least two,
        the reference and the previous action)."""
        return itemgetter(*self.names)

    def table(self) -> str:
        """The reStructuredText table of the blocks (used in the env docstrings)."""
        w = max(len(f"{name} ({n})") for name, n, _ in self.entries)
        rule = f"    {'=' * w}  {'=' * max(len(m) for _, _, m in self.entries)}"
        lines = [rule, f"    {'block (entries)':<{w}}  meaning", rule]
        lines += [f"    {f'{name} ({n})':<{w}}  {meaning}" for name, n, meaning in self.entries]
        return "\n".join([*lines, rule])


def observation_layout(
    n_sensors: int, preview_steps: int, history: int, privileged: bool, n_friction: int
) -> ObservationLayout:
    """The layout for a scenario's sizes (see ServoEnv's docstring for the meaning of each block).
    With the sizes given as names (strings), the layout describes every scenario (for docs)."""
    symbolic = isinstance(n_sensors, str)
    hist = f"{history}·({n_sensors} + 1)" if symbolic else history * (n_sensors + 1)
    priv = f"1 + 2·{n_friction} if {privileged}" if symbolic else (1 + 2 * n_friction) if privileged else 0
    return ObservationLayout(
        (
            ("sensors", n_sensors, "sensor readings / s (encoder angle in rad, quantised; tacho in V)"),
            ("reference", 1, "reference r(t_k) / s"),
            ("preview", preview_steps, "r(t_{k+1}) ... r(t_{k+P}) / s"),
            ("previous_action", 1, "the action being held, in [-1, 1]"),
            ("history", hist, "past (readings / s, action) samples, newest first"),
            (
                "privileged",
                priv,
                "true output / s, friction torques and bristle forces σ0·z per friction joint, "
                "in units of a full-scale action's torque",
            ),
        )
    )


def sanitize_observation(obs: np.ndarray | list[float]) -> np.ndarray:
    """float32, finite, within ±OBS_CLIP (NaN -> 0): what a diverged simulation may otherwise produce.
    A list of floats (the single env's path) is checked in plain Python, an array with numpy."""
    if isinstance(obs, list):
        # max of |v| may skip a NaN that is not first, but the sum is NaN then (C loops, no generator)
        if max(map(abs, obs)) <= OBS_CLIP and (s := sum(obs)) == s:
            return np.array(obs, dtype=np.float32)
        obs = np.array(obs)
    if not np.abs(obs).max() <= OBS_CLIP:  # also catches NaN
        obs = np.clip(np.nan_to_num(np.asarray(obs, dtype=float), nan=0.0), -OBS_CLIP, OBS_CLIP)
    return np.asarray(obs, dtype=np.float32)


# ---------------------------------------------------------------------------------------------- reward
REWARD_WEIGHTS = ("tracking", "tracking_abs", "effort", "smoothness")  # a scenario's reward.<name>
REWARD_TERMS = tuple(f"reward_{w}" for w in REWARD_WEIGHTS)  # their terms in ``info``


def reward_terms(e: Any, a: Any, a_prev: Any, weights: Mapping[str, float], ops: Ops) -> dict[str, Any]:
    """Terms of the reward: -w_t·min((e/s)², CLIP), -w_a·min(|e/s|, CLIP), -w_u·a², -w_du·(a - a_prev)²;
    e already divided by s. The absolute term weighs small errors (a set-point's last mrad) more against
    large ones than the squared term, as IAE and the final error do. Each term is within [-w·CLIP, 0]
    (actions are clipped to [-1, 1])."""
    return {
        "reward_tracking": -weights["tracking"] * ops.minimum(e * e, OBS_CLIP),
        "reward_tracking_abs": -weights["tracking_abs"] * ops.minimum(ops.abs(e), OBS_CLIP),
        "reward_effort": -weights["effort"] * a * a,
        "reward_smoothness": -weights["smoothness"] * ((a - a_prev) * (a - a_prev)),
    }


def diverged_reward(weights: Mapping[str, float]) -> float:
    """The reward of a diverged step: 1 below the worst any other step can score (each term of
    reward_terms is at least -w·CLIP, -w_a·CLIP, -w_u and -4·w_du for actions in [-1, 1])."""
    worst = (weights["tracking"] + weights["tracking_abs"]) * OBS_CLIP
    return -(worst + weights["effort"] + 4.0 * weights["smoothness"]) - 1.0


def reward_total(terms: Mapping[str, Any]) -> Any:
    """The reward: the sum of its terms."""
    t = terms
    return t["reward_tracking"] + t["reward_tracking_abs"] + t["reward_effort"] + t["reward_smoothness"]


def step_info(
    terms: Mapping[str, Any], command: Any, reference: Any, output: Any, time: Any, diverged: Any
) -> dict[str, Any]:
    """The per-step info entries (reward terms, command, reference, true output, time, diverged)."""
    return {
        **terms,
        "command": command,
        "reference": reference,
        "output": output,
        "time": time,
        "diverged": diverged,
    }
