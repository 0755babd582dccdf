"""Learned controllers behind the same interface as the classical ones, so the leaderboard compares like
with like: a stable-baselines3 policy acting on the env's observation, optionally as a residual over a
classical base controller and with frozen observation-normalisation statistics.

The model's input is the env's observation (with the history / privileged blocks the model was trained
with, which the controller asks the env for) followed, in residual mode, by the base controller's action.
`policy_observation` and `residual_action` are the one implementation of that input and of the combined
action, used by the training wrapper (agents/training/) and by SB3Policy alike.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.scenario import Scenario

from .base import Controller, EpisodeContext


@dataclasses.dataclass(frozen=True)
class PolicyInputs:
    """What a learned controller observes beyond the scenario's own observation.

    history: past (readings, action) samples the env appends (a delay needs a memory).
    privileged: the env appends ground truth (true output, friction, bristle force); only the critic reads
        it (asymmetric actor-critic, agents/training/), the actor's features drop it.
    base_action: the residual's base controller action is appended (residual mode).
    """

    history: int = 0
    privileged: bool = False
    base_action: bool = False

    def observation_overrides(self) -> dict[str, Any]:
        """The scenario `observation` settings the env must use for this model."""
        return {"history": self.history, "privileged": self.privileged}

    def size(self, scenario: Scenario) -> int:
        """Length of the model's input on this scenario."""
        sc = dataclasses.replace(scenario, history=self.history, privileged=self.privileged)
        return sc.layout.size + int(self.base_action)

    def actor_indices(self, scenario: Scenario) -> list[int]:
        """Indices of the model input the actor may read: all but the privileged block."""
        sc = dataclasses.replace(scenario, history=self.history, privileged=self.privileged)
        hidden = range(sc.layout.size)[sc.layout.slice("privileged")]
        return [i for i in range(self.size(scenario)) if i not in hidden]


def policy_observation(obs: np.ndarray, base_action: np.ndarray | None) -> np.ndarray:
    """The model's input: the env's observation, then the base action in residual mode (float32)."""
    if base_action is None:
        return obs
    return np.concatenate([obs, np.asarray(base_action, dtype=np.float32).reshape(1)])


def residual_action(base_action: np.ndarray, residual: np.ndarray, alpha: float) -> np.ndarray:
    """u = clip(u_base + α·u_res, -1, 1): the residual has authority α of the full command range."""
    u = np.asarray(base_action, dtype=np.float64).reshape(1) + alpha * np.asarray(residual).reshape(1)
    return np.clip(u, -1.0, 1.0).astype(np.float32)


def algorithm_class(algo: str) -> Any:
    """The stable-baselines3 or sb3-contrib class called algo (e.g. "SAC", "TQC", "RecurrentPPO"), or
    sbx's (JAX) for "sbx.<name>" (e.g. "sbx.SAC"; the optional sbx extra)."""
    if algo.startswith("sbx."):
        try:
            module = importlib.import_module("sbx")
        except ImportError:
            raise ValueError(f"algorithm {algo!r} needs sbx: pip install -e '.[sbx]'") from None
        if (cls_ := getattr(module, algo[4:], None)) is not None:
            return cls_
        raise ValueError(f"algorithm {algo!r} is not an sbx class")
    missing = []
    for package in ("stable_baselines3", "sb3_contrib"):
        try:
            module = importlib.import_module(package)
        except ImportError:
            missing.append(package)
            continue
        if (cls_ := getattr(module, algo, None)) is not None:
            return cls_
    hint = f" ({' and '.join(missing)} not installed: pip install -e '.[rl]')" if missing else ""
    raise ValueError(f"algorithm {algo!r} is not a stable-baselines3 or sb3-contrib class{hint}")


def is_jax(model: Any) -> bool:
    """Whether a model is sbx's (JAX / flax networks), not a torch one."""
    return type(model).__module__.split(".")[0] == "sbx"


def sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _chain(module: Any) -> list[Callable[[Any], Any]]:
    """The forward functions of a module's leaves in call order (Sequentials flattened), called without
    torch's per-module dispatch; a leaf's forward is the computation its call makes (no hooks are set)."""
    children = list(module.children())
    if type(module).__name__ == "Sequential":
        return [f for child in children for f in _chain(child)]
    return [module.forward]


def deterministic_actor(policy: Any) -> Callable[[Any], Any]:
    """A function of the observation tensor giving policy._predict(obs, deterministic=True), operation for
    operation: for a SAC, TQC or CrossQ actor (squashed Gaussian, no gSDE) tanh(mu(latent_pi(features)))
    (the distribution's mode), for a TD3 actor mu(features), each as the plain chain of its layers; any
    other policy (PPO, gSDE) keeps SB3's own _predict."""
    import torch  # the rl extra, as in _predict
    from stable_baselines3.common.distributions import SquashedDiagGaussianDistribution

    actor = getattr(policy, "actor", None)
    if actor is None or not hasattr(actor, "mu") or getattr(actor, "use_sde", False):
        return lambda obs: policy._predict(obs, deterministic=True)
    if hasattr(actor, "latent_pi"):
        if not isinstance(actor.action_dist, SquashedDiagGaussianDistribution):
            return lambda obs: policy._predict(obs, deterministic=True)
        chain = [*_chain(actor.latent_pi), *_chain(actor.mu), torch.tanh]
    else:
        chain = _chain(actor.mu)

    def act(obs: Any) -> Any:
        h = actor.extract_features(obs, actor.features_extractor)
        for f in chain:
            h = f(h)
        return h

    return act


class LearnedNeeds:
    """What a learned controller brings into its env: its base's hardware and its observation blocks. Shared
    by SB3Policy and the training env (agents/training/), so both build the same env."""

    inputs: PolicyInputs
    base: Controller | None

    def plant_overrides(self, scenario: Scenario) -> dict:
        return self.base.plant_overrides(scenario) if self.base is not None else {}

    def observation_overrides(self) -> dict:
        return self.inputs.observation_overrides()


def policy_why_not(
    observes: tuple[int, ...],
    inputs: PolicyInputs,
    plants: tuple[str, ...],
    base: Controller | None,
    scenario: Scenario,
) -> str | None:
    """Why a policy that observes `observes` (its input shape) cannot run on the scenario, or None: its
    base controller's reason, another input shape, another plant. Decided from the saved model or from
    its manifest alone (registry.why_not), the same way."""
    if base is not None and (reason := base.why_not(scenario)) is not None:
        return f"base controller {base.name}: {reason}"
    got = (inputs.size(scenario),)
    if got != tuple(observes):
        return f"the model observes shape {tuple(observes)}, the scenario gives {got}"
    if plants and scenario.spec.name not in plants:
        return f"trained for plants {list(plants)}, the scenario's plant is {scenario.spec.name}"
    return None


