"""The sim-to-real friction study (scripts/sim2real.py): controllers designed or trained on the nominal plant
(or on randomised ones) evaluated on shifted plants, with the foundation's per-episode parameter pinning.

- One axis at a time: each of AXES is pinned to a grid over its shift range (scales ×0.5…×1.5, the
  asymmetry shift ±0.25 of the Coulomb level, the delay 0…one control period), the others nominal.
- Structures: the nominal plant with each friction structure (envs/friction.py: LuGre, Dahl, Maxwell-slip,
  Kang's stick-slip model, Coulomb + viscous), the same static levels, bristle stiffness and episodes; the
  controllers are designed (and the agents were trained) on the scenario's own structure.
- Joint shifts: every axis drawn at once, in two separate sets: in-distribution (inside the plant preset's
  randomisation ranges, what the `nominal` agents trained on) and out-of-distribution (inside the study's
  wide box, outside the preset's ranges on at least one axis). Draws the plant's checks reject (e.g. a
  LuGre stiffness too high for the timestep at a small inertia) are left out and counted.

Every episode is an engine job (resumable episodes.csv); the summary is computed from the results.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from frictiongym.agents.lab import experiments as ex
from frictiongym.agents.lab.identification import identify_simulated
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants.identified import IdentifiedFriction, apply_identified
from frictiongym.envs.plants.params import EpisodeParams, spec_with
from frictiongym.envs.records import atomic_text, atomic_write, csv_text
from frictiongym.envs.sampler import stream
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode, seed_range

from . import engine, registry, stats
from .base import ZERO
from .evaluate import EnvCache, EpisodeResult, run_episode

SEEDS, _LAST = seed_range("sim2real")  # configs/suites.yaml's range: disjoint from every suite and training
SET_SPAN = (_LAST + 1 - SEEDS) // 3  # seeds per set: one-axis and structure episodes, joint sets, model error
SEED_RANGE = (SEEDS, _LAST + 1)  # every seed the study uses, [first, end)


@dataclass(frozen=True)
class Axis:
    """A shifted parameter: a randomization key over [low, high] (delay: fractions of the period)."""

    key: str
    low: float
    high: float
    label: str

    def values(self, points: int, period: float) -> list[float]:
        grid = np.linspace(self.low, self.high, points)
        return [float(x * period) if self.key == "delay_s" else float(x) for x in grid]

    def box(self, period: float) -> tuple[float, float]:
        k = period if self.key == "delay_s" else 1.0
        return self.low * k, self.high * k


AXES = (
    Axis("friction_scale", 0.5, 1.5, "friction level (x nominal)"),
    Axis("asymmetry_shift", -0.25, 0.25, "asymmetry (shift / Coulomb level)"),
    Axis("stribeck_velocity_scale", 0.5, 1.5, "Stribeck velocity (x nominal)"),
    Axis("sigma0_scale", 0.5, 1.5, "bristle stiffness σ0 (x nominal)"),
    Axis("viscous_scale", 0.5, 1.5, "viscous friction (x nominal)"),
    Axis("inertia_scale", 0.5, 1.5, "inertia (x nominal)"),
    Axis("delay_s", 0.0, 1.0, "delay (s; up to one control period)"),
)


def _pinned(values: dict[str, float]) -> tuple[tuple[str, float], ...]:
    return tuple(sorted(values.items()))


def _admissible(scenario: str, values: dict[str, float]) -> bool:
    """Whether the plant's checks accept the pinned values (numerics, physical ranges)."""
    spec = load_scenario(scenario).spec
    try:
        EpisodeParams.from_values(spec, values).validate(spec)  # as the env builds a non-random episode
    except (ConfigError, ValueError):
        return False
    return True


STRUCTURES = ("lugre", "dahl", "maxwell_slip", "kang", "coulomb")  # the structural axis (friction_model)


