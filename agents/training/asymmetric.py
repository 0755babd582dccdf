"""Asymmetric actor-critic for SB3's off-policy algorithms: the critic reads the whole observation,
privileged ground truth included; the actor's features keep only the indices a deployed controller has.
So a policy trained with privileged information acts on what a real controller measures."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import torch
from sb3_contrib.crossq.policies import CrossQPolicy
from sb3_contrib.tqc.policies import TQCPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.sac.policies import SACPolicy
from stable_baselines3.td3.policies import TD3Policy


class SelectFeatures(BaseFeaturesExtractor):
    """The observation entries at `indices` (flat Box observations)."""

    def __init__(self, observation_space: gym.spaces.Box, indices: Sequence[int]):
        super().__init__(observation_space, len(indices))
        self.register_buffer("indices", torch.as_tensor(list(indices), dtype=torch.long))

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return observations.index_select(1, self.indices).float()


class _AsymmetricActor:
    """Mixin: the policy takes actor_indices=[...] and builds its actor on SelectFeatures."""

    def __init__(self, *args: Any, actor_indices: Sequence[int] = (), **kwargs: Any):
        self.actor_indices = list(actor_indices)
        super().__init__(*args, **kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {**super()._get_constructor_parameters(), "actor_indices": self.actor_indices}

    def make_actor(self, features_extractor: BaseFeaturesExtractor | None = None) -> Any:
        return super().make_actor(SelectFeatures(self.observation_space, self.actor_indices))


class AsymmetricSACPolicy(_AsymmetricActor, SACPolicy):
    """SAC policy whose actor sees only actor_indices."""


class AsymmetricTD3Policy(_AsymmetricActor, TD3Policy):
    """TD3 policy whose actor (and target actor) see only actor_indices."""


class AsymmetricTQCPolicy(_AsymmetricActor, TQCPolicy):
    """TQC policy whose actor sees only actor_indices."""


class AsymmetricCrossQPolicy(_AsymmetricActor, CrossQPolicy):
    """CrossQ policy whose actor sees only actor_indices."""


POLICIES = {
    "SAC": AsymmetricSACPolicy,
    "TD3": AsymmetricTD3Policy,
    "TQC": AsymmetricTQCPolicy,
    "CrossQ": AsymmetricCrossQPolicy,
}


def asymmetric_policy(algorithm: str) -> type:
    """The asymmetric policy class for SAC, TD3, TQC or CrossQ."""
    if algorithm not in POLICIES:
        raise ValueError(f"no asymmetric policy for {algorithm}; use one of {list(POLICIES)}")
    return POLICIES[algorithm]
