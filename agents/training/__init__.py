"""Training learned compensators with stable-baselines3 / sb3-contrib (scripts/train.py is the front end), in
rooms: config.py (RunConfig from a checked config file), env.py and vec_env.py (the training env),
model.py (the learner), validation.py (selection on the validation suite), callbacks.py (SB3 callbacks:
validation, checkpoint, wall-time stop), run.py (a run, many runs, export).

A training config (configs/agents/<name>.yaml, rl-zoo style) gives `defaults` and per-scenario entries
that override them; every key is checked (unknown keys, types, ranges: errors naming the file and field).
One run = (config, scenario, seed) and writes a model folder the leaderboard loads (--models):

    policy.safetensors            the model selected on the validation suite: its actor's layers, action
                                  bounds and frozen statistics (agents/learned/folder.py: no pickle)
    manifest.yaml                 algorithm, network, SHA-256, scenario, base controller, α,
                                  hyper-parameters, seed, steps, wall time, the exact command, package
                                  version, validation score
    validation.csv, training_curve.png, tb/ (TensorBoard), checkpoint/ (for --resume: one complete set
                                  per checkpoint, named by checkpoint/LATEST)

Rules it enforces: training episodes use seeds from TRAINING_SEEDS (disjoint from every suite); the model
is selected on the `validation` suite only, by the scenario's main metric, among evaluations whose
effort_rms is at most `max_effort_ratio` times the best classical baseline's on the same episodes (a
compensator that chatters is not a result); one torch thread per process.
"""

from frictiongym.agents.learned.manifest import MANIFEST, MODEL, NORMALIZER, Manifest

from .config import (
    ALGORITHMS,
    ASYMMETRIC,
    JAX,
    OFF_POLICY,
    VALIDATION_SUITE,
    RunConfig,
    config_names,
    load_config,
    parse_run_config,
    raw_config,
    run_config_with,
    sb3_schedule,
    scenario_settings,
)
from .env import ResidualEnv, make_training_env, training_env_kwargs
from .model import build_model, zero_output
from .run import RECORDS, NothingSelected, TrainingRun, export_model, run_dir, train_many, train_one
from .validation import (
    Baseline,
    Snapshot,
    best_classical,
    classical_on,
    evaluate_controller,
    evaluate_snapshot,
    validation_episodes,
)
from .vec_env import SEEDS_PER_RUN, TRAINING_SEEDS, TrainingVecEnv, episode_seed

__all__ = [
    "ALGORITHMS",
    "ASYMMETRIC",
    "JAX",
    "MANIFEST",
    "MODEL",
    "NORMALIZER",
    "OFF_POLICY",
    "RECORDS",
    "SEEDS_PER_RUN",
    "TRAINING_SEEDS",
    "VALIDATION_SUITE",
    "Baseline",
    "Manifest",
    "NothingSelected",
    "ResidualEnv",
    "RunConfig",
    "Snapshot",
    "TrainingRun",
    "TrainingVecEnv",
    "best_classical",
    "build_model",
    "classical_on",
    "config_names",
    "episode_seed",
    "evaluate_controller",
    "evaluate_snapshot",
    "export_model",
    "load_config",
    "make_training_env",
    "parse_run_config",
    "raw_config",
    "run_config_with",
    "run_dir",
    "sb3_schedule",
    "scenario_settings",
    "train_many",
    "train_one",
    "training_env_kwargs",
    "validation_episodes",
    "zero_output",
]