def plan(
    scenario: str, seeds: int, points: int, joint: int, structures: tuple[str, ...] = STRUCTURES
) -> tuple[list[Episode], dict[str, int]]:
    """The study's episodes (nominal plant + pins; randomize off so only the pinned values move) and the
    number of rejected joint draws per set."""
    if max(seeds, joint) > SET_SPAN:
        raise ValueError(f"--seeds, --joint at most {SET_SPAN} (the study's seed sets: configs/suites.yaml)")
    sc = load_scenario(scenario)
    h, ranges = sc.control_period, sc.spec.randomization
    episodes: list[Episode] = []
    for model in structures:  # the same episodes (seeds) as every shift, on another friction structure
        episodes += [Episode(scenario, SEEDS + i, False, (("friction_model", model),)) for i in range(seeds)]
    for axis in AXES:
        if axis.key not in ranges and axis.key != "delay_s":
            continue
        for v in axis.values(points, h):
            if _admissible(scenario, {axis.key: v}):
                episodes += [
                    Episode(scenario, SEEDS + i, False, _pinned({axis.key: v})) for i in range(seeds)
                ]
    rejected = {}
    axes = [a for a in AXES if a.key in ranges]
    for k, name in enumerate(("in_distribution", "out_of_distribution")):
        rng, n, bad = stream(SEEDS + k, f"sim2real_{name}"), 0, 0
        while n < joint:
            if name == "in_distribution":
                values = {a.key: float(rng.uniform(*ranges[a.key])) for a in axes}
            else:
                values = {a.key: float(rng.uniform(*a.box(h))) for a in axes}
                if all(ranges[a.key][0] <= values[a.key] <= ranges[a.key][1] for a in axes):
                    continue  # inside the training ranges: not out of distribution
            if not _admissible(scenario, values):
                bad += 1
                continue
            episodes.append(Episode(scenario, SEEDS + SET_SPAN * (k + 1) + n, False, _pinned(values)))
            n += 1
        rejected[name] = bad
    return episodes, rejected


def condition(
    e: Episode | EpisodeResult, ranges: dict[str, tuple[float, float]]
) -> tuple[str, float | str]:
    """(axis or joint set, shift value; for the structural axis the structure's name) of an episode or of
    a result on one."""

    params = dict(e.params) if isinstance(e, Episode) else json.loads(e.params or "{}")
    if "friction_model" in params:
        return "friction_model", params["friction_model"]
    if len(params) == 1:
        ((key, value),) = params.items()
        return key, value
    inside = all(ranges[k][0] <= v <= ranges[k][1] for k, v in params.items())
    return ("joint_in_distribution" if inside else "joint_out_of_distribution"), math.nan


def summarize(results: list[EpisodeResult], scenario: str) -> list[dict[str, Any]]:
    """sim2real.csv rows: controller, axis, shift, main metric and score means with 95 % intervals."""
    sc = load_scenario(scenario)
    main, groups = sc.main_metric, defaultdict(list)
    for r in results:
        axis, shift = condition(r, sc.spec.randomization)
        groups[(r.controller, axis, shift)].append(r)
    out = []
    for (name, axis, shift), rs in groups.items():
        m = stats.mean_ci([r.metrics[main] for r in rs])
        s = stats.mean_ci([r.score for r in rs])
        e = stats.mean_ci([r.metrics["effort_rms"] for r in rs])
        out.append(
            {
                "controller": name,
                "axis": axis,
                "shift": shift,
                "episodes": len(rs),
                "metric": main,
                "mean": m[0],
                "ci_low": m[1],
                "ci_high": m[2],
                "score": s[0],
                "score_ci_low": s[1],
                "score_ci_high": s[2],
                "effort_rms": e[0],
            }
        )
    return out


DEGRADED = 1.5  # "breaks": the main metric exceeds 1.5x the controller's own value on the nominal plant


