"""Learned controllers behind the same interface as the classical ones, so the leaderboard compares like
with like: a stable-baselines3 policy acting on the env's observation, optionally as a residual over a
classical base controller and with frozen observation-normalisation statistics.

The model's input is the env's observation (with the history / privileged blocks the model was trained
with, which the controller asks the env for) followed, in residual mode, by the base controller's action.
`policy_observation` and `residual_action` are the one implementation of that input and of the combined
action, used by the training wrapper (agents/training/) and by LearnedPolicy alike. `LearnedPolicy.actions`
acts on many episodes' observations in one call (the leaderboard's and validation's batched episodes,
evaluate.run_episodes): its network is a `RowwiseActor`, whose rows never interact, so each episode gets
the action it would get alone. A saved model is that network's layers (agents/learned/folder.py), so
evaluating one needs numpy only.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from frictiongym.agents.base import Controller, EpisodeContext, Lockstep
from frictiongym.envs.scenario import REGULATION, Scenario

MAX_HISTORY = 64  # past (readings, action) samples a model may observe


@dataclasses.dataclass(frozen=True)
class PolicyInputs:
    """What a learned controller observes beyond the scenario's own observation.

    history: past (readings, action) samples the env appends (a delay needs a memory).
    privileged: the env appends ground truth (true output, friction, bristle force); only the critic reads
        it (asymmetric actor-critic, agents/training/), the actor's features drop it.
    base_action: the residual's base controller action is appended (residual mode).
    differences: two differences of inputs are appended last (difference_indices): the tracking error
        (y - r)/s and the reference's change over the preview (r(t_{k+P}) - r(t_k))/s. Both are small
        differences of large inputs that a normalised input hides: on the M220 (5 ms period, 0.5 rad
        scale) a 0.5 rad/s reference moves 0.4 % of the reference's spread per step. Appended, they get
        their own normalisation statistics.
    """

    history: int = 0
    privileged: bool = False
    base_action: bool = False
    differences: bool = False

    def observation_overrides(self) -> dict[str, Any]:
        """The scenario `observation` settings the env must use for this model."""
        return {"history": self.history, "privileged": self.privileged}

    def size(self, scenario: Scenario) -> int:
        """Length of the model's input on this scenario."""
        sc = dataclasses.replace(scenario, history=self.history, privileged=self.privileged)
        return model_input_size(sc.layout.size, self.base_action, self.differences)

    def actor_indices(self, scenario: Scenario) -> list[int]:
        """Indices of the model input the actor may read: all but the privileged block."""
        sc = dataclasses.replace(scenario, history=self.history, privileged=self.privileged)
        hidden = range(sc.layout.size)[sc.layout.slice("privileged")]
        return [i for i in range(self.size(scenario)) if i not in hidden]


DIFFERENCES = 2  # inputs PolicyInputs.differences appends: tracking error, reference change over the preview


def model_input_size(env_obs_size: int, base_action: bool, differences: bool) -> int:
    """Length of a model's input: the env's observation (its history and privileged blocks included), then
    the base controller's action (residual mode), then the DIFFERENCES (policy_observation's order)."""
    return env_obs_size + int(base_action) + DIFFERENCES * int(differences)


def difference_indices(scenario: Scenario, fill: int = 0) -> tuple[int, int, int]:
    """(tracked reading, reference, last preview sample) indices of the observation (with `fill` preview
    samples filled in, preview_fill), for PolicyInputs.differences: the model's inputs y/s - r/s and
    r(t_{k+P})/s - r(t_k)/s. Without a preview the last sample is the reference itself (a change of 0)."""
    lay = scenario.layout
    reference = lay.slice("reference").start
    return (
        lay.slice("sensors").start + scenario.tracked_sensor,
        reference,
        reference + (scenario.preview_steps or fill),
    )


