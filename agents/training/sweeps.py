"""Training sweeps on Ray Tune (scripts/train.py --sweep): several seeds and a grid, or an Optuna search, over
values of a training config. Every trial is a normal training run (agents/training/) that writes its
own model folder and manifest and reports its validation main metric to Tune after every evaluation.
The same sweep runs on a laptop (a local Ray) and on a cluster (--address).

    configs/sweeps/<name>.yaml:
        config: residual_sac              # a training config (configs/agents/)
        scenario: m220_reversal_tracking  # one of its scenarios
        seeds: [0, 1]                     # training seeds (a grid axis in every search)
        search: grid                      # grid | optuna
        samples: 8                        # optuna: number of trials
        space:                            # dotted keys of the scenario's settings
          residual.alpha: {grid: [0.05, 0.1]}                # grid
          hyperparams.learning_rate: {loguniform: [1.0e-4, 1.0e-3]}   # optuna: uniform | loguniform | choice
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any

from frictiongym.agents.evaluation.engine import ray_init
from frictiongym.agents.training import (
    RunConfig,
    TrainingRun,
    load_config,
    parse_run_config,
    raw_config,
    scenario_settings,
)
from frictiongym.envs.config import ConfigError, Node, load_yaml, preset_path
from frictiongym.envs.records import command_line

SEARCHES = ("grid", "optuna")
DISTRIBUTIONS = {"grid": "grid", "uniform": "uniform", "loguniform": "loguniform", "choice": "choice"}
METRIC = "validation_main"  # the scenario's main metric on the validation suite (lower is better)


@dataclasses.dataclass(frozen=True)
class Sweep:
    name: str
    config: str
    scenario: str
    seeds: tuple[int, ...]
    search: str
    samples: int
    space: dict[str, tuple[str, list[Any]]]  # dotted key -> (distribution, values or bounds)
    source: str


def load_sweep(path: str | Path) -> Sweep:
    """A sweep file, checked: its config and scenario exist, every key of the space is a setting of the
    config (checked by building one trial), distributions fit the search."""
    file = preset_path(path, "sweeps")
    s = Node(load_yaml(file), str(file))
    config, scenario = s["config"], s["scenario"]
    load_config(config, scenario)  # errors name the config's own file and field
    seeds = s["seeds"]
    if not isinstance(seeds, list) or not seeds or not all(isinstance(x, int) and x >= 0 for x in seeds):
        raise s.error("seeds", f"expected a non-empty list of non-negative integers, got {seeds!r}")
    search = s.choice("search", SEARCHES)
    samples = s.integer("samples", 1, 10_000, default=1)
    sp = s.section("space")
    space = {}
    for key in list(sp.keys()):
        d = sp.section(key)
        kinds = list(d.keys())
        if len(kinds) != 1 or kinds[0] not in DISTRIBUTIONS:
            raise sp.error(key, f"expected one of {list(DISTRIBUTIONS)} with its values, got {kinds}")
        kind, values = kinds[0], d[kinds[0]]
        if search == "grid" and kind != "grid":
            raise d.error(kind, "a grid search takes {grid: [values]}")
        if search == "optuna" and kind == "grid":
            raise d.error(kind, "an optuna search takes uniform, loguniform or choice")
        if (
            not isinstance(values, list)
            or not values
            or (kind in ("uniform", "loguniform") and len(values) != 2)
        ):
            raise d.error(kind, f"expected a list (bounds [low, high] for {kind}), got {values!r}")
        space[key] = (kind, values)
        d.done()
    sweep = Sweep(file.stem, config, scenario, tuple(seeds), search, samples, space, str(file))
    sp.done()
    s.done()
    first = {k: v[0] for k, (_, v) in space.items()}
    trial_config(sweep, first)  # every key is a setting of the config
    return sweep


def trial_config(sweep: Sweep, values: dict[str, Any]) -> RunConfig:
    """The run config of one trial: the scenario's settings with the dotted keys replaced."""
    raw, file = raw_config(sweep.config)
    entry = scenario_settings(raw, sweep.scenario)
    for key, value in values.items():
        node = entry
        parts = key.split(".")
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                raise ConfigError(
                    f"space.{key}", f"{p!r} is not a section of the training settings", sweep.source
                )
            node = node[p]
        if parts[-1] not in node and parts[0] != "hyperparams":
            raise ConfigError(f"space.{key}", "not a setting of the training config", sweep.source)
        node[parts[-1]] = value
    return parse_run_config(
        Node(entry, file, f"scenarios.{sweep.scenario}."), raw["name"], raw["algorithm"], sweep.scenario, file
    )


def run_sweep(sweep: Sweep, out: Path, address: str | None = None, workers: int = 2) -> list[dict[str, Any]]:
    """Run the sweep on Ray Tune (a local Ray with `workers` CPUs, or the cluster at `address`); returns one
    row per trial: its values, seed, best admissible validation metric and model folder."""
    from ray import tune

    ray_init(workers, address)
    command = command_line()
    out = Path(out).resolve()

    def trainable(params: dict[str, Any]) -> None:
        import torch

        torch.set_num_threads(1)
        values = dict(params)  # Tune keeps `params` as the trial's config: do not change it
        seed = values.pop("seed")
        cfg = trial_config(sweep, values)
        trial = tune.get_context().get_trial_id()
        folder = out / sweep.name / sweep.scenario / f"seed{seed}-{trial}"
        run = TrainingRun(cfg, seed, folder, command, progress=False)  # validation in turn: Ray's CPUs
        run.reporter = lambda row: tune.report(
            {
                METRIC: row["main"] if row["admissible"] else math.inf,
                "step": row["step"],
                "folder": str(folder),
            }
        )
        run.train()

    space: dict[str, Any] = {"seed": tune.grid_search(list(sweep.seeds))}
    search_alg = None
    for key, (kind, v) in sweep.space.items():
        if kind == "grid":
            space[key] = tune.grid_search(v)
        elif kind == "choice":
            space[key] = tune.choice(v)
        else:
            space[key] = getattr(tune, kind)(*v)
    if sweep.search == "optuna":
        from ray.tune.search.optuna import OptunaSearch

        space["seed"] = tune.choice(list(sweep.seeds))
        search_alg = OptunaSearch(metric=METRIC, mode="min", seed=0)
    tuner = tune.Tuner(
        tune.with_resources(trainable, {"cpu": 1}),
        param_space=space,
        tune_config=tune.TuneConfig(
            metric=METRIC, mode="min", search_alg=search_alg, num_samples=sweep.samples if search_alg else 1
        ),
        run_config=tune.RunConfig(name=sweep.name, storage_path=str(out / "tune"), verbose=0),
    )
    # Ctrl-C raises KeyboardInterrupt here, as in every other run of the suite (scripts/train.py stops at
    # once and says so); Tune's own handler would first wind its trials down
    os.environ.setdefault("TUNE_DISABLE_SIGINT_HANDLER", "1")
    results = tuner.fit()
    rows = []
    for r in results:
        frame = r.metrics_dataframe
        best = (
            frame[METRIC].min() if frame is not None and METRIC in frame else math.nan
        )  # nan: never reported
        rows.append(
            {
                **{k: v for k, v in r.config.items()},
                METRIC: float(best),
                "folder": r.metrics.get("folder", "") if r.metrics else "",
                "error": str(r.error) if r.error else "",
            }
        )
    return rows