def findings(table: list[dict[str, Any]], controllers: list[str]) -> list[str]:
    """Markdown bullets computed from the table, per axis: the best controller at each shift, where each
    learned (non built-in) controller loses to the best classical baseline (its lead lost), and where any
    controller breaks (main metric above DEGRADED x its own nominal-plant value)."""
    by: dict[str, dict[tuple[str, float], dict[str, Any]]] = defaultdict(dict)
    for r in table:
        by[r["axis"]][(r["controller"], r["shift"])] = r
    classical = [c for c in controllers if c in registry.BUILTIN]
    learned = [c for c in controllers if c not in registry.BUILTIN and c not in registry.LIMITS]
    nominal = {}
    for c in controllers:
        at = [
            r for r in table if r["controller"] == c and r["axis"] == "friction_scale" and r["shift"] == 1.0
        ]
        nominal[c] = at[0]["mean"] if at else math.nan
    lines = []
    for axis, cells in by.items():
        if axis == "friction_model":  # categorical: structure_findings
            continue
        shifts = sorted({s for _, s in cells})
        leaders, lost, broken = [], [], []
        for s in shifts:
            here = [(cells[(c, s)]["mean"], c) for c in controllers if (c, s) in cells]
            if here:
                leaders.append(f"{_fmt_shift(axis, s)}: {min(here)[1]}")
        for c in learned:
            worse = [
                s
                for s in shifts
                if (c, s) in cells
                and any((b, s) in cells and cells[(b, s)]["mean"] < cells[(c, s)]["mean"] for b in classical)
            ]
            if worse:
                lost.append(f"{c} at {', '.join(_fmt_shift(axis, s) for s in worse)}")
        for c in controllers:
            bad = [s for s in shifts if (c, s) in cells and cells[(c, s)]["mean"] > DEGRADED * nominal[c]]
            if bad:
                broken.append(f"{c} at {', '.join(_fmt_shift(axis, s) for s in bad)}")
        lines.append(
            f"- **{axis}**: best by mean {'; '.join(leaders)}."
            + (f" Learned behind a classical baseline: {'; '.join(lost)}." if lost else "")
            + (
                f" Breaks (main metric > {DEGRADED}x its nominal-plant value): {'; '.join(broken)}."
                if broken
                else " No controller breaks."
            )
        )
    return lines


def structure_findings(table: list[dict[str, Any]], controllers: list[str], own: str) -> list[str]:
    """Markdown for the structural axis: a table of the main metric per controller and structure, then
    per structure the best controller, whether each learned controller keeps its lead over the best
    classical baseline it had on the scenario's own structure `own`, and who breaks (main metric above
    DEGRADED x its own value on `own`)."""
    cells = {(r["controller"], r["shift"]): r for r in table if r["axis"] == "friction_model"}
    structures = [s for s in STRUCTURES if any(k[1] == s for k in cells)]
    ran = [c for c in controllers if any((c, s) in cells for s in structures)]
    if not structures:
        return []
    lines = [
        "| controller | " + " | ".join(structures) + " |",
        "|---|" + "---|" * len(structures),
    ]
    for c in ran:
        vals = [f"{cells[(c, s)]['mean']:.4g}" if (c, s) in cells else "" for s in structures]
        lines.append(f"| {c} | " + " | ".join(vals) + " |")
    classical = [c for c in ran if c in registry.BUILTIN]
    learned = [c for c in ran if c not in registry.BUILTIN and c not in registry.LIMITS]

    def best_classical(s: str) -> float:
        return min((cells[(b, s)]["mean"] for b in classical if (b, s) in cells), default=math.nan)

    lines.append("")
    for s in structures:
        here = [(cells[(c, s)]["mean"], c) for c in ran if (c, s) in cells and c not in registry.LIMITS]
        text = f"- **{s}**: best {min(here)[1]} (the reference rows Ideal, Oracle aside)."
        kept = [c for c in learned if (c, s) in cells and cells[(c, s)]["mean"] < best_classical(s)]
        led = [c for c in learned if (c, own) in cells and cells[(c, own)]["mean"] < best_classical(own)]
        gained = [c for c in kept if c not in led]
        if gained:
            text += f" Learned, ahead of every classical baseline here but not on {own}: {', '.join(gained)}."
        if led:
            lost = [c for c in led if c not in kept]
            text += (
                f" Learned, ahead of every classical baseline on {own}: "
                + (f"keep the lead {', '.join(kept)}; " if kept else "")
                + (f"lose it {', '.join(lost)}." if lost else "all keep it.")
            )
        broken = [
            c
            for c in ran
            if (c, s) in cells
            and (c, own) in cells
            and cells[(c, s)]["mean"] > DEGRADED * cells[(c, own)]["mean"]
        ]
        text += (
            f" Breaks (> {DEGRADED}x its value on {own}): {', '.join(broken)}."
            if broken
            else " No one breaks."
        )
        lines.append(text)
    return lines