def policy_observation(
    obs: np.ndarray, base_action: np.ndarray | None, differences: tuple[int, int, int] | None = None
) -> np.ndarray:
    """The model's input (float32): the env's observation, then the base action in residual mode, then
    with `differences` (difference_indices) the tracking error and the reference's change over the
    preview. One observation (d,) with one base action, or rows (n, d) with one base action per row."""
    parts = [obs]
    if base_action is not None:
        parts.append(np.asarray(base_action, dtype=np.float32).reshape(*obs.shape[:-1], 1))
    if differences is not None:
        tracked, reference, last = differences
        parts.append(obs[..., [tracked, last]] - obs[..., [reference, reference]])
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=-1)


def residual_action(
    base_action: np.ndarray, residual: np.ndarray, alpha: float, share: float | np.ndarray = 1.0
) -> np.ndarray:
    """u = clip(u_base + α·s·u_res, -1, 1): the residual has authority α of the full command range, times
    the share s in [0, 1] its base grants it now (Controller.residual_share; 1 for every base but a gated
    one), elementwise: one action (1,) or rows (n, 1) with s a number or (n, 1). s multiplies α·u_res in
    u_res's precision, so a number and an array give the same bits and s = 1 gives u_base + α·u_res to
    the last bit."""
    base = np.asarray(base_action, dtype=np.float64)
    r = alpha * np.asarray(residual).reshape(base.shape)
    u = base + np.asarray(share, dtype=r.dtype) * r
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


def _actor_leaves(policy: Any) -> tuple[Any, Any, list[Any], bool] | None:
    """A deterministic actor as its layers: (the module whose extract_features the actor calls, its
    features extractor, its leaf modules in call order, whether a final tanh follows them) for a SAC,
    TQC or CrossQ actor (squashed Gaussian, no gSDE: the mode is tanh(mu(latent_pi(features)))), a TD3
    actor (mu(features)) or a PPO / A2C policy (diagonal Gaussian, no gSDE: the mode is
    action_net(policy_net(features))); None for any other policy (recurrent, gSDE, another
    distribution)."""
    from stable_baselines3.common.distributions import (  # the rl extra
        DiagGaussianDistribution,
        SquashedDiagGaussianDistribution,
    )

    if hasattr(policy, "mlp_extractor") and hasattr(policy, "action_net"):  # an actor-critic policy
        if type(policy.action_dist) is not DiagGaussianDistribution or getattr(policy, "use_sde", False):
            return None
        if hasattr(policy, "lstm_actor"):
            return None
        leaves = [*_leaves(policy.mlp_extractor.policy_net), policy.action_net]
        return policy, policy.pi_features_extractor, leaves, False
    actor = getattr(policy, "actor", None)
    if actor is None or not hasattr(actor, "mu") or getattr(actor, "use_sde", False):
        return None
    if not hasattr(actor, "latent_pi"):
        return actor, actor.features_extractor, _leaves(actor.mu), False
    if not isinstance(actor.action_dist, SquashedDiagGaussianDistribution):
        return None
    return actor, actor.features_extractor, [*_leaves(actor.latent_pi), *_leaves(actor.mu)], True


def deterministic_actor(policy: Any) -> Callable[[Any], Any]:
    """A function of the observation tensor giving policy._predict(obs, deterministic=True), operation for
    operation: for a SAC, TQC or CrossQ actor (squashed Gaussian, no gSDE) tanh(mu(latent_pi(features)))
    (the distribution's mode), for a TD3 actor mu(features), for a PPO / A2C policy action_net(policy_net(
    features)), each as the plain chain of its layers; any other policy (recurrent, gSDE) keeps SB3's own
    _predict."""
    import torch  # the rl extra, as in _predict

    found = _actor_leaves(policy)
    if found is None:
        return lambda obs: policy._predict(obs, deterministic=True)
    owner, extractor, leaves, squashed = found
    # each leaf's forward is the computation its call makes (no hooks are set), without torch's dispatch
    chain = [leaf.forward for leaf in leaves] + ([torch.tanh] if squashed else [])

    def act(obs: Any) -> Any:
        h = owner.extract_features(obs, extractor)
        for f in chain:
            h = f(h)
        return h

    return act