class SB3Policy(LearnedNeeds, Controller):
    """A trained SB3 model (any algorithm with predict), deterministic.

    With `base` it is a residual: u = clip(u_base + α·π(obs, u_base), -1, 1), and it brings the base's
    hardware (plant_overrides). `normalizer` is a frozen VecNormalize (its observation statistics are
    applied, never updated). A recurrent policy (RecurrentPPO) keeps its state over the episode.
    """

    name: ClassVar[str] = "SB3"

    def __init__(
        self,
        model: Any,
        plants: tuple[str, ...] = (),
        name: str = "SB3",
        *,
        inputs: PolicyInputs = PolicyInputs(),
        base: Controller | None = None,
        alpha: float = 1.0,
        normalizer: Any = None,
    ):
        self.model, self.plants, self.name = model, tuple(plants), name  # instance values shadow the class
        self.inputs, self.base, self.alpha, self.normalizer = inputs, base, float(alpha), normalizer
        if inputs.base_action != (base is not None):
            raise ValueError(
                "a residual policy (base controller given) observes the base action, and only it"
            )
        if normalizer is not None:
            normalizer.training = False  # frozen statistics at evaluation
        self.recurrent = hasattr(model.policy, "lstm_actor")
        self.jax = is_jax(model)
        self.hashes: dict[str, str] = {}
        self._actor: Callable[[Any], Any] | None = None  # deterministic_actor(policy), built on first use
        self._device: Any = None  # the policy's torch device, read with _actor

    @classmethod
    def load(
        cls,
        path: str | Path,
        algo: str,
        plants: tuple[str, ...] = (),
        name: str | None = None,
        normalizer: str | Path | None = None,
        **kw: Any,
    ) -> SB3Policy:
        """Load a saved model, e.g. SB3Policy.load("sac_kang.zip", "SAC", ("kang_robot",)); algo is a
        stable-baselines3 or sb3-contrib class name, normalizer a saved VecNormalize (pickle). The files'
        SHA-256 are kept as provenance."""
        model = algorithm_class(algo).load(str(path), device="cpu")
        norm = None
        if normalizer is not None:
            with open(normalizer, "rb") as f:
                norm = pickle.load(f)
        policy = cls(model, plants, name or Path(path).stem, normalizer=norm, **kw)
        policy.hashes = {"model_sha256": sha256(path)}
        if normalizer is not None:
            policy.hashes["normalizer_sha256"] = sha256(normalizer)
        return policy

    def why_not(self, scenario: Scenario) -> str | None:
        observes = tuple(self.model.observation_space.shape)
        return policy_why_not(observes, self.inputs, self.plants, self.base, scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        self.ctx = ctx
        if self.base is not None:
            self.base.reset(ctx)
        self.state, self.start = None, np.ones(1, dtype=bool)

    def act(self, obs: np.ndarray) -> np.ndarray:
        ub = self.base.act(obs) if self.base is not None else None
        x = policy_observation(obs, ub)
        if self.normalizer is not None:
            x = self.normalizer.normalize_obs(x).astype(np.float32)
        if self.recurrent:
            a, self.state = self.model.predict(
                x, state=self.state, episode_start=self.start, deterministic=True
            )
            self.start = np.zeros(1, dtype=bool)
        elif self.jax:
            a = self.model.predict(x, deterministic=True)[0]
        else:
            a = self._predict(x)
        if ub is None:
            return np.clip(np.asarray(a, dtype=np.float32).reshape(1), -1.0, 1.0)
        return residual_action(ub, a, self.alpha)

    def _predict(self, x: np.ndarray) -> np.ndarray:
        """model.predict(x, deterministic=True) of a feed-forward policy, the same torch operations on the
        same tensors (so the same bits), without SB3's per-call overhead: its switch to eval mode (a
        recursion over every module) and, for a SAC-family actor, the action distribution it builds only
        to take its mode, tanh(mean), and its device lookup (together 3/4 of predict's time). The mode is
        switched only when training left it on."""
        import torch  # the rl extra; a model to predict with means it is installed

        policy = self.model.policy
        if policy.training:
            policy.set_training_mode(False)
        if self._actor is None:
            self._actor, self._device = deterministic_actor(policy), policy.device
        # policy.obs_to_tensor(x) of one Box observation, without its device lookup over every parameter
        shape = (-1, *policy.observation_space.shape)
        obs = torch.as_tensor(np.asarray(x).reshape(shape), device=self._device)
        with torch.no_grad():
            a = self._actor(obs).cpu().numpy().reshape(policy.action_space.shape)
        if policy.squash_output:
            return policy.unscale_action(a)
        return np.clip(a, policy.action_space.low, policy.action_space.high)

    def params(self) -> dict[str, Any]:
        out: dict[str, Any] = {"algorithm": type(self.model).__name__, **self.hashes}
        if self.base is not None:
            out |= {"base": self.base.name, "alpha": self.alpha}
        return out
