"""The learner of a run: an SB3 / sb3-contrib / sbx model built from its config, and the residual's
zero start (the policy's mean output zeroed, so a residual starts as its base controller)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from frictiongym.agents.learned.policy import algorithm_class, is_jax
from frictiongym.envs.scenario import load_scenario

from .config import RunConfig, learning_rate, sb3_schedule


# ------------------------------------------------------------------------------------------- model
def build_model(cfg: RunConfig, venv: Any, seed: int, tb: str | None) -> Any:
    """The algorithm with the config's hyper-parameters; in residual mode its policy starts at exactly
    zero output with a small action std (zero_output)."""
    import torch

    hyper = dict(cfg.hyperparams)
    if "learning_rate" in hyper:  # a number, or "lin_<rate>": a linear decay to 0 (config.learning_rate)
        hyper["learning_rate"] = learning_rate(hyper["learning_rate"])
    if cfg.update_to_data is not None:
        hyper["train_freq"], hyper["gradient_steps"] = sb3_schedule(cfg.update_to_data, cfg.n_envs)
    pk = dict(hyper.pop("policy_kwargs", {}) or {})
    if "activation_fn" in pk:
        pk["activation_fn"] = {
            "relu": torch.nn.ReLU,
            "tanh": torch.nn.Tanh,
            "elu": torch.nn.ELU,
            "leaky_relu": torch.nn.LeakyReLU,
        }[pk["activation_fn"]]
    noise_std = hyper.pop("action_noise_std", None)
    if noise_std is not None:
        from stable_baselines3.common.noise import NormalActionNoise

        hyper["action_noise"] = NormalActionNoise(np.zeros(1), np.full(1, float(noise_std)))
    policy: Any = "MlpLstmPolicy" if cfg.algorithm == "RecurrentPPO" else "MlpPolicy"
    if cfg.algorithm in ("PPO", "RecurrentPPO") or hyper.get("use_sde"):
        pk.setdefault("log_std_init", math.log(cfg.initial_std))
    if cfg.inputs.privileged:
        from .asymmetric import asymmetric_policy  # builds torch modules at import: only when asked for

        sc = load_scenario(cfg.scenario)
        policy = asymmetric_policy(cfg.algorithm)
        pk["actor_indices"] = cfg.inputs.actor_indices(sc)
    model = algorithm_class(cfg.algorithm)(
        policy, venv, seed=seed, device="cpu", verbose=0, tensorboard_log=tb, policy_kwargs=pk, **hyper
    )
    if cfg.base is not None:
        zero_output(model, cfg.initial_std)
    return model


def zero_output(model: Any, std: float) -> None:
    """Make the policy's mean action exactly 0 (last layer zeroed) and its std `std` (action units)."""
    if is_jax(model):
        return _zero_output_flax(model, std)
    import torch

    with torch.no_grad():
        policy = model.policy
        if hasattr(policy, "action_net"):  # PPO, RecurrentPPO
            last = policy.action_net
            policy.log_std.fill_(math.log(std))
        elif hasattr(model, "actor_target"):  # TD3: mu = Sequential(..., Linear, Tanh)
            last = [m for m in model.actor.mu if isinstance(m, torch.nn.Linear)][-1]
        else:  # SAC, TQC: squashed Gaussian with a state-dependent log std
            last = model.actor.mu
            if isinstance(model.actor.log_std, torch.nn.Linear):
                model.actor.log_std.weight.zero_()
                model.actor.log_std.bias.fill_(math.log(std))
        last.weight.zero_()
        last.bias.zero_()
        if hasattr(model, "actor_target"):
            model.actor_target.load_state_dict(model.actor.state_dict())


def _zero_output_flax(model: Any, std: float) -> None:
    """zero_output for sbx's squashed-Gaussian actors: their last two Dense layers are the mean and the
    log std (SAC and TQC nest the layers under "params", CrossQ does not)."""
    import jax.numpy as jnp

    state = model.policy.actor_state
    nested = "params" in state.params
    tree = state.params["params"] if nested else state.params
    dense = sorted((k for k in tree if k.startswith("Dense_")), key=lambda k: int(k.split("_")[1]))
    mean, log_std = dense[-2], dense[-1]
    tree = {
        **tree,
        mean: {k: jnp.zeros_like(v) for k, v in tree[mean].items()},
        log_std: {
            "kernel": jnp.zeros_like(tree[log_std]["kernel"]),
            "bias": jnp.full_like(tree[log_std]["bias"], math.log(std)),
        },
    }
    model.policy.actor_state = state.replace(params={**state.params, "params": tree} if nested else tree)
