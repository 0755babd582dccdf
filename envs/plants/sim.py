"""Sampled-data simulation of one plant: ZOH command over the control period, actuation delay from
MuJoCo's actuator history buffer (resolution: one physics step), sensors read at the sampling instants."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..friction import joint_friction_torque
from ..sampler import JITTER, SENSOR_NOISE, stream
from ..sensors import SensorArrays
from . import plant_spec
from .backend import SingleBackend, mujoco_diverged, period_delay
from .mjcf import to_mjcf
from .params import EpisodeParams, ModelIndex
from .spec import PlantSpec

ONE = np.zeros(1, dtype=int)  # the backend's simulation ids: PlantSim is its n = 1 case


@dataclass
class StepResult:
    """What a digital controller sees after one control period, plus ground truth."""

    measurement: np.ndarray  # sensor readings in spec.sensors order (rad or V)
    qpos: np.ndarray  # true joint angles (rad)
    qvel: np.ndarray  # true joint velocities (rad/s)
    diverged: bool


class PlantSim:
    """One compiled plant. Parameters change per episode via reset(params) without recompiling.

    Call step(u) once per control period: u (command units: V or N·m) is written to the drive's
    ctrl and held for spec.substeps physics steps; with delay τ the drive acts on it from t_k + τ. The
    physics runs through the env's single-simulation backend (backend.py), the same calls as the env's.
    """

    def __init__(self, spec: PlantSpec | str, overrides: dict | None = None, friction_model: str = "lugre"):
        self.spec = plant_spec(spec, overrides, friction_model) if isinstance(spec, str) else spec
        self.model = mujoco.MjModel.from_xml_string(to_mjcf(self.spec))
        self.idx = ModelIndex.of(self.model, self.spec)
        self.backend = SingleBackend(self.model, self.spec, self.idx)
        self.data = self.backend.data
        self.params = EpisodeParams.nominal(self.spec)
        self.sensors = SensorArrays.of(self.spec, self.idx.dofs)
        self._seed(0)
        self.backend.apply(ONE, [self.params])

    @property
    def dofs(self) -> tuple[int, ...]:
        return self.idx.dofs

    def reset(
        self,
        params: EpisodeParams | None = None,
        qpos: np.ndarray | None = None,
        qvel: np.ndarray | None = None,
        seed: int | None = None,
    ) -> StepResult:
        """Reset state (bristles, history buffer, time) and optionally parameters and initial state.

        For belt-coupled plants pass the drive angle/velocity only (qpos of length 1): the others follow
        the belt ratios.
        """
        if params is not None:
            self.backend.apply(ONE, [params])
            self.params = params
        if seed is not None:
            self._seed(seed)
        self.backend.reset_state(ONE, self.spec.full_state(qpos)[None], self.spec.full_state(qvel)[None])
        return self.read()

    def _seed(self, seed: int) -> None:
        """Sensor noise and delay jitter streams of the episode seed, named as in the env (sampler.py)."""
        self.rng, self.jitter_rng = stream(seed, SENSOR_NOISE), stream(seed, JITTER)

    def step(self, u: float, nstep: int | None = None) -> StepResult:
        """Hold command u for one control period (or nstep physics steps); read the sensors at the end."""
        if not np.isfinite(u):
            raise ValueError(f"command must be finite, got {u!r}")
        jmax = self.params.jitter_steps(self.spec)
        if jmax:
            d = period_delay(self.jitter_rng, self.params.delay_steps(self.spec), jmax, self.spec.timestep)
            self.backend.set_delay(ONE, np.array([d]))
        self.backend.step(ONE, np.array([u], dtype=float), None, nstep)
        return self.read()

    def read(self) -> StepResult:
        """The sensors sampled now (one draw of the noise stream, as at the end of a step), the true
        joint states, and whether the state is not finite or MuJoCo reported a divergence."""
        d = self.data
        diverged = bool(
            not np.all(np.isfinite(d.qpos))
            or not np.all(np.isfinite(d.qvel))
            or mujoco_diverged(d.warning.number)
        )
        noise = self.sensors.noise([self.rng], np.array([self.params.noise_scale]))
        meas = self.sensors.measure(d.qpos[None], d.qvel[None], noise)[0]
        return StepResult(meas, d.qpos[list(self.dofs)].copy(), d.qvel[list(self.dofs)].copy(), diverged)

    def friction_torque(self) -> np.ndarray:
        """Current friction torque on each frictional joint (N·m): its friction elements (the first with the
        bias) + the first's σ2 damping."""
        d, m = self.data, self.model
        f = self.idx.joint_forces(d.actuator_force)
        out = []
        for i, a in enumerate(self.idx.friction):
            dof = int(m.jnt_dofadr[m.actuator_trnid[a, 0]])
            out.append(joint_friction_torque(f[i], m.actuator_damping[a], d.qvel[dof]))
        return np.array(out)

    def bristle_state(self) -> np.ndarray:
        """Bristle deflections z (rad), one per LuGre element (idx.elements order; one per frictional joint
        for lugre and dahl, none for coulomb)."""
        m = self.model
        return np.array([self.data.act[m.actuator_actadr[a]] for a, _, _ in self.idx.elements])


def linearize(sim: PlantSim, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time (A, B) of the MuJoCo model at rest: central differences of qacc from mj_forward
    over (qpos, qvel) and the drive command. State x = (qpos, qvel)."""
    m, d = sim.model, sim.data
    nv = m.nv

    def acc(q: np.ndarray, v: np.ndarray, u: float) -> np.ndarray:
        d.qpos[:], d.qvel[:], d.ctrl[:] = q, v, 0.0
        d.ctrl[sim.idx.drive_ctrl] = u
        mujoco.mj_forward(m, d)
        return d.qacc.copy()

    q0, v0 = np.zeros(nv), np.zeros(nv)
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    for i in range(2 * nv):
        dx = np.zeros(2 * nv)
        dx[i] = eps
        A[nv:, i] = (acc(q0 + dx[:nv], v0 + dx[nv:], 0.0) - acc(q0 - dx[:nv], v0 - dx[nv:], 0.0)) / (2 * eps)
    B = np.zeros(2 * nv)
    B[nv:] = (acc(q0, v0, eps) - acc(q0, v0, -eps)) / (2 * eps)
    return A, B
