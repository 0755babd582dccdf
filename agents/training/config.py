"""Training configs (configs/agents/<name>.yaml, rl-zoo style): `defaults` and per-scenario entries over
configs/agents/_defaults.yaml, `extends:` chains, every key checked into a RunConfig (errors name the file
and field); the algorithms and their update-to-data schedule."""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from frictiongym.agents.learned.policy import MAX_HISTORY, PolicyInputs, algorithm_class
from frictiongym.envs.config import (
    ConfigError,
    Node,
    configs_dir,
    deep_merge,
    load_extending,
    load_yaml,
    preset_names,
    preset_path,
)
from frictiongym.envs.plants.spec import RANDOMIZATION_KEYS
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.step import REWARD_WEIGHTS

from ..registry import base_controller

VALIDATION_SUITE = "validation"
ASYMMETRIC = ("SAC", "TD3", "TQC", "CrossQ")  # the privileged critic (agents/training/asymmetric.py)
JAX = ("sbx.SAC", "sbx.TQC", "sbx.CrossQ")  # sbx's JAX learners (the optional sbx extra)
OFF_POLICY = (*ASYMMETRIC, *JAX)  # replay-buffer learners: update_to_data applies
ALGORITHMS = (*OFF_POLICY, "PPO", "RecurrentPPO")
ACTIVATIONS = ("relu", "tanh", "elu", "leaky_relu")


# ------------------------------------------------------------------------------------------- config
@dataclass(frozen=True)
class RunConfig:
    """One scenario's resolved training settings (defaults + the scenario's entry)."""

    name: str  # leaderboard name prefix; the model is called f"{name}-{scenario}-s{seed}"
    algorithm: str
    scenario: str
    total_timesteps: int
    n_envs: int
    update_to_data: float | None  # gradient steps per env step (off-policy); None: hyperparams' own
    randomize: bool
    randomization: dict[str, tuple[float, float]]  # replaces the plant's ranges key by key
    reward: dict[str, float]  # scenario reward weights replaced (tracking, tracking_abs, effort, smoothness)
    inputs: PolicyInputs
    base: str | None  # registered controller name (residual mode) or None
    alpha: float  # residual authority, fraction of the full command range
    initial_std: float  # initial action std of the (residual) policy, in action units
    normalize_observation: bool
    normalize_reward: bool
    eval_every_steps: int
    eval_episodes: int  # the first n of the scenario's validation-suite episodes
    max_effort_ratio: float  # selection: effort_rms <= ratio · best classical baseline's (validation)
    max_wall_time_s: float  # the run stops (and says so in its manifest) after this wall time
    hyperparams: dict[str, Any] = field(default_factory=dict)  # the algorithm's keyword arguments
    # more scenarios of the plant whose validation episodes select the model beside the scenario's own
    # (validation.scenarios): the most scenarios beaten, then the geometric mean of metric / baseline
    eval_scenarios: tuple[str, ...] = ()
    # the training envs' random-reference keys replaced (e.g. segments, segment_s); validation and every
    # evaluation keep the scenario's own references
    reference: dict[str, Any] = field(default_factory=dict)
    # residual mode: weight of the residual's own smoothness penalty, w·(a - a_prev)² on the policy's
    # action in [-1, 1] per control period (vec_env.residual_smoothness); 0: none
    residual_smoothness: float = 0.0
    source: str = ""  # the config file

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["randomization"] = {k: list(v) for k, v in self.randomization.items()}
        d["eval_scenarios"] = list(self.eval_scenarios)
        return d


def config_names() -> list[str]:
    return preset_names("agents")


def raw_config(path: str | Path) -> tuple[dict[str, Any], str]:
    """A training config file's mapping with its `extends:` chain merged in (the child's keys win), and
    the file's path."""
    return load_extending(path, "agents"), str(preset_path(path, "agents"))


def scenario_settings(raw: dict[str, Any], scenario: str) -> dict[str, Any]:
    """A scenario's settings in a (merged) config file: configs/agents/_defaults.yaml, then the file's
    `defaults`, then its scenario entry."""

    defaults = deep_merge(load_yaml(configs_dir() / "agents" / "_defaults.yaml"), raw.get("defaults") or {})
    return copy.deepcopy(deep_merge(defaults, raw["scenarios"][scenario]))  # the caller may edit it