def _fmt_shift(axis: str, s: float) -> str:
    return "set" if math.isnan(s) else f"{s:.3g}"


def plot(table: list[dict[str, Any]], scenario: str, path: Path) -> None:
    """Robustness curves: main metric and score against each axis's shift, with 95 % intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = [a for a in AXES if any(r["axis"] == a.key for r in table)]
    fig, ax = plt.subplots(2, len(axes), figsize=(3.2 * len(axes), 6), squeeze=False)
    names = sorted({r["controller"] for r in table if r["controller"] != ZERO})
    for j, a in enumerate(axes):
        for name in names:
            rs = sorted(
                (r for r in table if r["controller"] == name and r["axis"] == a.key), key=lambda r: r["shift"]
            )
            x = [r["shift"] for r in rs]
            for i, (k, lo, hi) in enumerate(
                (("mean", "ci_low", "ci_high"), ("score", "score_ci_low", "score_ci_high"))
            ):
                line = ax[i, j].plot(x, [r[k] for r in rs], "o-", ms=3, label=name)[0]
                ax[i, j].fill_between(
                    x, [r[lo] for r in rs], [r[hi] for r in rs], alpha=0.2, color=line.get_color()
                )
        ax[0, j].set(title=a.label, yscale="log")
        ax[1, j].set(xlabel=a.key)
    ax[0, 0].set_ylabel(table[0]["metric"])
    ax[1, 0].set_ylabel("score (1 - m/m_Zero)")
    ax[0, -1].legend(fontsize=6)
    fig.suptitle(f"sim-to-real: {scenario}")
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=90, format="png"))
    plt.close(fig)


def plot_structures(table: list[dict[str, Any]], scenario: str, path: Path) -> None:
    """The main metric (95 % intervals) of each controller on each friction structure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in table if r["axis"] == "friction_model" and r["controller"] != ZERO]
    structures = [s for s in STRUCTURES if any(r["shift"] == s for r in rows)]
    names = sorted({r["controller"] for r in rows})
    fig, ax = plt.subplots(figsize=(1.4 * len(structures) + 5, 3.8))
    w = 0.8 / max(len(names), 1)
    for k, name in enumerate(names):
        rs = [
            next((r for r in rows if r["controller"] == name and r["shift"] == s), None) for s in structures
        ]
        mean = [r["mean"] if r else np.nan for r in rs]
        err = [
            [r["mean"] - r["ci_low"] if r else 0 for r in rs],
            [r["ci_high"] - r["mean"] if r else 0 for r in rs],
        ]
        ax.bar(
            np.arange(len(structures)) + (k - (len(names) - 1) / 2) * w,
            mean,
            w,
            yerr=err,
            capsize=2,
            label=name,
            color=plt.cm.tab20(k % 20),
        )
    ax.set_xticks(np.arange(len(structures)), structures)
    ax.set(yscale="log", ylabel=rows[0]["metric"] if rows else "", title=f"friction structures: {scenario}")
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=90, format="png"))
    plt.close(fig)


