"""The episode logic shared by the single env and the vector env: parameter and initial-state draws,
sampled-data stepping with jitter, observations, reward, logging and episode metrics.

All arrays carry a leading axis of n simulations; the single env is n = 1 on an MjData, the vector env
n = N on a mujoco.batch.Batch. Both run the same arithmetic, so the same seeds give bit-identical episodes.
"""

from __future__ import annotations

import math
from dataclasses import asdict

import mujoco
import numpy as np

from .friction import element_levels, elements, joint_friction_torque, joint_levels
from .metrics import episode_metrics, from_first_period, reversal_half_window
from .plants.backend import BatchBackend, SingleBackend, period_delay
from .plants.mjcf import to_mjcf
from .plants.params import EpisodeParams, ModelIndex
from .sampler import DRIFT, INITIAL_STATE, JITTER, SENSOR_NOISE, stream
from .scenario import Scenario
from .sensors import SensorArrays
from .step import (
    ARRAY,
    FLOAT,
    diverged_reward,
    encoder_reading,
    reward_terms,
    reward_total,
    sanitize_observation,
    step_info,
    tacho_reading,
)

# What an episode in progress holds beyond its MjModel (episode parameters are written into it) and MjData.
EPISODE_STATE = (
    "k",
    "prev_action",
    "hist",
    "log_y",
    "log_v",
    "log_u",
    "params",
    "noise_scale",
    "sigma2",
    "delay_steps",
    "jitter_steps",
    "noise_rng",
    "jitter_rng",
    "diverged",
    "ended",
    "ref",  # an episode's own reference and load torque (type random), and the fast path's copies
    "disturbance",
    "_ref",
    "_disturbance",
    "drift",  # friction drift: λ per period and the episode's base levels, and the fast path's copies
    "levels",
    "elem_levels",
    "elem_sigma0",
    "_drift",
    "_levels",
)


