"""The sim-to-real study's report: its computed tables (agents/sim2real/study.py) rendered as sim2real.md's
text and its figures. Rendering only: nothing here evaluates or writes a file (sim2real.run computes,
renders with this module, then writes)."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

from frictiongym.agents.evaluation.report import palette
from frictiongym.envs.records import pyplot

from .. import registry
from ..base import ZERO
from .study import AXES, DEGRADED, DESIGNS, MODEL_ERROR_SEEDS, SEEDS, STRUCTURES


@dataclass(frozen=True)
class Study:
    """What a finished study reports: the summary table (study.summarize) and what it ran."""

    scenario: str
    metric: str  # the scenario's main metric
    own: str  # the scenario's friction structure (what the controllers were designed and trained on)
    table: list[dict[str, Any]]
    ran: list[str]  # controllers that ran, Zero aside
    seeds: int  # episodes per shift value
    joint: int  # joint-shift draws per set
    rejected: dict[str, int]  # joint draws the plant's checks rejected, per set
    skipped: list[tuple[str, str, str]]  # (controller, scenario, reason)
    structures_left_out: dict[str, str]  # friction structure -> why the scenario cannot be built with it


def markdown(study: Study, model_error: str | None = None) -> str:
    """sim2real.md's text; `model_error`: the closing-the-loop section (model_error_markdown), last."""
    table, scenario, own, ran = study.table, study.scenario, study.own, study.ran
    seeds, joint, rejected, skipped = study.seeds, study.joint, study.rejected, study.skipped
    joint_rows = [r for r in table if r["axis"].startswith("joint") and r["controller"] != ZERO]
    md = [
        f"# Sim-to-real study: {scenario}",
        "",
        f"Main metric: {study.metric} (lower is better); score = 1 - m / m_Zero. {seeds} episodes per "
        f"shift (seeds {SEEDS}+), {joint} joint draws per set; rejected joint draws (the plant's checks): "
        f"{rejected}. Skipped: {sorted({(n, why) for n, _, why in skipped}) or 'none'}."
        + "".join(f" Structure {k} left out: {why}." for k, why in study.structures_left_out.items()),
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
    if model_error is not None:
        md.append(model_error)
    return "\n".join(md) + "\n"


def _roles(controllers: list[str]) -> tuple[list[str], list[str]]:
    """(classical, learned) among controllers: the built-in loops and the rest, the reference rows
    (registry.LIMITS: Ideal, Oracle) in neither."""
    classical = [c for c in controllers if c in registry.BUILTIN]
    learned = [c for c in controllers if c not in registry.BUILTIN and c not in registry.LIMITS]
    return classical, learned


def findings(table: list[dict[str, Any]], controllers: list[str]) -> list[str]:
    """Markdown bullets computed from the table, per axis: the best controller at each shift, where each
    learned (non built-in) controller loses to the best classical baseline (its lead lost), and where any
    controller breaks (main metric above DEGRADED x its own nominal-plant value)."""
    by: dict[str, dict[tuple[str, float], dict[str, Any]]] = defaultdict(dict)
    for r in table:
        by[r["axis"]][(r["controller"], r["shift"])] = r
    classical, learned = _roles(controllers)
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
            here = [
                (cells[(c, s)]["mean"], c)
                for c in controllers
                if (c, s) in cells and c not in registry.LIMITS
            ]
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
            f"- **{axis}**: best by mean (the reference rows Ideal, Oracle aside) {'; '.join(leaders)}."
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
    classical, learned = _roles(ran)

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


def robustness_figure(table: list[dict[str, Any]], scenario: str) -> Any:
    """Robustness curves: the main metric (mean and 95 % interval over the episodes) of each controller
    against each axis's shift, one panel per axis in a grid, a distinct colour per controller (the
    leaderboard's palette), the nominal plant marked. The main metric is the headline here: every shifted
    plant is scored on it, and the old score 1 - m/m_Zero cannot separate the entries."""
    plt = pyplot()

    axes = [a for a in AXES if any(r["axis"] == a.key for r in table)]
    names = sorted({r["controller"] for r in table if r["controller"] != ZERO})
    colours = palette(names)
    cols = min(4, len(axes))
    rows = -(-len(axes) // cols)
    fig, ax = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.0 * rows + 0.8), squeeze=False)
    for j, a in enumerate(axes):
        panel = ax.flat[j]
        for name in names:
            rs = sorted(
                (r for r in table if r["controller"] == name and r["axis"] == a.key), key=lambda r: r["shift"]
            )
            x = [r["shift"] for r in rs]
            panel.plot(x, [r["mean"] for r in rs], "o-", ms=3, color=colours[name], label=name)
            lo, hi = [r["ci_low"] for r in rs], [r["ci_high"] for r in rs]
            panel.fill_between(x, lo, hi, alpha=0.18, color=colours[name])
        if a.nominal is not None:
            panel.axvline(a.nominal, color="0.6", lw=0.8, ls=":")
        panel.set(title=a.label, xlabel=a.key, yscale="log")
        if j % cols == 0:
            panel.set_ylabel(table[0]["metric"])
    for panel in ax.flat[len(axes):]:
        panel.axis("off")
    handles, labels = ax.flat[0].get_legend_handles_labels()
    fig.suptitle(f"sim-to-real: {scenario} (dotted: the nominal plant)")
    if len(axes) < ax.size:  # the legend in the free panel
        ax.flat[-1].legend(handles, labels, loc="center", fontsize=8, frameon=False)
        fig.tight_layout(rect=(0, 0, 1, 0.96))
    else:
        fig.legend(handles, labels, loc="lower center", ncol=min(5, len(labels)), fontsize=8, frameon=False)
        fig.tight_layout(rect=(0, 0.05 * (1 + len(labels) // 5) / rows, 1, 0.96))
    return fig


def structures_figure(table: list[dict[str, Any]], scenario: str) -> Any:
    """The main metric (95 % intervals) of each controller on each friction structure."""
    plt = pyplot()

    rows = [r for r in table if r["axis"] == "friction_model" and r["controller"] != ZERO]
    structures = [s for s in STRUCTURES if any(r["shift"] == s for r in rows)]
    names = sorted({r["controller"] for r in rows})
    colours = palette(names)
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
            color=colours[name],
        )
    ax.set_xticks(np.arange(len(structures)), structures)
    ax.set(yscale="log", ylabel=rows[0]["metric"] if rows else "", title=f"friction structures: {scenario}")
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def model_error_figure(table: list[dict[str, Any]], metric: str) -> Any:
    """The main metric of each controller designed on the nominal, identified and true model."""
    plt = pyplot()

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
    return fig


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
