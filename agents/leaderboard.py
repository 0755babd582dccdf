"""Leaderboard: every applicable controller on the identical episodes of a suite; per-scenario tables of
mean and 95 % bootstrap intervals of the main metrics; CSV, markdown and PNG plots."""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.suites import Episode, load_suite

from . import engine, registry
from .evaluate import EnvCache, EpisodeResult, run_episode

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


def _atomic_text(path: Path, text: str) -> None:
    """Write a whole text file atomically (temporary file, then rename): never a half-written file."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)


def write_table_csv(table: dict[str, list[dict]], path: Path) -> None:
    """The tables: one row per (scenario, controller), mean and 95 % interval of each main metric."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["scenario", "controller", "episodes", "diverged"]
        + [f"{m}_{k}" for m in MAIN_METRICS for k in ("mean", "lo", "hi")]
    )
    for sc, rows in table.items():
        for r in rows:
            w.writerow(
                [
                    sc,
                    r["controller"],
                    r["episodes"],
                    r["diverged"],
                    *(repr(v) for m in MAIN_METRICS for v in r[m]),
                ]
            )
    _atomic_text(path, buf.getvalue())


def _save_png(fig, path: Path) -> str:
    """Save a figure atomically (temporary file, then rename) and close it; returns the file name."""
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.name}.tmp")
    fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    tmp.replace(path)
    return path.name


def plots(
    results: list[EpisodeResult], table: dict[str, list[dict]], out: Path, randomize: dict[str, bool]
) -> list[str]:
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
        names.append(_save_png(fig, out / f"bar_{m}.png"))
    for sc in scenarios:
        rs = [r for r in results if r.scenario == sc]
        iae = [r.metrics["iae"] for r in rs]
        best, worst = with_logs([rs[int(np.nanargmin(iae))], rs[int(np.nanargmax(iae))]], randomize[sc])
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
        names.append(_save_png(fig, out / f"response_{sc}.png"))
    return names


def result_of(row: dict[str, Any]) -> EpisodeResult:
    """An EpisodeResult from an engine row (native values, or the strings read back from episodes.csv)."""
    return EpisodeResult(
        controller=str(row["controller"]),
        scenario=str(row["scenario"]),
        seed=int(row["seed"]),
        metrics={m: float(row[m]) for m in METRIC_NAMES},
        episode_return=float(row["return"]),
        diverged=row["diverged"] in (True, "True"),
    )


def with_logs(picked: list[EpisodeResult], randomize: bool) -> list[EpisodeResult]:
    """The same episodes re-run with their time logs (deterministic: the same seeds give the same runs)."""
    envs = EnvCache()
    return [
        run_episode(registry.make(r.controller), Episode(r.scenario, r.seed, randomize), True, envs=envs)
        for r in picked
    ]


def run(
    suite: str = "default",
    controllers: list[str] | None = None,
    out: Path | None = None,
    progress: bool = True,
    workers: int = 1,
    episodes: list[Episode] | None = None,
) -> tuple[list[EpisodeResult], dict[str, list[dict]]]:
    """Evaluate (the suite, or the given episodes) and summarize. With out: results go to out/episodes.csv
    incrementally (a rerun resumes), then leaderboard.md, leaderboard.csv (the tables) and PNG plots."""
    available = registry.available()
    names = controllers or list(available)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(f"unknown controllers {unknown}; available: {list(available)}")
    episodes = episodes if episodes is not None else load_suite(suite)
    if out is None:
        jobs, skipped = engine.plan(names, episodes)
        rows: list[dict[str, Any]] = []
        engine.run_jobs(jobs, workers, rows.extend, progress)
        rank = {j.key(): i for i, j in enumerate(jobs)}
        rows.sort(key=lambda r: rank[(r["controller"], r["scenario"], str(r["seed"]), str(r["randomize"]))])
    else:
        options = {"episodes": [asdict(e) for e in episodes], "controllers": names}
        rows, skipped = engine.evaluate_to(out, names, episodes, options, workers, progress)
    for name, scenario, reason in skipped:
        if progress:
            print(f"skipped {name} on {scenario}: {reason}")
    results = [result_of(r) for r in rows]
    table = summarize(results)
    if out is not None:
        write_table_csv(table, out / "leaderboard.csv")
        figs = plots(results, table, out, randomize={e.scenario: e.randomize for e in episodes})
        _atomic_text(
            out / "leaderboard.md", markdown(table, suite) + "\n" + "".join(f"![{f}]({f})\n" for f in figs)
        )
    return results, table
