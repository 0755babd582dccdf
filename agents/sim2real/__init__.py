"""The sim-to-real friction study (scripts/sim2real.py): `study` computes (the episodes, their summary, the
closing-the-loop model-error study), `report` renders (sim2real.md's text, the figures), `run` evaluates,
computes, renders and writes (see study's docstring for the design)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from frictiongym.agents import registry
from frictiongym.agents.evaluation import engine
from frictiongym.envs.records import atomic_text, csv_text
from frictiongym.envs.scenario import load_scenario

from ..base import ZERO
from ..figures import save_figure
from . import report
from .study import (
    AXES,
    MODEL_ERROR_SEEDS,
    SEED_RANGE,
    SEEDS,
    SET_SPAN,
    STRUCTURES,
    model_error,
    model_error_table,
    plan,
    runnable_structures,
    summarize,
)

__all__ = ["AXES", "MODEL_ERROR_SEEDS", "SEEDS", "SEED_RANGE", "SET_SPAN", "STRUCTURES", "plan", "run"]


def run(
    scenario: str,
    controllers: list[str] | None,
    models: tuple[str, ...],
    out: Path,
    seeds: int = 10,
    points: int = 5,
    joint: int = 20,
    workers: int = 1,
    progress: bool = True,
    model_error_draws: int = 10,
    ray: engine.Ray | None = None,
    structures: tuple[str, ...] = STRUCTURES,
) -> tuple[list[dict[str, Any]], str]:
    """Run the study into out/ (episodes.csv, sim2real.csv, sim2real.png, sim2real.md, and the closing-the-
    loop study model_error.csv / .png); returns the table and the markdown."""
    controllers, models = registry.entries(controllers, models)  # a user's "module:attr" specs too
    names = controllers or registry.default_entries(models)
    names = [ZERO, *(n for n in names if n != ZERO)]
    structures, left_out = runnable_structures(scenario, structures)
    episodes, rejected = plan(scenario, seeds, points, joint, structures)
    options = {
        "structures": list(structures),
        "study": "sim2real",
        "scenario": scenario,
        "seeds": seeds,
        "points": points,
        "joint": joint,
        "controllers": names,
        "models": list(models),
    }
    results, skipped = engine.evaluate_to(out, names, episodes, options, workers, progress, models, ray)
    table = summarize(results, scenario)
    sc = load_scenario(scenario)
    ran = [n for n in names if n != ZERO and any(r["controller"] == n for r in table)]
    study = report.Study(
        scenario,
        sc.main_metric,
        sc.spec.friction_model,
        table,
        ran,
        seeds,
        joint,
        rejected,
        skipped,
        left_out,
    )
    atomic_text(out / "sim2real.csv", csv_text(table))
    save_figure(report.robustness_figure(table, scenario), out, "sim2real.png", dpi=90)
    if structures:
        save_figure(report.structures_figure(table, scenario), out, "sim2real_structures.png", dpi=90)
    section = None
    if model_error_draws:
        classical = [n for n in names if n in registry.BUILTIN and n != ZERO]
        me = model_error_table(model_error(scenario, classical, model_error_draws, progress))
        fields = ["controller", "design", "mean", "ci_low", "ci_high", "loss", "loss_low", "loss_high"]
        atomic_text(out / "model_error.csv", csv_text(me, fields))
        save_figure(report.model_error_figure(me, sc.main_metric), out, "model_error.png", dpi=90)
        section = report.model_error_markdown(me, sc.main_metric, model_error_draws)
    text = report.markdown(study, section)
    atomic_text(out / "sim2real.md", text)
    return table, text