def tree_sum(p: np.ndarray) -> np.ndarray:
    """Σ over axis 1 of p (n, k, m) by a fixed pairwise tree of elementwise additions (the first half of
    the terms plus the second, until one is left): every output element is the same sequence of IEEE
    operations whatever n and the other rows hold, so a row summed in a batch equals that row alone."""
    while (k := p.shape[1]) > 1:
        half = k // 2
        head = p[:, :half] + p[:, half : 2 * half]
        p = np.concatenate([head, p[:, 2 * half :]], axis=1) if k % 2 else head
    return p[:, 0]


@dataclasses.dataclass(frozen=True)
class RowwiseActor:
    """A deterministic SB3 actor as numpy layers whose rows never interact, for evaluating many episodes
    with one call per step (evaluate.run_episodes): a batch of observations gets, row for row and bit
    for bit, the actions each would get alone. torch's batched matrix products do not promise that (on
    this machine rows of a 20-row batch differed from single rows in the last bit).

    Each layer is computed in float64: the products of the activations and the weights, summed by
    tree_sum, plus the bias; then ReLU or tanh; the action is rounded to float32 once, at the end. It is
    the network function to float64 rounding, where torch's float32 forward differs from it by float32
    rounding (up to 1.2e-6 per action measured on the committed models; tests bound it at 1e-5). Built for a
    SAC / TQC / CrossQ actor (the squashed Gaussian's mode tanh(mu(latent_pi(features)))), a TD3 actor
    (mu(features)) or a PPO / A2C policy's Gaussian mean (action_net(policy_net(features))), of Linear,
    ReLU and Tanh layers on a flatten or a column-selecting (asymmetric) features extractor; `of` gives
    None for any other network."""

    columns: tuple[int, ...] | None  # the features extractor's selection of observation columns (None: all)
    # ("linear", Wᵀ (in, out), b (out,)) or ("relu" | "tanh", None, None), in call order
    layers: tuple[tuple[str, np.ndarray | None, np.ndarray | None], ...]

    @classmethod
    def of(cls, policy: Any) -> RowwiseActor | None:
        """The actor of a feed-forward SB3 policy, or None if it has layers this class does not know."""
        found = _actor_leaves(policy)
        if found is None:
            return None
        _, features, leaves, squashed = found
        extractor = type(features).__name__
        if extractor == "SelectFeatures":  # training/asymmetric.py: the actor's columns of the observation
            columns = tuple(int(i) for i in features.indices.tolist())
        elif extractor == "FlattenExtractor" and len(policy.observation_space.shape) == 1:
            columns = None
        else:
            return None
        layers = []
        for m in leaves:
            kind = type(m).__name__
            if kind == "Linear":
                w = m.weight.detach().cpu().numpy().astype(np.float64).T.copy()
                b = np.zeros(w.shape[1]) if m.bias is None else m.bias.detach().cpu().numpy()
                b = b.astype(np.float64)
                layers.append(("linear", w, b))
            elif kind in ("ReLU", "Tanh"):
                layers.append((kind.lower(), None, None))
            else:
                return None
        if squashed:
            layers.append(("tanh", None, None))
        return cls(columns, tuple(layers))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The actions (n, k), float32, for model inputs (n, d)."""
        h = np.asarray(x, dtype=np.float64)
        if self.columns is not None:
            h = h[:, self.columns]
        for kind, w, b in self.layers:
            if kind == "linear":
                h = tree_sum(h[:, :, None] * w) + b
            elif kind == "relu":
                h = np.maximum(h, 0.0)
            else:
                h = np.tanh(h)
        return h.astype(np.float32)


def _leaves(module: Any) -> list[Any]:
    """A module's leaves in call order (Sequentials flattened)."""
    if type(module).__name__ == "Sequential":
        return [leaf for child in module.children() for leaf in _leaves(child)]
    return [module]


class LearnedNeeds:
    """What a learned controller brings into its env: its base's hardware and its observation blocks. Shared
    by LearnedPolicy and the training env (agents/training/), so both build the same env."""

    inputs: PolicyInputs
    base: Controller | None

    def plant_overrides(self, scenario: Scenario) -> dict:
        return self.base.plant_overrides(scenario) if self.base is not None else {}

    def observation_overrides(self) -> dict:
        return self.inputs.observation_overrides()