def load_config(path: str | Path, scenario: str | None = None) -> list[RunConfig]:
    """The runs a training config asks for: every scenario in it, or just `scenario` (scenario_settings)."""
    raw, file = raw_config(path)
    top = Node(raw, file)
    algo = top.choice("algorithm", ALGORITHMS)
    name = top["name"]
    if not isinstance(name, str) or not name.replace("-", "").replace("_", "").isalnum():
        raise top.error("name", f"expected a name of letters, digits, '-' and '_', got {name!r}")
    top.get("defaults")  # read through scenario_settings; marks the key as known for top.done()
    scenarios = top.section("scenarios")
    keys = [k for k in list(scenarios.keys()) if scenarios[k] is not None]  # null: an entry left out
    if not keys:
        raise top.error("scenarios", "expected at least one scenario")
    if scenario is not None and scenario not in keys:
        raise top.error("scenarios", f"no entry for scenario {scenario!r}; the file has {keys}")
    out = []
    for sc in keys:  # every entry is checked, the asked-for ones returned
        node = Node(scenario_settings(raw, sc), file, f"scenarios.{sc}.")
        cfg = parse_run_config(node, name, algo, sc, file)
        if scenario in (None, sc):
            out.append(cfg)
    scenarios.done()
    top.done()
    return out


def run_config_with(
    path: str | Path, scenario: str, overrides: dict[str, Any], algorithm: str | None = None
) -> RunConfig:
    """A scenario's run config with `overrides` (a mapping of its settings, merged key by key; a
    hyper-parameter set to null takes the algorithm's default) and optionally another algorithm: a
    variant of a config, e.g. one setup of scripts/bench_training.py."""
    raw, file = raw_config(path)
    if scenario not in (raw.get("scenarios") or {}):
        raise ConfigError("scenarios", f"no entry for scenario {scenario!r}", file)
    entry = deep_merge(scenario_settings(raw, scenario), overrides)
    if algorithm is not None and algorithm not in ALGORITHMS:
        raise ConfigError("algorithm", f"expected one of {list(ALGORITHMS)}, got {algorithm!r}", file)
    node = Node(entry, file, f"scenarios.{scenario}.")
    return parse_run_config(node, raw["name"], algorithm or raw["algorithm"], scenario, file)


def parse_run_config(c: Node, name: str, algo: str, scenario: str, source: str) -> RunConfig:
    """The RunConfig of one scenario entry (`c`: its merged settings), every key checked; errors name the
    field and the file."""
    try:
        algorithm_class(algo)  # an optional extra (sbx) may be missing
    except ValueError as e:
        raise ConfigError("algorithm", str(e), source) from None
    trained = load_scenario(scenario)  # (an unknown scenario is an error naming the available ones)
    if trained.held_out:
        raise ConfigError(
            f"scenarios.{scenario}",
            "is a held-out (generalisation) scenario: it is never trained or selected on",
            source,
        )
    r = c.section("randomization")
    ranges = {}
    for key in list(r.keys()):
        if key not in RANDOMIZATION_KEYS:
            raise r.error(key, f"unknown randomization key; allowed: {sorted(RANDOMIZATION_KEYS)}")
        ranges[key] = r.interval(key, *RANDOMIZATION_KEYS[key])
    w = c.section("reward")
    reward = {k: w.nonneg(k) for k in REWARD_WEIGHTS if k in w}
    reference = _training_reference(c, trained)
    o = c.section("observation")
    res = c.section("residual")
    base = res["base"]
    if base is not None:
        try:
            base_controller(base)
        except ValueError as e:
            raise res.error("base", str(e)) from None
    inputs = PolicyInputs(
        o.integer("history", 0, MAX_HISTORY),
        o.boolean("privileged_critic"),
        base is not None,
        o.boolean("differences"),
    )
    hp = c.section("hyperparams")
    hyper = {k: hp[k] for k in list(hp.keys()) if hp[k] is not None}  # null: the algorithm's default
    _check_hyperparams(algo, hyper, hp)
    warmup = hyper.get("learning_starts", 100) > 0 and not (
        hyper.get("use_sde") and hyper.get("use_sde_at_warmup")
    )
    if base is not None and algo in OFF_POLICY and warmup:
        raise hp.error(
            "learning_starts",
            "a residual starts at zero output: set learning_starts: 0 (no uniform random actions at "
            "full authority), or use_sde with use_sde_at_warmup",
        )
    if inputs.privileged and algo not in ASYMMETRIC:
        raise o.error(
            "privileged_critic",
            f"asymmetric actor-critic is implemented for {', '.join(ASYMMETRIC)}, not {algo}",
        )
    n_envs = c.integer("n_envs", 1, 64)
    utd = None if c.get("update_to_data") is None else c.positive("update_to_data", 64.0)
    if utd is not None:
        if algo not in OFF_POLICY:
            raise c.error("update_to_data", f"applies to {', '.join(OFF_POLICY)}, not {algo}: set it to null")
        for key in ("train_freq", "gradient_steps"):
            if key in hyper:
                raise hp.error(key, "update_to_data sets it (with n_envs): give one of the two, not both")
        try:
            sb3_schedule(utd, n_envs)
        except ValueError as e:
            raise c.error("update_to_data", str(e)) from None
    n = c.section("normalize")
    v = c.section("validation")
    cfg = RunConfig(
        name=name,
        algorithm=algo,
        scenario=scenario,
        total_timesteps=c.integer("total_timesteps", 1, 10**8),
        n_envs=n_envs,
        update_to_data=utd,
        randomize=c.boolean("randomize"),
        randomization=ranges,
        reward=reward,
        inputs=inputs,
        base=base,
        alpha=res.positive("alpha", 1.0) if base is not None else 1.0,
        initial_std=c.positive("initial_std", 1.0),
        normalize_observation=n.boolean("observation"),
        normalize_reward=n.boolean("reward"),
        eval_every_steps=v.integer("every_steps", 1),
        eval_episodes=v.integer("episodes", 1, 10_000),
        max_effort_ratio=v.positive("max_effort_ratio"),
        max_wall_time_s=c.positive("max_wall_time_s"),
        hyperparams=hyper,
        eval_scenarios=_eval_scenarios(v, trained),
        reference=reference,
        residual_smoothness=_residual_smoothness(res, base),
        source=source,
    )
    if base is None:
        res.get("alpha")  # read (unused without a base)
    for node in (r, w, o, res, hp, n, v, c):
        node.done()
    return cfg