# ------------------------------------------------------------------------------------------- model error
MODEL_ERROR_SEEDS = SEEDS + SET_SPAN  # "true" plants of the closing-the-loop study (a randomised draw each)
DESIGNS = ("nominal", "identified", "true")


def model_error(
    scenario: str, controllers: list[str], draws: int = 10, progress: bool = True
) -> list[dict[str, Any]]:
    """Closing the identification loop. For each randomised "true" plant (the scenario's draw of seed
    MODEL_ERROR_SEEDS + i), run the LuGre identification experiments on it (noise and quantisation on),
    then run each controller on that same episode designed on three models: the nominal preset, the
    identified plant (nominal preset + identified friction) and the true plant. Rows: controller, design,
    seed, main metric."""

    if draws > SET_SPAN:
        raise ValueError(f"--model-error at most {SET_SPAN} (the study's seed sets, configs/suites.yaml)")
    envs = EnvCache()
    rows = []
    for i in tqdm(range(draws), desc="model error", unit="plant", disable=not progress):
        seed = MODEL_ERROR_SEEDS + i
        episode = Episode(scenario, seed, True)
        sc = envs.scenario(episode)
        p = ex.protocol(sc.spec)
        rig = ex.Rig.of(sc.spec, seed, True)
        fid = identify_simulated(ex.run_all(rig, p, ("holds", "breakaway", "presliding")), p)
        values = {k: v for k, v in fid.values().items() if k not in fid.unidentified}
        # the scenario's plant with the identified friction (the friction_identified mechanism), checked as
        # a plant's parameters are; a design model, so the randomisation ranges are not re-checked
        identified = apply_identified(sc.spec, IdentifiedFriction.from_values(values))
        EpisodeParams.nominal(identified).validate(identified)
        true = spec_with(sc.spec, EpisodeParams.draw(sc.spec, seed))
        for name in controllers:
            c = registry.make(name)
            if not c.applies_to(sc):
                continue
            for design, spec in zip(DESIGNS, (sc.spec, identified, true), strict=True):
                r = run_episode(c, episode, envs=envs, design=spec)
                rows.append(
                    {"controller": name, "design": design, "seed": seed, "main": r.metrics[sc.main_metric]}
                )
    return rows


