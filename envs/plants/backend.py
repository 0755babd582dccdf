"""The physics of a plant's simulations, one control period at a time: one MjData (SingleBackend) or a
mujoco.batch.Batch (BatchBackend) behind the same calls (write the episode's parameters, reset the state,
set the actuation delay and the friction levels, hold a command over a period, read the state). The env's
core (envs/core.py) steps through them, and so does PlantSim (sim.py) on its one MjData."""

from __future__ import annotations

from operator import itemgetter

import mujoco
import numpy as np
from mujoco.batch import Batch, SimulationError

from .params import EpisodeParams, ModelIndex, apply, apply_batch, history_delay
from .spec import PlantSpec

# MuJoCo warnings after which it resets the simulation or ignores the command: each ends the episode
# as diverged (MuJoCo would otherwise carry on silently from rest).
DIVERGENCE_WARNINGS = np.array(
    [
        int(getattr(mujoco.mjtWarning, w))
        for w in ("mjWARN_BADQACC", "mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADCTRL")
    ]
)
_DIVERGENCE_COUNTS = itemgetter(*DIVERGENCE_WARNINGS.tolist())  # their counts from a list of all counts


def period_delay(jitter: np.random.Generator, delay_steps: int, jitter_steps: int, timestep: float) -> float:
    """The actuation delay over one control period (s): the episode's delay plus 0..jitter_steps whole
    physics steps, one uniform draw of the episode's jitter stream per period. The one jitter rule of the
    env's vector and single paths and of PlantSim."""
    return history_delay(delay_steps + int(jitter.integers(0, jitter_steps + 1)), timestep)


def mujoco_diverged(warning_counts: np.ndarray) -> bool:
    """Whether an MjData's warning counts (`data.warning.number`) show a divergence warning."""
    return any(_DIVERGENCE_COUNTS(warning_counts.tolist()))


def frictionloss_torque(model: mujoco.MjModel, data: mujoco.MjData, dofs: np.ndarray) -> np.ndarray:
    """The frictionloss constraint's torque on each dof of `dofs` (N·m, opposing motion) at the data's
    state: mj_forward on `data` (a scratch copy), then the FRICTION_DOF rows of efc_force."""
    mujoco.mj_forward(model, data)
    out = np.zeros(len(dofs))
    rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)
    for r in rows:
        out[np.flatnonzero(dofs == data.efc_id[r])] += data.efc_force[r]
    return out


