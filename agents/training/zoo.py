"""rl-baselines3-zoo support: what a zoo hyper-parameter file (configs/zoo/*.yml) names, so that

    python -m rl_zoo3.train --algo sac --env frictiongym/KangRobot-v1 --gym-packages frictiongym.envs \\
        --conf-file configs/zoo/sac.yml

trains the project's residual agents; a trained zoo agent as a controller of the suite (zoo_policy), so
that it is judged on the validation suite by the leaderboard's own loop (validate); and the front end
for the zoo's commands that have no --gym-packages option (scripts/zoo.py record_video).
"""

from __future__ import annotations

import argparse
import contextlib
import runpy
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

from frictiongym.agents.evaluation.evaluate import EnvCache
from frictiongym.agents.learned.folder import load_sb3_zip
from frictiongym.agents.learned.policy import LearnedPolicy, PolicyInputs, algorithm_class
from frictiongym.agents.registry import base_controller
from frictiongym.agents.training import (
    ResidualEnv,
    best_classical,
    classical_on,
    evaluate_controller,
    validation_episodes,
    zero_output,
)
from frictiongym.envs.config import ConfigError


class Residual(ResidualEnv):
    """Zoo `env_wrapper`: residual mode over the built-in controller `base` with authority `alpha` (a
    fraction of the full command), and the residual's own smoothness weight (ResidualEnv). A base that
    brings hardware of its own (plant_overrides, e.g. RDFC's analog rate feedback) is refused: the zoo
    builds the env with gym.make, before any wrapper."""

    def __init__(self, env: gym.Env, base: str, alpha: float, smoothness: float = 0.0):
        controller = base_controller(base)
        scenario = env.unwrapped.scenario
        if (reason := controller.why_not(scenario)) is not None:
            raise ConfigError("env_wrapper.base", f"{base} does not apply to {scenario.name}: {reason}")
        if hardware := controller.plant_overrides(scenario):
            raise ConfigError(
                "env_wrapper.base",
                f"{base} brings hardware ({hardware}) that an env made by "
                "gym.make lacks; choose a base without it, or train with scripts/train.py",
            )
        super().__init__(env, controller, alpha, smoothness=smoothness)


def _callback_base() -> type:
    from stable_baselines3.common.callbacks import BaseCallback

    return BaseCallback


class ZeroResidualStart(_callback_base()):
    """Zoo `callback`: at the start of training the policy's mean action is exactly 0 and its std `std`
    (action units), so the residual starts as its base controller, as scripts/train.py's runs start."""

    def __init__(self, std: float = 0.05, verbose: int = 0):
        super().__init__(verbose)
        self.std = std

    def _on_training_start(self) -> None:

        zero_output(self.model, self.std)

    def _on_step(self) -> bool:
        return True


def zoo_run(folder: str | Path, algo: str, env_id: str, exp_id: int = 0) -> Path:
    """A zoo log folder's run: <folder>/<algo>/<env>_<exp_id> (exp_id 0: the latest)."""
    root = Path(folder) / algo.lower()
    prefix = env_id.replace("/", "-") if "/" in env_id else env_id
    runs = sorted(root.glob(f"{prefix}_*"), key=lambda p: int(p.name.rsplit("_", 1)[1]))
    if exp_id:
        runs = [r for r in runs if r.name == f"{prefix}_{exp_id}"]
    if not runs:
        raise FileNotFoundError(f"no zoo run of {env_id} ({algo}) under {root}")
    return runs[-1]


def _params_dir(run: Path) -> Path:
    return next(p for p in run.iterdir() if p.is_dir() and (p / "config.yml").exists())


class _ZooConfigLoader(yaml.SafeLoader):
    """The safe loader plus the one Python tag rl-zoo writes into config.yml: an OrderedDict, read as a
    plain mapping. Any other tag is refused, never constructed."""


_ZooConfigLoader.add_constructor(
    "tag:yaml.org,2002:python/object/apply:collections.OrderedDict",
    lambda loader, node: dict(loader.construct_sequence(node, deep=True)[0]),
)