def _training_reference(c: Node, scenario: Scenario) -> dict[str, Any]:
    """`reference`: keys of the training scenario's random reference family replaced for the training
    envs (the type stays; checked by loading the scenario with them, errors naming reference.<key>)."""
    ref = c.get("reference") or {}
    if not isinstance(ref, dict):
        raise c.error("reference", f"expected a mapping of random-reference keys, got {ref!r}")
    if not ref:
        return {}
    if scenario.reference.type != "random" or "type" in ref:
        raise c.error(
            "reference", f"only a random reference's keys may be replaced ({scenario.name}'s type stays)"
        )
    try:
        load_scenario(scenario.name, {"reference": ref})
    except ConfigError as e:
        raise c.error(
            e.field if e.field.startswith("reference") else f"reference.{e.field}", e.message
        ) from None
    return copy.deepcopy(ref)


def _residual_smoothness(res: Node, base: str | None) -> float:
    """residual.smoothness: >= 0, and only with a base (without one the scenario's reward.smoothness
    prices the policy's whole command)."""
    w = res.nonneg("smoothness")
    if w and base is None:
        raise res.error(
            "smoothness", "applies in residual mode (set residual.base), or use reward.smoothness"
        )
    return w


def _eval_scenarios(v: Node, scenario: Scenario) -> tuple[str, ...]:
    """validation.scenarios: more scenarios of the training scenario's plant to select on (their
    validation-suite episodes; never a held-out scenario), the training scenario itself left out."""
    names = v.get("scenarios") or []
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise v.error("scenarios", f"expected a list of scenario names, got {names!r}")
    plant = scenario.spec.name
    for name in names:
        try:
            sc = load_scenario(name)
        except (ConfigError, FileNotFoundError) as e:
            raise v.error("scenarios", str(e)) from None
        if sc.held_out:
            raise v.error("scenarios", f"{name} is held-out (generalisation): never selected on")
        if sc.spec.name != plant:
            raise v.error("scenarios", f"{name} is a {sc.spec.name} scenario; {scenario.name} is {plant}'s")
    return tuple(dict.fromkeys(n for n in names if n != scenario.name))


def sb3_schedule(update_to_data: float, n_envs: int) -> tuple[int, int]:
    """SB3's (train_freq in vector steps, gradient_steps) for `update_to_data` gradient steps per env step
    with n_envs envs (one vector step = n_envs env steps): g = ratio·n_envs gradient steps after every
    vector step if g >= 1, else one after every 1/g vector steps; either must be a whole number."""
    g = update_to_data * n_envs
    whole = round(g) if g >= 1 else round(1 / g)
    if abs((g if g >= 1 else 1 / g) - whole) > 1e-9 * whole:
        raise ValueError(
            f"{update_to_data} x n_envs {n_envs} = {g:.6g} gradient steps per vector step: it, or its "
            "inverse, must be a whole number"
        )
    return (1, whole) if g >= 1 else (whole, 1)