def preview_fill(observes: int, inputs: PolicyInputs, plants: tuple[str, ...], scenario: Scenario) -> int:
    """Reference-preview samples to fill in for a model of `observes` inputs, trained on `plants`, on this
    scenario: on a regulation scenario (a constant reference, Scenario.task) without a preview, a model
    trained on the scenario's plant with a P-step preview is given r(t_{k+1}) ... r(t_{k+P}) = r(t_k), its
    observation's reference repeated P times (what the env itself shows with a preview, bit for bit:
    tested), so one model can serve a plant's regulation and tracking scenarios. Within a plant the
    layouts differ by the preview alone (the history and privileged blocks are the model's inputs), so
    the missing inputs are the preview; a model of unknown or other plants gets nothing filled (0)."""
    if scenario.spec.name not in plants or scenario.task != REGULATION or scenario.preview_steps:
        return 0
    return max(observes - inputs.size(scenario), 0)


def with_preview(obs: np.ndarray, reference_end: int, fill: int) -> np.ndarray:
    """Observation rows (n, d) with the reference entry (the column before `reference_end`) repeated
    `fill` times after it, where a preview block stands (preview_fill)."""
    if not fill:
        return obs
    head, tail = obs[:, :reference_end], obs[:, reference_end:]
    return np.concatenate([head, np.repeat(head[:, -1:], fill, axis=1), tail], axis=1)


def policy_why_not(
    observes: tuple[int, ...],
    inputs: PolicyInputs,
    plants: tuple[str, ...],
    base: Controller | None,
    scenario: Scenario,
) -> str | None:
    """Why a policy that observes `observes` (its input shape) cannot run on the scenario, or None: its
    base controller's reason, another plant, another input shape (after any preview_fill). Decided from
    the saved model or from its manifest alone (registry.why_not), the same way."""
    if base is not None and (reason := base.why_not(scenario)) is not None:
        return f"base controller {base.name}: {reason}"
    if plants and scenario.spec.name not in plants:
        return f"trained for plants {list(plants)}, the scenario's plant is {scenario.spec.name}"
    got = (inputs.size(scenario) + preview_fill(observes[0], inputs, plants, scenario),)
    if got != tuple(observes):
        return f"the model observes shape {tuple(observes)}, the scenario gives {got}"
    return None


