"""Leaderboard: every applicable controller on the identical episodes of a suite; per-scenario tables of
mean and 95 % bootstrap intervals of the main metrics; CSV, markdown and PNG plots."""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from frictiongym.envs.suites import load_suite

from .base import Controller
from .classical import PD, PID, RDFC, CoulombViscousFF, LuGreObserver, Southward, StateFeedback
from .evaluate import EpisodeResult, evaluate

CONTROLLERS: dict[str, Callable[[], Controller]] = {
    "PD": PD,
    "PID": PID,
    "Southward": Southward,
    "RDFC": RDFC,
    "SF": StateFeedback,
    "SF+relay": partial(StateFeedback, "relay"),
    "SF+highgain": partial(StateFeedback, "highgain"),
    "LuGreObserver": LuGreObserver,
    "CoulombViscousFF": CoulombViscousFF,
}
MAIN_METRICS = ("iae", "final_error", "limit_cycle_amp", "reversal_peak_error", "effort_rms")
N_BOOT = 2000


def bootstrap_ci(x: np.ndarray, seed: int = 0) -> tuple[float, float, float]:
    """Mean and 95 % percentile bootstrap interval of the finite values (fixed seed: reproducible)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return (math.nan,) * 3
    if len(x) == 1:
        return float(x[0]), float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    means = rng.choice(x, size=(N_BOOT, len(x))).mean(axis=1)
    return float(x.mean()), float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def summarize(results: list[EpisodeResult]) -> dict[str, list[dict]]:
    """Per scenario: one row per controller with (mean, lo, hi) per main metric, sorted by mean IAE."""
    groups: dict[str, dict[str, list[EpisodeResult]]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        groups[r.scenario][r.controller].append(r)
    table = {}
    for sc, by_ctrl in groups.items():
        rows = []
        for name, rs in by_ctrl.items():
            row = {"controller": name, "episodes": len(rs), "diverged": sum(r.diverged for r in rs)}
            for m in MAIN_METRICS:
                row[m] = bootstrap_ci(np.array([r.metrics[m] for r in rs]))
            rows.append(row)
        table[sc] = sorted(rows, key=lambda r: r["iae"][0] if np.isfinite(r["iae"][0]) else math.inf)
    return table


def _fmt(ci: tuple[float, float, float]) -> str:
    m, lo, hi = ci
    return "n/a" if not np.isfinite(m) else f"{m:.4g} [{lo:.3g}, {hi:.3g}]"


def markdown(table: dict[str, list[dict]], suite: str) -> str:
    lines = [
        f"# frictiongym leaderboard, suite `{suite}`",
        "",
        "Mean and 95 % bootstrap interval over the suite's episodes; sorted by IAE. Units: the scenario's "
        "tracked output (rad or V) and command (V or N·m); see docs/envs.md for the metric definitions.",
        "",
    ]
    for sc, rows in table.items():
        lines += [
            f"## {sc}",
            "",
            "| controller | episodes | " + " | ".join(MAIN_METRICS) + " |",
            "|---|---|" + "---|" * len(MAIN_METRICS),
        ]
        for r in rows:
            div = f" ({r['diverged']} diverged)" if r["diverged"] else ""
            lines.append(
                f"| {r['controller']} | {r['episodes']}{div} | "
                + " | ".join(_fmt(r[m]) for m in MAIN_METRICS)
                + " |"
            )
        lines.append("")
    return "\n".join(lines)


def write_csv(results: list[EpisodeResult], path: Path) -> None:
    rows = [r.row() for r in results]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def plots(results: list[EpisodeResult], table: dict[str, list[dict]], out: Path) -> list[str]:
    """A bar chart per metric (controllers per scenario, 95 % intervals) and, per scenario, the time
    responses of its best and worst episodes (by IAE)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    scenarios = list(table)
    ctrls = sorted({r["controller"] for rows in table.values() for r in rows})
    width = 0.8 / max(1, len(ctrls))
    for m in MAIN_METRICS:
        fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(scenarios)), 4))
        for k, c in enumerate(ctrls):
            for i, sc in enumerate(scenarios):
                row = next((r for r in table[sc] if r["controller"] == c), None)
                if row is None or not np.isfinite(row[m][0]):
                    continue
                mean, lo, hi = row[m]
                ax.bar(
                    i + k * width,
                    mean,
                    width,
                    yerr=[[mean - lo], [hi - mean]],
                    capsize=2,
                    color=f"C{k}",
                    label=c if i == 0 or c not in ax.get_legend_handles_labels()[1] else None,
                )
        ax.set_xticks(np.arange(len(scenarios)) + 0.4 - width / 2, scenarios, rotation=20, ha="right")
        ax.set(ylabel=m, title=f"{m} (mean, 95 % bootstrap interval)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / f"bar_{m}.png", dpi=110)
        plt.close(fig)
        names.append(f"bar_{m}.png")
    for sc in scenarios:
        rs = [r for r in results if r.scenario == sc and r.log is not None]
        if not rs:
            continue
        iae = [r.metrics["iae"] for r in rs]
        best, worst = rs[int(np.nanargmin(iae))], rs[int(np.nanargmax(iae))]
        fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        for r, style in ((best, "-"), (worst, "--")):
            g = r.log
            lab = f"{r.controller} seed {r.seed} (IAE {r.metrics['iae']:.3g})"
            ax[0].plot(g["t"], g["output"], style, label=f"output, {'best' if r is best else 'worst'}: {lab}")
            ax[1].step(g["t"], g["command"], style, where="pre")
        ax[0].plot(best.log["t"], best.log["reference"], "k:", label="reference")
        ax[0].set(title=f"{sc}: best and worst episode", ylabel="output")
        ax[0].legend(fontsize=7)
        ax[1].set(xlabel="t (s)", ylabel="command")
        fig.tight_layout()
        fig.savefig(out / f"response_{sc}.png", dpi=110)
        plt.close(fig)
        names.append(f"response_{sc}.png")
    return names


def run(
    suite: str = "default",
    controllers: list[str] | None = None,
    out: Path | None = None,
    progress: bool = True,
) -> tuple[list[EpisodeResult], dict[str, list[dict]]]:
    """Evaluate, summarize, and (with out) write leaderboard.md, leaderboard.csv and PNG plots."""
    names = controllers or list(CONTROLLERS)
    unknown = [n for n in names if n not in CONTROLLERS]
    if unknown:
        raise ValueError(f"unknown controllers {unknown}; available: {list(CONTROLLERS)}")
    results = evaluate(
        [CONTROLLERS[n]() for n in names], load_suite(suite), keep_logs=out is not None, progress=progress
    )
    table = summarize(results)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        write_csv(results, out / "leaderboard.csv")
        figs = plots(results, table, out)
        (out / "leaderboard.md").write_text(
            markdown(table, suite) + "\n" + "\n".join(f"![{f}]({f})" for f in figs) + "\n"
        )
    return results, table