class SingleBackend:
    """One MjData (a new one, or `data`, e.g. restored from a snapshot). Its arrays are read and written
    through views made once (the MjData is never replaced, and each attribute access would build a new
    view)."""

    def __init__(
        self, model: mujoco.MjModel, spec: PlantSpec, idx: ModelIndex, data: mujoco.MjData | None = None
    ):
        self.model, self.spec, self.idx, self.n = model, spec, idx, 1
        self.data = mujoco.MjData(model) if data is None else data
        d = self.data
        self.qpos, self.qvel, self.ctrl, self.act = d.qpos, d.qvel, d.ctrl, d.act
        self.force = d.actuator_force
        self.warning_counts = d.warning.number  # live counts of each mjtWarning
        self._good, self._bad = np.array([False]), np.array([True])

    def warned(self) -> bool:
        """Whether MuJoCo reported a divergence (and reset the simulation) since the last reset."""
        return mujoco_diverged(self.warning_counts)

    def apply(self, ids: np.ndarray, params: list[EpisodeParams]) -> None:
        apply(self.model, self.data, self.spec, self.idx, params[0])

    def reset_state(self, ids: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.qpos[:], self.qvel[:] = qpos[0], qvel[0]
        mujoco.mj_forward(self.model, self.data)

    def set_delay(self, ids: np.ndarray, delay: np.ndarray) -> None:
        self.model.actuator_delay[self.idx.drive] = delay[0]

    def set_levels(self, ids: np.ndarray, levels: np.ndarray) -> None:
        """Friction levels (n, n_elements, [fc, fs, bias]) of the LuGre elements, N·m (drift)."""
        bp, f = self.model.actuator_biasprm, [a for a, _, _ in self.idx.elements]
        bp[f, 3], bp[f, 4], bp[f, 0] = levels[0, :, 0], levels[0, :, 1], levels[0, :, 2]

    def step(
        self, ids: np.ndarray, command: np.ndarray, disturbance: np.ndarray | None, nstep: int | None = None
    ) -> np.ndarray:
        """Advance simulations ids one control period (or nstep physics steps) with the command, and the
        load torque if any, held over it; returns their 'diverged' flags."""
        self.ctrl[self.idx.drive_ctrl] = command[0]
        if disturbance is not None:
            self.ctrl[self.idx.disturbance_ctrl] = disturbance[0]
        mujoco.mj_step(self.model, self.data, nstep or self.spec.substeps)
        return self._bad if self.warned() else self._good

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.qpos[None], self.qvel[None], self.act[None], self.force[None]

    def frictionloss(self, ids: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        """(len(ids), len(dofs)) frictionloss torques now (the Coulomb structure's friction)."""
        scratch = mujoco.MjData(self.model)
        mujoco.mj_copyData(scratch, self.model, self.data)
        return frictionloss_torque(self.model, scratch, dofs)[None]


class BatchBackend:
    """A mujoco.batch.Batch of n simulations on nthread threads."""

    def __init__(self, model: mujoco.MjModel, spec: PlantSpec, idx: ModelIndex, n: int, nthread: int):
        self.batch, self.spec, self.idx, self.n = Batch(model, n, nthread), spec, idx, n
        self.qpos, self.qvel, self.ctrl = (
            self.batch.bind("qpos"),
            self.batch.bind("qvel"),
            self.batch.bind("ctrl"),
        )
        self.act = self.batch.bind("act")
        self.force = self.batch.bind("actuator_force")
        self.delay = self.batch.expand("actuator_delay")
        self.biasprm: np.ndarray | None = None  # expanded when friction drifts
        self.failed = np.zeros(n, dtype=bool)

    def apply(self, ids: np.ndarray, params: list[EpisodeParams]) -> None:
        apply_batch(self.batch, self.spec, self.idx, params, ids)

    def reset_state(self, ids: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> None:
        self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        self.qpos[ids], self.qvel[ids] = qpos, qvel
        self.batch.forward(ids)
        self.failed[ids] = False

    def set_delay(self, ids: np.ndarray, delay: np.ndarray) -> None:
        self.delay[ids, self.idx.drive] = delay

    def set_levels(self, ids: np.ndarray, levels: np.ndarray) -> None:
        if self.biasprm is None:
            self.biasprm = self.batch.expand("actuator_biasprm")
        rows, f = ids[:, None], np.array([a for a, _, _ in self.idx.elements])[None, :]
        bp = self.biasprm
        bp[rows, f, 3], bp[rows, f, 4], bp[rows, f, 0] = levels[:, :, 0], levels[:, :, 1], levels[:, :, 2]

    def step(self, ids: np.ndarray, command: np.ndarray, disturbance: np.ndarray | None) -> np.ndarray:
        self.ctrl[ids, self.idx.drive_ctrl] = command
        if disturbance is not None:
            self.ctrl[ids, self.idx.disturbance_ctrl] = disturbance
        try:
            self.batch.step(ids, nstep=self.spec.substeps)
        except SimulationError as e:  # those simulations kept their state; the others ran
            self.failed[e.ids] = True
        return (self.batch.warning[ids][:, DIVERGENCE_WARNINGS, 1] > 0).any(axis=1) | self.failed[ids]

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.qpos, self.qvel, self.act, self.force

    def frictionloss(self, ids: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        return np.array(
            [frictionloss_torque(self.batch.get_model(i), self.batch.get_data(i), dofs) for i in ids]
        )