def zoo_config(run: str | Path) -> dict[str, Any]:
    """The hyper-parameters a zoo run saved (its config.yml), read safely (_ZooConfigLoader); a file it
    cannot read is a ConfigError naming it."""
    path = _params_dir(Path(run)) / "config.yml"
    try:
        data = yaml.load(path.read_text(), Loader=_ZooConfigLoader)
    except yaml.YAMLError as e:
        raise ConfigError("(yaml)", " ".join(str(e).split()), str(path)) from None
    if not isinstance(data, dict):
        raise ConfigError("(file)", "expected a mapping of hyper-parameters", str(path))
    return data


def zoo_env_kwargs(run: str | Path) -> dict[str, Any]:
    """The env keyword arguments a zoo run trained with (from its hyper-parameter file)."""
    return dict(zoo_config(run).get("env_kwargs") or {})


def zoo_policy(
    run: str | Path, algo: str, name: str | None = None, *, trust_pickle: bool = False
) -> LearnedPolicy:
    """A trained zoo agent as a controller of the suite: its final model, its frozen VecNormalize and,
    from its saved config, the residual base and authority (Residual wrapper). The zoo saves pickles
    only (an SB3 zip, a VecNormalize): loading them runs their code, so only with trust_pickle."""
    run = Path(run)
    params = _params_dir(run)
    config = zoo_config(run)
    wrappers = config.get("env_wrapper") or []
    wrappers = [wrappers] if not isinstance(wrappers, list) else wrappers
    name_of_wrapper = f"{__name__}.{Residual.__name__}"
    residual = next(
        (w[name_of_wrapper] for w in wrappers if isinstance(w, dict) and name_of_wrapper in w), None
    )
    model_zip = next(run.glob("*.zip"))
    norm = params / "vecnormalize.pkl"
    algorithm = algorithm_class(algo.upper()).__name__
    model, stats = load_sb3_zip(
        model_zip, norm if norm.exists() else None, algorithm, trust_pickle=trust_pickle
    )
    return LearnedPolicy(
        model,
        name=name or f"zoo-{algo}-{run.name}",
        normalizer=stats,
        inputs=PolicyInputs(base_action=residual is not None),
        base=base_controller(residual["base"]) if residual else None,
        alpha=residual["alpha"] if residual else 1.0,
    )


def validate(
    run: str | Path, algo: str, env_id: str, episodes: int = 10, *, trust_pickle: bool = False
) -> dict[str, Any]:
    """A zoo agent against the best classical baseline on the first `episodes` validation-suite episodes
    of the scenario it trained on (the selection the project's own training uses; never the test suite);
    its files are pickles (zoo_policy): only with trust_pickle."""

    spec = gym.spec(env_id)  # a per-scenario id carries its scenario; a per-plant id its default
    default = spec.kwargs.get("scenario") or spec.scenario  # envs.ScenarioSpec
    scenario = zoo_env_kwargs(run).get("scenario") or default
    eps = validation_episodes(scenario)[:episodes]
    envs = EnvCache()
    baseline = best_classical(scenario, classical_on(eps, envs))
    agent = evaluate_controller(zoo_policy(run, algo, trust_pickle=trust_pickle), eps, envs)
    return {"scenario": scenario, "baseline": baseline, "agent": agent}


def run_zoo_command(command: str, argv: list[str]) -> None:
    """Run rl_zoo3.<command> (train, enjoy, record_video: scripts/zoo.py's ZOO_COMMANDS) with this package's
    envs registered. enjoy and
    record_video read a run's env arguments from its args.yml, where the zoo stores only those given on
    its command line: without --env-kwargs, those of the run's hyper-parameter file are passed on, so
    the agent is shown on the scenario it trained on."""
    import frictiongym.envs  # noqa: F401  (registers the ids the zoo's --env names)

    if command != "train" and "--env-kwargs" not in argv:
        p = argparse.ArgumentParser(add_help=False)
        p.add_argument("--algo", default="ppo")
        p.add_argument("--env", default="")
        p.add_argument("-f", "--folder", default="rl-trained-agents")
        p.add_argument("--exp-id", type=int, default=0)
        known, _ = p.parse_known_args(argv)
        with contextlib.suppress(FileNotFoundError, StopIteration):
            kwargs = zoo_env_kwargs(zoo_run(known.folder, known.algo, known.env, known.exp_id))
            argv = [*argv, "--env-kwargs", *(f"{k}:{v!r}" for k, v in kwargs.items())]
    sys.argv = [f"rl_zoo3.{command}", *argv]
    runpy.run_module(f"rl_zoo3.{command}", run_name="__main__", alter_sys=True)
