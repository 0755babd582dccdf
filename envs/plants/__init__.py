"""Plants: one module per plant (its preset builder, typed document data and derived linear models),
shared dataclasses (spec.py), MJCF (mjcf.py), per-episode parameters (params.py) and the sampled-data
simulator (sim.py).

Adding a plant means configs/plants/<name>.yaml with `plant: <name>`, a module <name>.py here with
`build(cfg: Node, friction_model: str) -> PlantSpec`, and its scenarios.
"""

from __future__ import annotations

import importlib
import logging
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import mujoco

from ..config import ConfigError, Node, load_yaml, merge, plant_names, preset_path
from ..friction import BRISTLE_MODELS, FRICTION_MODELS, check_numerics
from .identified import IdentifiedFriction, apply_identified
from .params import check_randomization
from .spec import JointSpec, PlantSpec

# MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working directory; route them to Python logging
# instead (a divergence is reported per episode through info["diverged"]). Set where every simulation's
# plant is built, so importing frictiongym.envs (a command's --help) does not import MuJoCo.
mujoco.set_mju_user_warning(lambda msg: logging.getLogger("frictiongym.mujoco").warning(msg))

__all__ = ["PlantSpec", "plant_config", "plant_module", "plant_names", "plant_spec"]


def plant_module(name: str) -> ModuleType:
    """The module frictiongym.envs.plants.<name> that builds plant `name`."""
    if name not in plant_names():
        raise ConfigError("plant", f"unknown plant {name!r}; available: {plant_names()}")
    return importlib.import_module(f"{__name__}.{name}")


FIXED_KEYS = ("plant",)  # a preset's keys that overrides cannot change (choose another preset instead)


def plant_config(name: str | Path, overrides: dict | None = None, prefix: str = "") -> dict[str, Any]:
    """The preset's YAML merged with overrides (keys must exist in the preset); `prefix` names where the
    overrides came from in errors (e.g. "plant_overrides.")."""
    source = preset_path(name, "plants").name
    for key in FIXED_KEYS:
        if isinstance(overrides, dict) and key in overrides:
            raise ConfigError(
                f"{prefix}{key}",
                "the plant is the preset's; choose another plant (or scenario) instead",
                source,
            )
    return merge(load_yaml(name), overrides, prefix=prefix, source=source)


def plant_spec(
    name: str | Path,
    overrides: dict | None = None,
    friction_model: str = "lugre",
    check_ranges: bool = True,
    prefix: str = "",
) -> PlantSpec:
    """Build the SI PlantSpec of preset `name` with YAML-level overrides; validates every value, every
    key (unknown and missing keys are errors naming the file) and, with check_ranges (the plant will be
    randomised), every corner of the randomization ranges. Without it, values drawn from the ranges
    are never used, and any value pinned at a reset is checked there. `prefix`: as plant_config's."""

    if friction_model not in FRICTION_MODELS:
        raise ConfigError("friction_model", f"{friction_model!r} not in {list(FRICTION_MODELS)}")
    cfg = Node(plant_config(name, overrides, prefix), preset_path(name, "plants").name)
    module = plant_module(cfg.choice("plant", plant_names()))
    cfg.get("description")
    spec = module.build(cfg, friction_model)
    identified = IdentifiedFriction.from_section(cfg)
    if identified is not None:  # friction identified from data (scripts/identify.py) replaces the document's
        spec = apply_identified(spec, identified)
    cfg.done()
    delay_hi = spec.randomization.get("delay_s", (0.0, spec.delay))[1]
    jitter_hi = spec.randomization.get("jitter_s", (0.0, spec.jitter))[1]
    if delay_hi + jitter_hi > spec.control_period + 1e-12:
        raise ConfigError(
            "randomization.delay_s",
            f"delay up to {delay_hi} s plus jitter up to {jitter_hi} s exceeds "
            f"the control period {spec.control_period} s",
            cfg.source,
        )
    try:  # the friction the preset's levels give, checked in the model's terms (and named so)
        for j in spec.joints:
            if j.friction is not None:
                j.friction.validate(f"friction[{j.name}]")
                if friction_model in BRISTLE_MODELS:
                    inertia = spec.reflected_inertia(j.name)
                    check_numerics(j.friction, inertia, spec.timestep, spec.integrator, f"friction[{j.name}]")
    except ConfigError as e:
        raise ConfigError(e.field, e.message, cfg.source) from None
    if friction_model not in BRISTLE_MODELS:
        spec = replace(spec, joints=tuple(_strip(j, friction_model) for j in spec.joints))
    if check_ranges:
        check_randomization(spec)
    return spec


def _strip(j: JointSpec, model: str) -> JointSpec:
    """Reduce a joint's LuGre friction to the requested simpler model (kept as LuGreParams fields)."""
    if j.friction is None:
        return j
    if model == "none":
        return replace(j, friction=None)
    if model == "viscous":
        return replace(j, viscous=j.viscous + j.friction.sigma2, friction=None)
    return j  # coulomb: the MJCF uses frictionloss = fc and the bias; σ's are unused