@dataclasses.dataclass(frozen=True)
class Normalizer:
    """Frozen observation statistics (stable-baselines3's VecNormalize at evaluation): x ↦
    clip((x - mean) / sqrt(var + ε), -clip, clip) in float64, then float32, VecNormalize.normalize_obs's
    arithmetic operation for operation (so the same bits)."""

    mean: np.ndarray  # float64, one per model input
    var: np.ndarray  # float64
    epsilon: float
    clip: float

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.clip((x - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip, self.clip).astype(
            np.float32
        )

    @classmethod
    def of(cls, venv: Any) -> Normalizer | None:
        """The observation statistics of a VecNormalize (None if it does not normalise observations)."""
        if venv is None or not venv.norm_obs:
            return None
        rms = venv.obs_rms
        return cls(np.array(rms.mean, np.float64), np.array(rms.var, np.float64), venv.epsilon, venv.clip_obs)


@dataclasses.dataclass(frozen=True)
class ActionScale:
    """From the network's output to the action (SB3's predict): a squashed policy's tanh output in
    [-1, 1] mapped onto [low, high] (BasePolicy.unscale_action's arithmetic), any other clipped to it."""

    low: np.ndarray  # float32, the action space's bounds
    high: np.ndarray
    squash: bool

    def __call__(self, a: np.ndarray) -> np.ndarray:
        if self.squash:
            return self.low + (0.5 * (a + 1.0) * (self.high - self.low))
        return np.clip(a, self.low, self.high)

    @classmethod
    def of(cls, policy: Any) -> ActionScale:
        space = policy.action_space
        return cls(np.array(space.low), np.array(space.high), bool(policy.squash_output))


@dataclasses.dataclass(frozen=True)
class LayerNetwork:
    """A deterministic actor as plain layers (RowwiseActor) and its action scaling: what the safe model
    format (agents/learned/folder.py) stores and what every feed-forward SAC / TD3 / TQC actor is evaluated
    as, numpy only. `observes` is the model input's shape, `algorithm` the algorithm that trained it."""

    actor: RowwiseActor
    scale: ActionScale
    observes: tuple[int, ...]
    algorithm: str
    recurrent: ClassVar[bool] = False

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The actions (n, k) for model inputs (n, d)."""
        return self.scale(self.actor(x))

    def reset(self) -> None:
        """A new episode: no state to clear."""

    @classmethod
    def of(cls, model: Any) -> LayerNetwork | None:
        """The network of an SB3 model as layers, or None where RowwiseActor does not know its actor."""
        actor = RowwiseActor.of(model.policy)
        if actor is None:
            return None
        shape = tuple(model.observation_space.shape)
        return cls(actor, ActionScale.of(model.policy), shape, type(model).__name__)


class SB3Network:
    """An SB3 model that is not a LayerNetwork (a recurrent PPO, gSDE, CrossQ's batch
    renormalisation, sbx's JAX models): acted through SB3, one row at a time, deterministic. Only models
    of this process (training, validation) or loaded with an explicit trust in pickles
    (folder.load_sb3_zip) reach it."""

    def __init__(self, model: Any):
        self.model = model
        self.observes = tuple(model.observation_space.shape)
        self.algorithm = type(model).__name__
        self.recurrent = hasattr(model.policy, "lstm_actor")
        self.jax = is_jax(model)
        self._actor: Callable[[Any], Any] | None = None  # deterministic_actor(policy), built on first use
        self._device: Any = None  # the policy's torch device, read with _actor
        self.reset()

    def reset(self) -> None:
        """A new episode: a recurrent policy's state starts afresh."""
        self.state, self.start = None, np.ones(1, dtype=bool)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.recurrent:  # one episode's state: lockstep() gives each episode its own replica
            rows = []
            for row in x:
                a, self.state = self.model.predict(
                    row, state=self.state, episode_start=self.start, deterministic=True
                )
                self.start = np.zeros(1, dtype=bool)
                rows.append(a)
            return np.asarray(rows)
        if self.jax:
            return np.asarray([self.model.predict(row, deterministic=True)[0] for row in x])
        return np.asarray([self._predict(row) for row in x])

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
        return ActionScale.of(policy)(a)


Network = LayerNetwork | SB3Network


def network_of(model: Any) -> Network:
    """A model as the network a LearnedPolicy acts with: a LayerNetwork as it is; an SB3 model as its
    layers where RowwiseActor knows them (each row bit for bit as alone), otherwise SB3Network."""
    if isinstance(model, LayerNetwork | SB3Network):
        return model
    layers = None if is_jax(model) or hasattr(model.policy, "lstm_actor") else LayerNetwork.of(model)
    return layers if layers is not None else SB3Network(model)


class LearnedPolicy(LearnedNeeds, Controller):
    """A trained policy, deterministic: a network (LayerNetwork, from the safe model format or an SB3
    model's layers; or SB3Network) on the model input, after frozen observation statistics.

    With `base` it is a residual: u = clip(u_base + α·π(obs, u_base), -1, 1), and it brings the base's
    hardware (plant_overrides). `normalizer` is a Normalizer (or a VecNormalize, whose statistics are
    copied). A recurrent policy keeps its state over the episode. An SB3 model's weights are read when
    the policy is built: wrap a model that is no longer being trained (a loaded or saved one, as the
    registry and validation do), or build a new LearnedPolicy after training it further.
    """

    name: ClassVar[str] = "Learned"

    def __init__(
        self,
        model: Any,
        plants: tuple[str, ...] = (),
        name: str = "Learned",
        *,
        inputs: PolicyInputs = PolicyInputs(),
        base: Controller | None = None,
        alpha: float = 1.0,
        normalizer: Any = None,
    ):
        self.network = network_of(model)
        self.plants, self.name = tuple(plants), name  # instance values shadow the class
        self.inputs, self.base, self.alpha = inputs, base, float(alpha)
        self.normalizer = (
            normalizer
            if normalizer is None or isinstance(normalizer, Normalizer)
            else (Normalizer.of(normalizer))
        )
        if inputs.base_action != (base is not None):
            raise ValueError(
                "a residual policy (base controller given) observes the base action, and only it"
            )
        self.hashes: dict[str, str] = {}
        self._fill, self._reference_end = 0, 0  # preview samples to fill in (set per episode by reset)
        self._differences: tuple[int, int, int] | None = None  # difference_indices, set per episode

    @property
    def recurrent(self) -> bool:
        return self.network.recurrent

    def why_not(self, scenario: Scenario) -> str | None:
        return policy_why_not(self.network.observes, self.inputs, self.plants, self.base, scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        if self.base is not None:
            self.base.reset(ctx)
        self.start_episode(ctx)

    def start_episode(self, ctx: EpisodeContext) -> None:
        """The policy's own episode start (its base is reset by whoever acts it: reset, PolicyLockstep)."""
        self.ctx = ctx
        self.network.reset()
        self._fill = preview_fill(self.network.observes[0], self.inputs, self.plants, ctx.scenario)
        self._reference_end = ctx.scenario.layout.slice("reference").stop
        if self.inputs.differences:
            self._differences = difference_indices(ctx.scenario, self._fill)

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.base is None:
            return self.actions(obs[None], None)[0]
        ub = np.asarray(self.base.act(obs)).reshape(1, 1)
        return self.actions(obs[None], ub, self.base.residual_share())[0]

    def actions(
        self, obs: np.ndarray, base: np.ndarray | None, share: float | np.ndarray = 1.0
    ) -> np.ndarray:
        """The actions (n, 1) for observation rows (n, d) and, in residual mode, the base actions (n, 1)
        and the residual's shares the bases grant (a number or (n, 1); residual_action): the model input,
        the frozen normaliser, the network and the residual, each row's action the same whatever the
        other rows hold (one network call for a LayerNetwork, one per row otherwise)."""
        x = policy_observation(with_preview(obs, self._reference_end, self._fill), base, self._differences)
        if self.normalizer is not None:
            x = self.normalizer(x)
        a = self.network(x)
        if base is None:
            return np.clip(np.asarray(a, dtype=np.float32), -1.0, 1.0)
        return residual_action(base, a, self.alpha, share)

    def lockstep(self, n: int) -> Lockstep:
        """n episodes with one network call per step for all of them: one copy of the base per episode
        (PolicyLockstep); a recurrent policy keeps one state per episode, so each gets a replica."""
        if self.recurrent:
            return Lockstep(self, n, other=self.replica)
        return PolicyLockstep(self, n)

    def replica(self) -> LearnedPolicy:
        """Another controller on the same model and normaliser, with its own base and episode state."""
        twin = copy.copy(self)
        twin.base = copy.deepcopy(self.base)
        if isinstance(self.network, SB3Network):
            twin.network = copy.copy(self.network)
            twin.network.reset()
        return twin

    def params(self) -> dict[str, Any]:
        out: dict[str, Any] = {"algorithm": self.network.algorithm, **self.hashes}
        if self.base is not None:
            out |= {"base": self.base.name, "alpha": self.alpha}
        return out


class PolicyLockstep(Lockstep):
    """A LearnedPolicy on n episodes: each episode's base controller acts on its own row, then one call of
    LearnedPolicy.actions for every row (row for row the actions each episode gets alone)."""

    def __init__(self, policy: LearnedPolicy, n: int):
        super().__init__(policy, n)
        self.policy = policy
        self.bases = policy.base.lockstep(n) if policy.base is not None else None

    def reset(self, ctx: EpisodeContext) -> None:
        self.policy.start_episode(ctx)
        if self.bases is not None:  # policy.base among them: reset once
            self.bases.reset(ctx)

    def act(self, obs: np.ndarray, rows: np.ndarray) -> np.ndarray:
        if self.bases is None:
            return self.policy.actions(obs, None)
        acts = self.bases.act(obs, rows)  # an array where the bases' rows are decoded at once (Lockstep)
        base = acts if isinstance(acts, np.ndarray) else np.array([np.asarray(u).reshape(1) for u in acts])
        share = self.bases.shares(rows)
        return self.policy.actions(obs, base, share)