class ServoCore:
    """Episodes of one scenario on n simulations (see module docstring)."""

    def __init__(self, scenario: Scenario, n: int = 1, nthread: int = 0, batch: bool = False):
        sc = self.sc = scenario
        spec = sc.spec
        self.model = mujoco.MjModel.from_xml_string(to_mjcf(spec))
        self.idx = ModelIndex.of(self.model, spec)
        self.backend = (
            BatchBackend(self.model, sc.spec, self.idx, n, nthread)
            if batch
            else SingleBackend(self.model, sc.spec, self.idx)
        )
        self.n = n
        self._all = np.arange(n)
        self.sensors = SensorArrays.of(spec, self.idx.dofs)
        self.any_noise = self.sensors.any_noise
        self.preview_offsets = np.arange(scenario.preview_steps + 1)
        self.nsensor = len(spec.sensors)
        self.track_dof = int(self.sensors.dofs[sc.tracked_sensor])
        m = self.model
        self.fric_dofs = np.array(
            [int(m.jnt_dofadr[m.actuator_trnid[a, 0]]) for a in self.idx.friction], dtype=int
        )
        self.fric_act = np.array(self.idx.friction, dtype=int)
        # a structure's LuGre elements: all of them (bristle states, drift) and those beyond each joint's
        # first, whose forces add to their joint's (friction torques)
        self.elem_act = np.array([a for a, _, _ in self.idx.elements], dtype=int)
        self._element_order = [(i, k) for _, i, k in self.idx.elements]
        self._extras = [(int(a), i) for a, i, k in self.idx.elements if k > 0]
        self.bristle_adr = np.array([m.actuator_actadr[a] for a in self.elem_act], dtype=int)
        track_joint = spec.joints[spec.joint_index(spec.sensors[sc.tracked_sensor].joint)]
        self.stick_velocity = track_joint.friction.vs if track_joint.friction is not None else 1e-3
        res = spec.sensors[sc.tracked_sensor].resolution
        self.lc_min_amp = res if spec.sensors[sc.tracked_sensor].kind == "encoder" else 1e-3 * sc.output_scale
        T = sc.episode_steps
        self.t = np.arange(T + 1) * sc.control_period
        self.t_ref = np.arange(T + 1 + sc.preview_steps) * sc.control_period  # with the preview
        # reference (n or 1 rows: one per simulation when each episode draws its own) and the load
        # torque (N·m) held over the period that starts at t_k; rows[i] is simulation i's row
        self.per_episode = sc.reference.per_episode
        self.rows = np.arange(n) if self.per_episode else np.zeros(n, dtype=int)
        if self.per_episode:
            self.ref = np.zeros((n, len(self.t_ref)))
            loaded = sc.reference.family.load_torque > 0
            self.disturbance = np.zeros((n, T)) if loaded else None
        else:
            self.ref = sc.reference(self.t_ref)[None, :]
            self.disturbance = sc.disturbance(self.t[:-1])[None, :] if sc.disturbance is not None else None
        # friction drift: λ per control period and the episode's base [fc, fs, bias] per frictional joint
        nf = len(self.fric_act)
        self.drift = np.ones((n, T)) if sc.friction_drift is not None else None
        self.levels = np.zeros((n, nf, 3))
        self.elem_levels = np.zeros((n, len(self.elem_act), 3))
        self.elem_sigma0 = np.zeros((n, len(self.elem_act)))
        self._drift: list[float] | None = None
        self._levels: list[tuple[int, float, float, float]] = []
        # per-simulation episode state
        self.k = np.zeros(n, dtype=int)
        self.prev_action = np.zeros(n)
        self.hist = np.zeros((n, sc.history, self.nsensor + 1))
        self.log_y = np.zeros((n, T + 1))
        self.log_v = np.zeros((n, T + 1))
        self.log_u = np.zeros((n, T + 1))
        self.params: list[EpisodeParams] = [EpisodeParams.nominal(spec)] * n
        self.noise_scale = np.ones(n)
        self.sigma2 = np.zeros((n, len(self.fric_act)))
        self.delay_steps = np.zeros(n, dtype=int)
        self.jitter_steps = np.zeros(n, dtype=int)
        self.noise_rng: list[np.random.Generator] = [np.random.default_rng(0)] * n
        self.jitter_rng: list[np.random.Generator] = [np.random.default_rng(0)] * n
        self.diverged = np.zeros(n, dtype=bool)
        self.ended = np.zeros(n, dtype=bool)
        # plain-Python copies for the n = 1 fast path (step_single)
        self._fast = (
            n == 1 and not batch and not sc.history and not sc.privileged and not self.sensors.any_ripple
        )
        self._ref = self.ref[0].tolist()
        self._fric = [(int(a), int(d)) for a, d in zip(self.fric_act, self.fric_dofs, strict=True)]
        self._row_views()
        self._t = self.t.tolist()
        self._disturbance = self.disturbance[0].tolist() if self.disturbance is not None else None
        self._substeps = spec.substeps
        self._window = sc.preview_steps + 1  # samples of the reference in the observation
        self._sens = [
            (int(d), bool(e), float(r), float(g))
            for d, e, r, g in zip(
                self.sensors.dofs,
                self.sensors.encoder,
                self.sensors.resolution,
                self.sensors.gain,
                strict=True,
            )
        ]
        self.layout = sc.layout
        self.obs_dim = self.layout.size
        self.diverged_reward = diverged_reward(sc.reward_weights)

    def _row_views(self) -> None:
        self._log_y0, self._log_v0, self._log_u0 = self.log_y[0], self.log_v[0], self.log_u[0]

    # ------------------------------------------------------------------ snapshots (copy and pickle)
    def snapshot(self) -> dict:
        """The episode in progress of a single backend: its MjModel and MjData (MuJoCo pickles both, the
        actuator delay's history included) and the EPISODE_STATE arrays and random streams. The caller
        copies it (pickle or deepcopy); restore() then continues the episode bit for bit."""
        if not isinstance(self.backend, SingleBackend):
            raise TypeError("only a single-simulation core (ServoEnv) can be copied")
        episode = {k: getattr(self, k) for k in EPISODE_STATE}
        return {"model": self.model, "data": self.backend.data, **episode}

    def restore(self, snap: dict) -> None:
        """Continue the episode of a snapshot taken from a core of the same scenario (and own it)."""
        self.model = snap["model"]
        self.backend = SingleBackend(self.model, self.sc.spec, self.idx, snap["data"])
        for k in EPISODE_STATE:
            setattr(self, k, snap[k])
        self._row_views()

    # ------------------------------------------------------------------ reset
    def draw(
        self, seed: int, pinned: dict | None = None
    ) -> tuple[EpisodeParams, np.ndarray, np.ndarray, list[np.random.Generator]]:
        """Everything random about an episode, from its seed alone, each quantity from its own named
        stream (envs/sampler.py): parameters (then `pinned` parameter values; on a scenario with
        nonlinear_friction false, their friction-free twin), initial state, and the noise and jitter
        streams."""
        sc = self.sc
        if sc.randomize:
            params = EpisodeParams.draw(sc.spec, seed, pinned)
        else:
            params = EpisodeParams.from_values(sc.spec, pinned or {})
        if not sc.nonlinear_friction:  # the friction-free twin of the same draw
            params = params.friction_free()
        init = stream(seed, INITIAL_STATE)
        qpos = sc.spec.full_state(init.uniform(sc.qpos_range[:, 0], sc.qpos_range[:, 1]))
        qvel = sc.spec.full_state(init.uniform(sc.qvel_range[:, 0], sc.qvel_range[:, 1]))
        if sc.random_sign:  # drawn after the ranges: scenarios without it keep their draws
            sign = 1.0 if init.random() < 0.5 else -1.0
            qpos, qvel = sign * qpos, sign * qvel
        return params, qpos, qvel, [stream(seed, SENSOR_NOISE), stream(seed, JITTER)]

    def reset(self, ids: np.ndarray, seeds: list[int], pinned: dict | None = None) -> np.ndarray:
        """Start new episodes in simulations ids with the given seeds (and pinned parameter values);
        returns their observations. Everything is drawn and checked before any state changes."""
        draws = [self.draw(s, pinned) for s in seeds]
        params = [d[0] for d in draws]
        self.backend.apply(ids, params)
        self.backend.reset_state(ids, np.array([d[1] for d in draws]), np.array([d[2] for d in draws]))
        spec = self.sc.spec
        for i, (p, _, _, (noise, jitter)) in zip(ids, draws, strict=True):
            self.params[i], self.noise_rng[i], self.jitter_rng[i] = p, noise, jitter
            self.noise_scale[i] = p.noise_scale
            model = spec.friction_model
            self.sigma2[i] = [f.sigma2 for f in p.friction]  # coulomb: in the joint's damping
            self.delay_steps[i], self.jitter_steps[i] = p.delay_steps(spec), p.jitter_steps(spec)
            self.levels[i] = [joint_levels(model, f) for f in p.friction] or np.zeros((0, 3))
            els = [elements(model, f) for f in p.friction]
            order = self._element_order
            per_joint = [element_levels(e, f.bias) for e, f in zip(els, p.friction, strict=True)]
            self.elem_levels[i] = [per_joint[j][k] for j, k in order] or np.zeros((0, 3))
            self.elem_sigma0[i] = [els[j][k].sigma0 for j, k in order]
        if self.drift is not None:  # each episode's own drift, from its seed
            period_starts = self.t[:-1]
            for i, seed in zip(ids, seeds, strict=True):
                rng = stream(seed, DRIFT)
                self.drift[i] = self.sc.friction_drift.draw(rng, period_starts, float(self.t[-1]))
            if self._fast:
                self._drift = self.drift[0].tolist()
                self._levels = [
                    (int(a), float(fc), float(fs), float(b))
                    for a, (fc, fs, b) in zip(self.elem_act, self.elem_levels[0], strict=True)
                ]
        if self.per_episode:  # each episode's own reference (and load torque), from its seed
            for i, seed in zip(ids, seeds, strict=True):
                r, load = self.sc.reference.episode(seed, self.t_ref)
                self.ref[i] = r
                if self.disturbance is not None:
                    self.disturbance[i] = load[: self.disturbance.shape[1]]
            if self._fast:
                self._ref = self.ref[0].tolist()
                self._disturbance = self.disturbance[0].tolist() if self.disturbance is not None else None
        self.k[ids] = 0
        self.prev_action[ids] = 0.0
        self.hist[ids] = 0.0
        self.diverged[ids] = False
        self.ended[ids] = False
        self.log_u[ids] = 0.0
        obs, _ = self._observe(ids)
        return obs

    # ------------------------------------------------------------------ step
    def step(
        self, action: np.ndarray, ids: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """One control period for simulations ids (default all); the others do not move. action: one
        row per simulation in ids, in [-1, 1] (clipped). Returns arrays over ids."""
        ids = self._all if ids is None else np.asarray(ids)
        if self.ended[ids].any():
            raise RuntimeError("the episode has ended (truncated or diverged): call reset() first")
        action = check_action(action, len(ids))
        a = np.minimum(np.maximum(action, -1.0), 1.0)
        command = a * self.sc.action_scale
        jittered = ids[self.jitter_steps[ids] > 0]
        if len(jittered):
            h, rng, d, j = self.sc.spec.timestep, self.jitter_rng, self.delay_steps, self.jitter_steps
            delays = np.array([period_delay(rng[i], d[i], j[i], h) for i in jittered])
            self.backend.set_delay(jittered, delays)
        rows = self.rows[ids]
        dist = self.disturbance[rows, self.k[ids]] if self.disturbance is not None else None
        if self.drift is not None:  # the levels over this period
            self.backend.set_levels(ids, self.elem_levels[ids] * self.drift[ids, self.k[ids]][:, None, None])
        self.diverged[ids] |= self.backend.step(ids, command, dist)
        self.k[ids] += 1
        k = self.k[ids]
        a_prev = self.prev_action[ids].copy()
        self.prev_action[ids] = a  # the observation shows the command now being held
        obs, truth = self._observe(ids)
        ref = self.ref[rows, k]
        e = (truth - ref) / self.sc.output_scale
        terms = reward_terms(e, a, a_prev, self.sc.reward_weights, ARRAY)
        reward = reward_total(terms)
        diverged = self.diverged[ids]
        if diverged.any():  # otherwise the reward is finite: truth was sanitised and a is clipped
            reward = np.where(diverged, self.diverged_reward, reward)
        self.log_u[ids, k] = command
        terminated = diverged.copy()
        truncated = (k >= self.sc.episode_steps) & ~terminated
        self.ended[ids] = terminated | truncated
        info = step_info(terms, command, ref, truth, self.t[k], diverged.copy())
        return obs, reward, terminated, truncated, info

    def step_single(self, action: float) -> tuple[np.ndarray, float, bool, bool, dict]:
        """step() for one simulation on an MjData, in plain Python floats: the same IEEE operations in the
        same order as the vectorised path (tests check single == vector env bit for bit), without numpy's
        per-call overhead. Used when there is no history, privileged observation or tachometer ripple."""
        if not self._fast:
            obs, reward, term, trunc, info = self.step(np.array([action], dtype=float))
            return obs[0], float(reward[0]), bool(term[0]), bool(trunc[0]), {k: v[0] for k, v in info.items()}
        if self.ended[0]:
            raise RuntimeError("the episode has ended (truncated or diverged): call reset() first")
        x = float(action)
        if not math.isfinite(x):
            raise ActionError(f"actions must be finite, got {action}")
        sc = self.sc
        a = x if -1.0 <= x <= 1.0 else (1.0 if x > 0.0 else -1.0)  # the clip, as the vector path's
        command = a * sc.action_scale
        if self.jitter_steps[0]:
            d = period_delay(self.jitter_rng[0], self.delay_steps[0], self.jitter_steps[0], sc.spec.timestep)
            self.backend.set_delay(self._all, np.array([d]))
        b = self.backend
        b.ctrl[self.idx.drive_ctrl] = command
        if self._disturbance is not None:
            b.ctrl[self.idx.disturbance_ctrl] = self._disturbance[int(self.k[0])]
        if self._drift is not None:  # the levels over this period, as set_levels
            lam, bp = self._drift[int(self.k[0])], b.model.actuator_biasprm
            for act, fc, fs, bias in self._levels:
                bp[act, 3], bp[act, 4], bp[act, 0] = fc * lam, fs * lam, bias * lam
        mujoco.mj_step(b.model, b.data, self._substeps)
        diverged = b.warned()  # it was False: a diverged episode has ended, and stepping it raised above
        self.diverged[0] = diverged
        k = int(self.k[0]) + 1
        self.k[0] = k
        a_prev = float(self.prev_action[0])
        self.prev_action[0] = a
        # the observation, as _observe
        qpos, qvel = b.qpos.tolist(), b.qvel.tolist()  # Python floats: cheaper arithmetic
        noise = (
            self.sensors.noise([self.noise_rng[0]], self.noise_scale[:1])[0].tolist()
            if self.any_noise
            else None
        )
        inv = 1.0 / sc.output_scale
        sensors = []
        for i, (d, enc, res, gain) in enumerate(self._sens):
            if enc:
                m = encoder_reading(qpos[d] + noise[i] if noise is not None else qpos[d], res, FLOAT)
            else:
                m = tacho_reading(qvel[d], gain, noise[i] if noise is not None else 0.0)
            sensors.append(m * inv)
        d, enc, _, gain = self._sens[sc.tracked_sensor]
        truth = float(qpos[d]) if enc else gain * qvel[d]
        vel = float(qvel[self.track_dof])
        if not math.isfinite(truth):
            truth, vel = float(np.nan_to_num(truth)), float(np.nan_to_num(vel))
        self._log_y0[k] = truth
        self._log_v0[k] = vel
        ref = self._ref
        window = [r * inv for r in ref[k : k + self._window]]
        parts = {"sensors": sensors, "reference": window[:1], "preview": window[1:], "previous_action": [a]}
        obs = sanitize_observation(self.layout.pack(parts))
        e = (truth - ref[k]) / sc.output_scale
        terms = reward_terms(e, a, a_prev, sc.reward_weights, FLOAT)
        reward = self.diverged_reward if diverged else reward_total(terms)
        self._log_u0[k] = command
        truncated = k >= sc.episode_steps and not diverged
        self.ended[0] = diverged or truncated
        info = step_info(terms, command, ref[k], truth, self._t[k], diverged)
        return obs, reward, diverged, truncated, info

    def _observe(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Observations (float32) and true tracked outputs of simulations ids; logs them."""
        sel = slice(None) if len(ids) == self.n else ids  # views, not copies, for the common case
        qpos, qvel, act, force = self.backend.state()
        qpos, qvel = qpos[sel], qvel[sel]
        noise = (
            self.sensors.noise([self.noise_rng[i] for i in ids], self.noise_scale[ids])
            if self.any_noise
            else 0.0
        )
        meas = self.sensors.measure(qpos, qvel, noise)
        truth = self.sensors.truth(qpos, qvel, self.sc.tracked_sensor)
        vel = qvel[:, self.track_dof]
        if not np.isfinite(truth).all():  # a diverged simulation: log zeros
            truth, vel = np.nan_to_num(truth), np.nan_to_num(vel)
        k = self.k[ids]
        self.log_y[ids, k] = truth
        self.log_v[ids, k] = vel
        sc = self.sc
        inv = 1.0 / sc.output_scale
        ns, n = self.nsensor, len(ids)
        window = self.ref[self.rows[ids][:, None], k[:, None] + self.preview_offsets] * inv
        parts = {
            "sensors": meas * inv,
            "reference": window[:, :1],
            "preview": window[:, 1:],
            "previous_action": self.prev_action[ids][:, None],
        }
        if sc.history:
            h = self.hist[ids]
            h[:, 1:] = h[:, :-1].copy()
            h[:, 0, :ns], h[:, 0, ns] = meas * inv, self.prev_action[ids]
            self.hist[ids] = h
            parts["history"] = h.reshape(n, -1)
        if sc.privileged:
            unit = sc.action_scale * sc.spec.actuator_gain  # torque of a unit action
            act, force = act[sel], force[sel]
            spring = self.per_joint(self.elem_sigma0[ids] * act[:, self.bristle_adr], primary=False)
            parts["privileged"] = np.concatenate(
                [
                    (truth * inv)[:, None],
                    (
                        self._with_frictionloss(self.per_joint(force), ids)
                        - self.sigma2[ids] * qvel[:, self.fric_dofs]
                    )
                    / unit,
                    spring / unit,
                ],
                axis=1,
            )
        return sanitize_observation(self.layout.pack(parts)), truth

    # ------------------------------------------------------------------ ground truth and metrics
    def ground_truth(self, i: int | slice) -> dict:
        """True states of simulation i (or one row per simulation of a slice): joint angles (rad) and
        velocities (rad/s), bristle deflections (rad, one per LuGre element of the friction structure),
        friction torques (N·m), and their nonlinear part (N·m: -Σ(σ0·z + σ1·ż) + b over the joint's
        elements, or the frictionloss constraint's torque + b for coulomb; friction_torque without the
        viscous -σ2·v; what the friction-free twin removes), one per frictional joint; and the friction
        levels over the period that starts now (coulomb_level, static_level, N·m per frictional joint, and
        friction_scale, the drift's λ: 1 without drift)."""
        lam, levels = self.current_levels(i)
        now = {"coulomb_level": levels[..., 0], "static_level": levels[..., 1], "friction_scale": lam}
        if self._fast:  # the same values from the MjData, with plain indices
            b = self.backend
            qv, s2 = b.qvel, self.sigma2[0]
            f = self._with_frictionloss(self.per_joint(b.force), 0)
            return {
                "qpos": b.qpos.copy(),
                "qvel": qv.copy(),
                "bristle": b.act[self.bristle_adr],
                "friction_torque": np.array(
                    [joint_friction_torque(f[j], s2[j], qv[dof]) for j, (_, dof) in enumerate(self._fric)]
                ),
                "nonlinear_friction_torque": f,
                **now,
            }
        qpos, qvel, act, force = self.backend.state()
        qv = qvel[i]
        f = self._with_frictionloss(self.per_joint(force[i]), np.arange(self.n)[i])
        return {
            "qpos": qpos[i].copy(),
            "qvel": qv.copy(),
            "bristle": act[i, self.bristle_adr],
            "friction_torque": joint_friction_torque(f, self.sigma2[i], qv[..., self.fric_dofs]),
            "nonlinear_friction_torque": f,
            **now,
        }

    def _with_frictionloss(self, f: np.ndarray, ids: np.ndarray | int) -> np.ndarray:
        """Per-joint element forces f of simulations ids plus, for the Coulomb structure, its frictionloss
        torques now (N·m); the other structures' friction is all in their elements' actuator forces."""
        if self.sc.spec.friction_model != "coulomb":
            return f
        fl = self.backend.frictionloss(np.atleast_1d(ids), self.fric_dofs)
        return f + (fl if np.ndim(ids) else fl[0])

    def per_joint(self, x: np.ndarray, primary: bool = True) -> np.ndarray:
        """Per frictional joint, the sum over its LuGre elements: of actuator forces x (..., nu) (primary:
        the first element's force carries the bias) or of per-element values x (..., n_elements)."""
        if primary:
            return self.idx.joint_forces(x)
        nf = len(self.fric_act)
        if x.shape[-1] == 0:
            return np.zeros((*x.shape[:-1], nf))
        out = x[..., :nf]
        extras = [(nf + e, j) for e, (_, j) in enumerate(self._extras)]
        if extras:
            out = out.copy()
            for a, j in extras:
                out[..., j] += x[..., a]
        return out

    def current_levels(self, i: int | slice) -> tuple[np.ndarray, np.ndarray]:
        """(λ, [fc, fs, bias] per frictional joint, N·m) of simulation i (or a slice) over the period that
        starts now: the episode's drawn levels times the drift's λ (1 without drift)."""
        k = np.minimum(self.k[i], self.sc.episode_steps - 1)
        lam = self.drift[np.arange(self.n)[i], k] if self.drift is not None else np.ones(np.shape(k))
        return lam, self.levels[i] * np.asarray(lam)[..., None, None]

    def params_dict(self, i: int) -> dict:
        return asdict(self.params[i])

    def episode_log(self, i: int) -> dict[str, np.ndarray]:
        """Signals of simulation i's current episode up to now: t, reference, output, command, velocity."""
        k = self.k[i] + 1
        return {
            "t": self.t[:k],
            "reference": self.ref[self.rows[i], :k],
            "output": self.log_y[i, :k],
            "command": self.log_u[i, :k],
            "velocity": self.log_v[i, :k],
        }

    def metrics(self, i: int) -> dict[str, float]:
        """Episode metrics of simulation i (commands from the first period on)."""
        g = from_first_period(self.episode_log(i))
        return episode_metrics(
            g["t"],
            g["reference"],
            g["output"],
            g["command"],
            g["velocity"],
            settle_band=self.sc.settle_band,
            stick_velocity=self.stick_velocity,
            command_limit=self.sc.action_scale,
            lc_min_amp=self.lc_min_amp,
            reversal_half_window=reversal_half_window(self.sc.control_period),
        )


def new_renderer(model: mujoco.MjModel) -> mujoco.Renderer:
    """A 640 x 480 offscreen renderer of the model, or a clear error where there is no OpenGL context."""
    try:
        return mujoco.Renderer(model, 480, 640)
    except mujoco.FatalError as e:  # no OpenGL context: a machine without a display
        raise RuntimeError(
            "no OpenGL context to render in; without a display set MUJOCO_GL=egl (or osmesa) before "
            "MuJoCo is imported"
        ) from e


def render_frame(renderer: mujoco.Renderer, data: mujoco.MjData) -> np.ndarray:
    """One RGB frame of the plant from its top camera, each moving part labelled by its body's name
    (drive, load, carriage, ...)."""
    labels = mujoco.MjvOption()
    labels.label = mujoco.mjtLabel.mjLABEL_BODY
    renderer.update_scene(data, camera="top", scene_option=labels)
    return renderer.render()


class ActionError(ValueError):
    """An action that is not one finite real per env (check_action, the single env's step): its own type,
    so that an evaluation loop can tell the controller's mistake from any other error of a step."""


def check_action(action: object, n: int) -> np.ndarray:
    """(n,) float actions from one finite real scalar per env: shapes (), (1,) for n = 1, or (n,), (n, 1).
    Anything else (strings, bytes, complex, bool, empty, other shapes, NaN) is a clear error."""
    a = np.asarray(action)
    if a.dtype.kind not in "fiu":
        raise ActionError(f"actions must be real numbers, got dtype {a.dtype} ({action!r:.80})")
    if a.size != n or a.shape not in ((n,), (n, 1)) + (((),) if n == 1 else ()):
        want = "a scalar, (1,) or (1, 1)" if n == 1 else f"({n},) or ({n}, 1)"
        raise ActionError(f"expected one action per env, shape {want}; got shape {a.shape}")
    a = a.astype(float).reshape(n)
    if not np.isfinite(a).all():
        raise ActionError(f"actions must be finite, got {a}")
    return a


def check_options(options: object) -> dict:
    """The pinned parameters of reset(options={"params": {...}}) ({} if none); other keys are errors."""
    if options is None:
        return {}
    if not isinstance(options, dict) or set(options) - {"params"}:
        raise ValueError(f"options: expected None or {{'params': {{...}}}}, got {options!r}")
    pinned = options.get("params") or {}
    if not isinstance(pinned, dict):
        raise ValueError(f"options['params']: expected a mapping of randomization keys, got {pinned!r}")
    return dict(pinned)
