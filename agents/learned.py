"""Learned controllers behind the same interface as the classical ones, so the leaderboard compares like
with like: a stable-baselines3 policy acting on the env's observation."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.scenario import Scenario

from .base import Controller, EpisodeContext


class SB3Policy(Controller):
    """A trained SB3 model (any algorithm with predict), deterministic. It applies to a scenario whose
    observation has the model's shape and, if `plants` is given, whose plant is one of them."""

    name: ClassVar[str] = "SB3"

    def __init__(self, model: Any, plants: tuple[str, ...] = (), name: str = "SB3"):
        self.model, self.plants, self.name = model, tuple(plants), name  # instance values shadow the class
        self.model_hash = ""

    @classmethod
    def load(
        cls, path: str | Path, algo: str, plants: tuple[str, ...] = (), name: str | None = None
    ) -> SB3Policy:
        """Load a saved model, e.g. SB3Policy.load("sac_kang.zip", "SAC", ("kang_robot",)); algo is a
        stable-baselines3 or sb3-contrib class name. The file's SHA-256 is kept as its provenance."""
        import importlib

        for package in ("stable_baselines3", "sb3_contrib"):
            try:
                cls_ = getattr(importlib.import_module(package), algo, None)
            except ImportError:
                cls_ = None
            if cls_ is not None:
                break
        else:
            raise ValueError(f"algorithm {algo!r} is not a stable-baselines3 or sb3-contrib class")
        policy = cls(cls_.load(str(path), device="cpu"), plants, name or Path(path).stem)
        policy.model_hash = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        return policy

    def why_not(self, scenario: Scenario) -> str | None:
        want = tuple(self.model.observation_space.shape)
        got = (scenario.layout.size,)
        if got != want:
            return f"the model observes shape {want}, the scenario gives {got}"
        if self.plants and scenario.spec.name not in self.plants:
            return f"trained for plants {list(self.plants)}, the scenario's plant is {scenario.spec.name}"
        return None

    def reset(self, ctx: EpisodeContext) -> None:
        self.ctx = ctx

    def act(self, obs: np.ndarray) -> np.ndarray:
        action, _ = self.model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float32).reshape(1)

    def params(self) -> dict[str, Any]:
        return {"algorithm": type(self.model).__name__, "model_sha256": self.model_hash}