# The numeric hyper-parameters with a meaningful range (SB3's documentation): a value outside it, or NaN,
# diverges or fails inside torch, so it is refused when the config is read. (low, high, whole number)
HYPER_RANGES: dict[str, tuple[float, float, bool]] = {
    "gamma": (0.0, 1.0, False),  # discount (1: undiscounted)
    "tau": (0.0, 1.0, False),  # soft target update
    "gae_lambda": (0.0, 1.0, False),
    "clip_range": (0.0, 1.0, False),
    "ent_coef": (0.0, 10.0, False),  # a number here ("auto", "auto_<init>" are strings)
    "vf_coef": (0.0, 10.0, False),
    "max_grad_norm": (1e-6, 1e6, False),
    "target_entropy": (-1e3, 1e3, False),
    "action_noise_std": (0.0, 10.0, False),
    "buffer_size": (1, 1e8, True),
    "batch_size": (1, 1e6, True),
    "learning_starts": (0, 1e9, True),
    "n_steps": (1, 1e7, True),
    "n_epochs": (1, 1e4, True),
    "train_freq": (1, 1e6, True),
    "policy_delay": (1, 1e4, True),
    "n_quantiles": (1, 1e4, True),
    "top_quantiles_to_drop_per_net": (0, 1e4, True),
}


def _check_hyperparams(algo: str, hyper: dict[str, Any], node: Node) -> None:
    """Every hyper-parameter is a keyword of the algorithm's constructor (or one of ours, below)."""
    ours = {"action_noise_std"}
    params = set(inspect.signature(algorithm_class(algo).__init__).parameters) - {"self", "policy", "env"}
    params -= {"seed", "device", "tensorboard_log", "verbose", "_init_setup_model"}
    for key in hyper:
        if key not in params | ours:
            raise node.error(key, f"not a hyper-parameter of {algo}; allowed: {sorted(params | ours)}")
    pk = hyper.get("policy_kwargs", {})
    if not isinstance(pk, dict):
        raise node.error("policy_kwargs", f"expected a mapping, got {pk!r}")
    act = pk.get("activation_fn")
    if act is not None and act not in ACTIVATIONS:
        raise node.error("policy_kwargs.activation_fn", f"expected one of {list(ACTIVATIONS)}, got {act!r}")
    for key, (low, high, whole) in HYPER_RANGES.items():
        if key in hyper and isinstance(hyper[key], int | float):  # "auto" and schedules are SB3's to read
            x = hyper[key]
            if isinstance(x, bool) or not (low <= x <= high) or (whole and x != int(x)):
                kind = "a whole number" if whole else "a number"
                raise node.error(key, f"expected {kind} in [{low:g}, {high:g}], got {x!r}")
    if "learning_rate" in hyper:
        try:
            learning_rate(hyper["learning_rate"])
        except ValueError as e:
            raise node.error("learning_rate", str(e)) from None


def learning_rate(value: float | str) -> float | Callable[[float], float]:
    """A learning_rate hyper-parameter as the algorithm takes it: a number, or "lin_<rate>" (rl-zoo3's
    spelling) for a rate decaying linearly from <rate> to 0 over the run's total_timesteps (SB3 calls it
    with the progress remaining, 1 -> 0)."""
    if isinstance(value, bool):
        raise ValueError(f"expected a positive number or 'lin_<rate>', got {value!r}")
    if isinstance(value, int | float):
        if not math.isfinite(value) or value <= 0:
            raise ValueError(f"expected a positive finite number or 'lin_<rate>', got {value!r}")
        return float(value)
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError:
            start = -1.0
        if math.isfinite(start) and start > 0:
            from stable_baselines3.common.utils import LinearSchedule

            return LinearSchedule(start, 0.0, 1.0)
    raise ValueError(f"expected a positive finite number or 'lin_<rate>' (e.g. lin_3e-4), got {value!r}")


def scenario_overrides(cfg: RunConfig) -> dict[str, Any]:
    """The scenario overrides of the run's training env (before the base controller's hardware)."""
    out: dict[str, Any] = {}
    if cfg.randomization:
        out["plant_overrides"] = {"randomization": {k: list(v) for k, v in cfg.randomization.items()}}
    if cfg.reward:
        out["reward"] = dict(cfg.reward)
    if cfg.reference:
        out["reference"] = copy.deepcopy(cfg.reference)
    return out
