"""Gymnasium environments: one class over the shared core, four thin per-plant subclasses.

One `step` = one control period: the action is held (ZOH) over the period, the plant's actuation delay,
jitter and sensor models apply, and the observation is what a digital controller reads at the next
sampling instant.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import EzPickle

from .config import boolean
from .core import ServoCore, check_action, check_options, new_renderer, render_frame
from .metrics import defined_metrics
from .records import pyplot
from .sampler import check_seed
from .scenario import Scenario, load_scenario
from .step import OBS_CLIP, observation_layout

OBSERVATION_DOC = f"""
    Observation (float32, flat Box), blocks in this order (``env.unwrapped.layout`` names their slices);
    s = the scenario's ``task.output_scale``:

{observation_layout("n_sensors", "preview_steps", "history", "privileged", "n_friction").table()}

    Action: Box(-1, 1, (1,)). The amplifier command is action · ``task.action_scale`` (V or N·m), then
    clipped by the plant's limit. Classical controllers convert with ``command_to_action`` /
    ``action_to_command`` and read physical readings with ``decode_observation``.

    Reward: ``-(w_t·min((e/s)², 1e6) + w_a·min(|e/s|, 1e6) + w_u·a² + w_du·(a - a_prev)²)`` with e = true
    output - reference at the new sample (w_a is 0 in every built-in scenario: a training option); the
    terms are in ``info`` as reward_tracking, reward_tracking_abs, reward_effort, reward_smoothness and sum
    to the reward. A diverged simulation (MuJoCo reset it, or its state is not finite) ends the episode
    (terminated, ``info["diverged"]``) with a reward below that of any step that did not diverge.
    ``info`` also holds the command, the true output, the reference and the time, at reset the episode's
    parameters, at the end ``info["episode_metrics"]``. The ground truth (qpos, qvel, bristle,
    friction_torque) comes from ``env.unwrapped.ground_truth()``, or in ``info`` with
    ``ground_truth_in_info=True`` (it costs ≈ 1.5 µs per step, ~5 % of the M220's step).
"""

ARGUMENTS_DOC = """
    Arguments (``gym.make(id, ...)``; a per-scenario id fixes ``scenario``):

    - ``scenario``: a name of configs/scenarios/ or the path of a scenario YAML (default: the plant's
      default scenario).
    - ``randomize``: draw friction, inertia, delay and sensor noise from the plant's ranges at each reset
      (default: the scenario's own setting).
    - ``control_period_s``: the controller's sampling period, s (default: the plant preset's).
    - ``episode_s``: the episode's length, s (default: the scenario's).
    - ``overrides``: scenario keys deep-merged into its YAML, each checked, and ``plant_overrides`` for
      the plant preset's (an identified drive's preset, for example).
    - ``render_mode``: ``"rgb_array"`` (a 640 x 480 frame; headless: ``MUJOCO_GL=egl``) or None.
    - ``ground_truth_in_info``: put qpos, qvel, bristle state and friction torque into ``info``.
"""
ENV_DOC = OBSERVATION_DOC + ARGUMENTS_DOC


def check_plant(scenario: Scenario, plant: str | None) -> None:
    """Refuse a scenario of another plant than the env's (plant None: any)."""
    if plant is not None and scenario.spec.name != plant:
        raise ValueError(f"scenario {scenario.name!r} is for plant {scenario.spec.name!r}, not {plant!r}")


def json_safe_spec(spec: EnvSpec | None) -> EnvSpec | None:
    """The spec gym.make gives an env, with a Path scenario written as its str, so that spec.to_json()
    and pickling the spec work (the env reads either form alike)."""
    if spec is None or not isinstance(spec.kwargs.get("scenario"), Path):
        return spec
    return dataclasses.replace(spec, kwargs={**spec.kwargs, "scenario": str(spec.kwargs["scenario"])})


class JsonSafeSpec:
    """The spec gym.make / gym.make_vec give an env, kept JSON-safe (json_safe_spec) as it is set."""

    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        self._spec = json_safe_spec(value)


def decode_observation(scenario: Scenario, obs: np.ndarray, trusted: bool = False) -> dict[str, Any]:
    """Physical readings from an observation, by the scenario's layout: sensors (rad or V), reference,
    preview, held command. The observation must have the layout's shape and be finite; `trusted`: it
    comes straight from the env's step (always so: sanitize_observation), and is not checked again (the
    suite's controllers decode one per step)."""
    lay, s = scenario.layout, scenario.output_scale
    if not trusted:
        obs = np.asarray(obs)
        if obs.shape != (lay.size,) or obs.dtype.kind not in "fiu":
            raise ValueError(f"expected an observation of shape ({lay.size},), got {obs.dtype} {obs.shape}")
        if not np.isfinite(obs).all():
            raise ValueError(f"observation must be finite, got {obs}")
    return {
        "sensors": dict(zip(scenario.spec.sensor_names, obs[lay.slice("sensors")] * s, strict=True)),
        "reference": float(obs[lay.slice("reference")][0] * s),
        "preview": obs[lay.slice("preview")] * s,
        "previous_command": float(obs[lay.slice("previous_action")][0] * scenario.action_scale),
    }