def model_error_table(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per controller and design: the mean main metric with 95 % CI; for `identified` and `nominal`, the
    paired loss against the true-parameter design (positive = worse)."""
    by = defaultdict(dict)
    for r in rows:
        by[(r["controller"], r["design"])][r["seed"]] = r["main"]
    out = []
    for (name, design), vals in sorted(by.items()):
        m = stats.mean_ci(list(vals.values()))
        row = {"controller": name, "design": design, "mean": m[0], "ci_low": m[1], "ci_high": m[2]}
        true = by.get((name, "true"), {})
        if design != "true" and true:
            seeds = sorted(set(vals) & set(true))
            d = stats.paired([vals[s] for s in seeds], [true[s] for s in seeds])
            row |= {"loss": d["diff"], "loss_low": d["diff_lo"], "loss_high": d["diff_hi"]}
        out.append(row)
    return out


def plot_model_error(table: list[dict[str, Any]], metric: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({r["controller"] for r in table})
    fig, ax = plt.subplots(figsize=(1.6 * len(names) + 2, 3.6))
    w = 0.27
    for k, design in enumerate(DESIGNS):
        rs = [next((r for r in table if r["controller"] == n and r["design"] == design), None) for n in names]
        x = np.arange(len(names)) + (k - 1) * w
        mean = [r["mean"] if r else np.nan for r in rs]
        err = [
            [r["mean"] - r["ci_low"] if r else 0 for r in rs],
            [r["ci_high"] - r["mean"] if r else 0 for r in rs],
        ]
        ax.bar(x, mean, w, yerr=err, label=f"designed on the {design} model", capsize=2)
    ax.set_xticks(np.arange(len(names)), names, fontsize=8)
    ax.set(ylabel=metric, title="performance lost to model error (evaluated on the true plants)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=90, format="png"))
    plt.close(fig)


def model_error_markdown(table: list[dict[str, Any]], metric: str, draws: int) -> str:
    lines = [
        "## Closing the identification loop: performance lost to model error",
        "",
        f"{draws} randomised true plants (seeds {MODEL_ERROR_SEEDS}+); on each, the LuGre identification "
        "experiments (scripts/identify.py lugre), then every controller on that plant's episode designed on "
        "the nominal preset, on the identified model and on the true parameters. Loss = per-plant difference "
        f"of {metric} against the true-parameter design (positive = worse), 95 % interval.",
        "",
        f"| controller | design | {metric} | loss vs true design |",
        "|---|---|---|---|",
    ]
    for r in table:
        loss = (
            f"{r['loss']:+.4g} [{r['loss_low']:.3g}, {r['loss_high']:.3g}]" if "loss" in r else "(reference)"
        )
        lines.append(
            f"| {r['controller']} | {r['design']} | {r['mean']:.4g} [{r['ci_low']:.3g}, "
            f"{r['ci_high']:.3g}] | {loss} |"
        )
    return "\n".join([*lines, "", "![model error](model_error.png)", ""])


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

    available = registry.available(models)
    names = controllers or list(available)
    names = [ZERO, *(n for n in names if n != ZERO)]
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
    atomic_text(out / "sim2real.csv", csv_text(table))
    plot(table, scenario, out / "sim2real.png")
    if structures:
        plot_structures(table, scenario, out / "sim2real_structures.png")
    ran = [n for n in names if n != ZERO and any(r["controller"] == n for r in table)]
    sc = load_scenario(scenario)
    own = sc.spec.friction_model
    joint_rows = [r for r in table if r["axis"].startswith("joint") and r["controller"] != ZERO]
    md = [
        f"# Sim-to-real study: {scenario}",
        "",
        f"Main metric: {sc.main_metric} (lower is better); score = 1 - m / m_Zero. {seeds} episodes per "
        f"shift (seeds {SEEDS}+), {joint} joint draws per set; rejected joint draws (the plant's checks): "
        f"{rejected}. Skipped: {sorted({(n, why) for n, _, why in skipped}) or 'none'}.",
        "",
        "## Where each controller keeps its lead, and where it breaks",
        "",
        *findings(table, ran),
        "",
        f"## Friction structures (designed and trained on {own})",
        "",
        *structure_findings(table, ran, own),
        "",
        "![friction structures](sim2real_structures.png)",
        "",
        "## Joint shifts",
        "",
        "| controller | set | main metric | score |",
        "|---|---|---|---|",
        *[
            f"| {r['controller']} | {r['axis'][6:]} | {r['mean']:.4g} [{r['ci_low']:.3g}, "
            f"{r['ci_high']:.3g}] | {r['score']:.3f} [{r['score_ci_low']:.3f}, {r['score_ci_high']:.3f}] |"
            for r in sorted(joint_rows, key=lambda r: (r["axis"], r["mean"]))
        ],
        "",
        "![robustness curves](sim2real.png)",
        "",
    ]
    if model_error_draws:
        classical = [n for n in names if n in registry.BUILTIN and n != ZERO]
        me = model_error_table(model_error(scenario, classical, model_error_draws, progress))
        fields = ["controller", "design", "mean", "ci_low", "ci_high", "loss", "loss_low", "loss_high"]
        atomic_text(out / "model_error.csv", csv_text(me, fields))
        plot_model_error(me, sc.main_metric, out / "model_error.png")
        md.append(model_error_markdown(me, sc.main_metric, model_error_draws))
    text = "\n".join(md) + "\n"
    atomic_text(out / "sim2real.md", text)
    return table, text