class ServoEnv(JsonSafeSpec, gym.Env, EzPickle):
    __doc__ = "A friction-dominated servo under sampled-data control (frictiongym)." + ENV_DOC
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 25}
    default_scenario = "kang_regulation"
    plant: str | None = None

    def __init__(
        self,
        scenario: str | Path | None = None,
        *,
        randomize: bool | None = None,
        control_period_s: float | None = None,
        episode_s: float | None = None,
        overrides: dict | None = None,
        render_mode: str | None = None,
        ground_truth_in_info: bool = False,
    ):
        EzPickle.__init__(
            self,
            scenario,
            randomize=randomize,
            control_period_s=control_period_s,
            episode_s=episode_s,
            overrides=overrides,
            render_mode=render_mode,
            ground_truth_in_info=ground_truth_in_info,
        )
        self.ground_truth_in_info = boolean(ground_truth_in_info, "ground_truth_in_info")
        self.scenario: Scenario = load_scenario(
            self.default_scenario if scenario is None else scenario,
            overrides,
            randomize=randomize,
            control_period_s=control_period_s,
            episode_s=episode_s,
        )
        check_plant(self.scenario, self.plant)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not in {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.core = ServoCore(self.scenario)
        self.layout = self.core.layout  # named slices of the observation
        self.observation_structure = self.layout.structure()
        self.observation_space = spaces.Box(-OBS_CLIP, OBS_CLIP, (self.core.obs_dim,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self._renderer: mujoco.Renderer | None = None
        self._ids = np.array([0])
        self._started = self._closed = False

    # --------------------------------------------------------------- Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode. With seed, the episode (parameters, initial state, noise, jitter) is a function
        of the seed alone; without, the next seed comes from the env's generator.
        options={"params": {"friction_scale": 1.3, ...}} pins parameters (randomization keys) for this
        episode; the others are drawn as usual. info["params"] holds the episode's parameters and
        info["pinned"] the pinned values."""
        if self._closed:
            raise RuntimeError("reset() after close(): make a new env")
        if seed is not None:
            seed = check_seed(seed)  # any integer type, as the vector env takes it (Gymnasium wants int)
        pinned = check_options(options)
        super().reset(seed=seed)
        episode_seed = seed if seed is not None else int(self.np_random.integers(2**63))
        obs = self.core.reset(self._ids, [episode_seed], pinned)
        self._started = True
        info = {"params": self.core.params_dict(0), "pinned": pinned, "episode_seed": episode_seed}
        if self.ground_truth_in_info:
            info.update(self.core.ground_truth(0))
        return obs[0], info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if not self._started:
            if self._closed:
                raise RuntimeError("step() after close(): make a new env")
            raise RuntimeError("step() before reset(): call reset() first")
        if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
            x = float(action[0])  # the common case, without the general checks' cost
        else:
            x = float(check_action(action, 1)[0])
        obs, reward, term, trunc, info = self.core.step_single(x)
        if self.ground_truth_in_info:
            info.update(self.core.ground_truth(0))
        if term or trunc:
            info["episode_metrics"] = defined_metrics(self.core.metrics(0))
        return obs, reward, term, trunc, info

    # --------------------------------------------------------------- copy and pickle
    def __getstate__(self) -> dict[str, Any]:
        """The constructor's arguments (EzPickle), the env's random generator and spec, and the episode in
        progress, so that a copy (copy.deepcopy, pickle) steps on from the same state, bit for bit."""
        state = EzPickle.__getstate__(self)
        state.update(np_random=self._np_random, np_random_seed=self._np_random_seed, spec=self._spec)
        if self._started:
            state["episode"] = self.core.snapshot()
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        EzPickle.__setstate__(self, state)  # a new env from the constructor's arguments
        self._np_random, self._np_random_seed, self._spec = (
            state["np_random"],
            state["np_random_seed"],
            state["spec"],
        )
        if "episode" in state:
            self.core.restore(state["episode"])
            self._started = True

    def render(self) -> np.ndarray | None:
        """An RGB frame of the disks (headless: set MUJOCO_GL=egl or osmesa)."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = new_renderer(self.core.model)
        return render_frame(self._renderer, self.core.backend.data)

    def close(self) -> None:
        """Release the renderer; the env cannot step or reset after it (closing twice is fine)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._started, self._closed = False, True

    def ground_truth(self) -> dict[str, np.ndarray]:
        """True states now: joint angles (qpos, rad) and velocities (qvel, rad/s), bristle deflections of
        the friction structure's LuGre elements (bristle, rad: one per frictional joint for lugre, dahl and
        kang, four per joint for maxwell_slip, none for coulomb), friction torques on the frictional joints
        (friction_torque, N·m: every element, or the frictionloss constraint) and their nonlinear part
        (nonlinear_friction_torque, N·m, without the viscous term). In info after every step and reset with
        ground_truth_in_info=True."""
        return self.core.ground_truth(0)

    # --------------------------------------------------------------- helpers for classical controllers
    def command_to_action(self, command: float) -> np.ndarray:
        """Amplifier command (V or N·m, a finite real scalar) -> action."""
        return np.array([check_action(command, 1)[0] / self.scenario.action_scale], dtype=np.float32)

    def action_to_command(self, action: np.ndarray | float) -> float:
        """Action (a finite real scalar, or shape (1,)) -> amplifier command (V or N·m), after the
        [-1, 1] clip."""
        return float(np.clip(check_action(action, 1)[0], -1, 1) * self.scenario.action_scale)

    def decode_observation(self, obs: np.ndarray) -> dict[str, Any]:
        """Physical readings from an observation (see decode_observation)."""
        return decode_observation(self.scenario, obs)

    def plot_episode(self, path: str | Path | None = None):
        """Matplotlib figure of the current episode: reference and true output, error, command."""
        if path is not None:  # a file: the file backend (records.pyplot)
            plt = pyplot()
        else:  # shown where the user's backend draws it
            import matplotlib.pyplot as plt  # the user's backend: a figure to show

        g = self.core.episode_log(0)
        sens = self.scenario.spec.sensors[self.scenario.tracked_sensor]
        unit = self.scenario.output_unit
        fig, ax = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
        ax[0].plot(g["t"], g["reference"], "--", label="reference")
        ax[0].plot(g["t"], g["output"], label=f"output ({sens.name}, true)")
        ax[0].set_ylabel(unit)
        ax[0].legend()
        ax[1].plot(g["t"], g["output"] - g["reference"])
        ax[1].set_ylabel(f"error ({unit})")
        ax[2].step(g["t"], g["command"], where="pre")
        ax[2].set(ylabel=f"command ({self.scenario.spec.command_unit})", xlabel="t (s)")
        ax[0].set_title(f"{self.scenario.name}")
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
            plt.close(fig)
        return fig


class M220Env(ServoEnv):
    description = (
        "The ECP Model 220 industrial emulator (Iurian et al. 2005, part 2): a brushless drive disk, a "
        "belt to a speed-reduction (SR) pulley, a second belt to the load disk; LuGre friction, lumped "
        "on the drive shaft, from the document's asymmetric steady-state table. Encoders on the drive "
        "and the load (rad, 16000 counts/rev); the command is the amplifier voltage (V). The position "
        "loop tracks the drive encoder: stick-slip at low speed and set-points within a few counts make "
        "it hard."
    )
    __doc__ = description + ENV_DOC
    default_scenario = "m220_regulation"
    plant = "m220"


class FlexibleServoEnv(ServoEnv):
    description = (
        "Wallenborg's two-inertia flexible servo (Wallenborg 1987, §3): a DC motor's inertia J1 coupled "
        "by a torsional shaft spring to the load inertia J2, Coulomb friction on both shafts, "
        "tachometers on both (V, 0.1 V per rad/s); the command is the amplifier voltage (V, ±10 V), "
        "sampled at 40 ms. Speed loops on the motor tacho; the spring's resonance and the friction at "
        "zero speed make limit cycles."
    )
    __doc__ = description + ENV_DOC
    default_scenario = "flexible_speed_step"
    plant = "flexible_servo"


class KangRobotEnv(ServoEnv):
    description = (
        "Kang's single-axis robot (Kang 1998, §6): one rotor of large inertia with asymmetric static "
        "friction well above its Coulomb level, an encoder (rad), an analog rate loop around the motor, "
        "and a torque command (N·m) sampled at 20 ms. A PD loop stops anywhere inside its stick band; "
        "set-point regulation and ramps."
    )
    __doc__ = description + ENV_DOC
    default_scenario = "kang_regulation"
    plant = "kang_robot"


class EMPSEnv(ServoEnv):
    description = (
        "The EMPS prismatic drive (Janot, Gautier, Brunot 2019): a carriage on a ball screw driven by a "
        "DC motor, identified from the published measurements (the simulation is checked against them, "
        "docs/emps.md). An encoder (m, 50 nm) and an amplifier voltage command (V, ±10 V, "
        "gτ = 35.15 N/V); position tracking of the lab's trajectory, pulses and random references."
    )
    __doc__ = description + ENV_DOC
    default_scenario = "emps_tracking"
    plant = "emps"
