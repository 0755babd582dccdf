"""Leaderboard: every applicable controller, and the Zero reference, on the identical episodes of a suite.

Per scenario: its main metric (declared in the scenario's YAML, lower is better) with a 95 % bootstrap
interval, the normalised score s = 1 - m / m_Zero per episode, the secondary metrics, and a paired
comparison of every controller against the scenario's best classical baseline on the same episodes (mean
difference, its 95 % interval, probability of improvement). Across scenarios: the IQM of the normalised
scores with stratified-bootstrap intervals, and a performance profile (agents/stats.py).
"""

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
from frictiongym.envs.records import atomic_text, atomic_write
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.suites import Episode, load_suite

from . import engine, registry, stats
from .evaluate import EnvCache, EpisodeResult, run_episode

REFERENCE = "Zero"
TAUS = np.linspace(-1.0, 1.0, 201)  # performance-profile thresholds of the normalised score


def classical(name: str) -> bool:
    """Built-in baselines (not the Zero reference, not plug-ins or trained models)."""
    return name in registry.BUILTIN and name != REFERENCE


def per_seed(rs: list[EpisodeResult], metric: str) -> dict[int, float]:
    """{seed: metric} of one controller's episodes on one scenario."""
    return {r.seed: r.metrics[metric] for r in rs}


def summarize(results: list[EpisodeResult], scenarios: dict[str, Scenario]) -> dict[str, list[dict]]:
    """Per scenario, one row per controller, sorted by the mean main metric (see the module docstring)."""
    groups: dict[str, dict[str, list[EpisodeResult]]] = defaultdict(dict)
    for r in results:
        groups[r.scenario].setdefault(r.controller, []).append(r)
    table = {}
    for sc, by_ctrl in groups.items():
        main = scenarios[sc].main_metric
        rows = []
        for name, rs in by_ctrl.items():
            rows.append(
                {
                    "controller": name,
                    "episodes": len(rs),
                    "diverged": sum(r.diverged for r in rs),
                    "main": stats.mean_ci([r.metrics[main] for r in rs]),
                    "score": stats.mean_ci([r.score for r in rs]),
                    "metrics": {m: stats.mean_ci([r.metrics[m] for r in rs]) for m in METRIC_NAMES},
                }
            )
        rows.sort(key=lambda r: r["main"][0] if math.isfinite(r["main"][0]) else math.inf)
        best = next((r["controller"] for r in rows if classical(r["controller"])), None)
        for r in rows:
            r["baseline"] = best
            r["vs_baseline"] = None
            if best is not None and r["controller"] != best:
                mine, theirs = per_seed(by_ctrl[r["controller"]], main), per_seed(by_ctrl[best], main)
                seeds = sorted(set(mine) & set(theirs))
                r["vs_baseline"] = stats.paired([mine[s] for s in seeds], [theirs[s] for s in seeds])
        table[sc] = rows
    return table


MAX_EFFORT_RATIO = 1.2  # a learned compensator may spend at most this times the baseline's effort_rms


def verdicts(table: dict[str, list[dict]], scenarios: dict[str, Scenario]) -> list[dict]:
    """For each controller that is not a built-in (plug-ins, trained models) on each scenario: does it beat
    the scenario's best classical baseline? It must (1) lower the main metric with a paired 95 % interval
    of the per-episode difference below 0, (2) spend at most MAX_EFFORT_RATIO times the baseline's
    effort_rms, and (3) add no limit cycle: its limit_cycle_amp at most 1.2x the baseline's plus the
    scenario's settling band. A compensator that fails (2) or (3) chatters: it is not a result."""
    out = []
    for sc, rows in table.items():
        base = next((r for r in rows if r["controller"] == r["baseline"]), None)
        if base is None:
            continue
        band = scenarios[sc].settle_band
        for r in rows:
            if r["controller"] in registry.BUILTIN or r["vs_baseline"] is None:
                continue
            v = r["vs_baseline"]
            effort = r["metrics"]["effort_rms"][0] / base["metrics"]["effort_rms"][0]
            lc, lc_base = r["metrics"]["limit_cycle_amp"][0], base["metrics"]["limit_cycle_amp"][0]
            why = []
            if not v["diff_hi"] < 0:
                why.append("difference interval does not exclude 0" if v["diff_lo"] < 0 else "worse")
            if not effort <= MAX_EFFORT_RATIO:
                why.append(f"effort {effort:.2f}x")
            if not lc <= 1.2 * lc_base + band:
                why.append(f"limit cycle {lc:.3g} vs {lc_base:.3g}")
            out.append(
                {
                    "scenario": sc,
                    "controller": r["controller"],
                    "baseline": base["controller"],
                    "vs_baseline": v,
                    "effort_ratio": effort,
                    "limit_cycle_amp": lc,
                    "baseline_limit_cycle_amp": lc_base,
                    "beats_baseline": not why,
                    "why_not": "; ".join(why),
                }
            )
    return out


def aggregate(results: list[EpisodeResult]) -> list[dict]:
    """Per controller: the IQM of its normalised scores over the scenarios it applies to, with a 95 %
    stratified-bootstrap interval (strata: scenarios), best first."""
    strata: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        strata[r.controller][r.scenario].append(r.score)
    rows = [
        {"controller": c, "scenarios": len(by_sc), "iqm": stats.iqm_ci(list(by_sc.values()))}
        for c, by_sc in strata.items()
    ]
    return sorted(rows, key=lambda r: -r["iqm"][0] if math.isfinite(r["iqm"][0]) else math.inf)


def _fmt(ci: tuple[float, float, float]) -> str:
    m, lo, hi = ci
    return "n/a" if not np.isfinite(m) else f"{m:.4g} [{lo:.3g}, {hi:.3g}]"


def _vs(r: dict) -> str:
    v = r["vs_baseline"]
    if v is None:
        return "(baseline)" if r["controller"] == r["baseline"] else "n/a"
    ci = _fmt((v["diff"], v["diff_lo"], v["diff_hi"]))
    return f"{ci}, P(better) {v['p_improve']:.2f}"


def markdown(
    table: dict[str, list[dict]], agg: list[dict], suite: str, scenarios: dict[str, Scenario]
) -> str:
    lines = [
        f"# frictiongym leaderboard, suite `{suite}`",
        "",
        "Per scenario: mean and 95 % bootstrap interval over the suite's episodes, sorted by the",
        "scenario's main metric (lower is better; units: the tracked output in rad or V, the command in V or",
        "N·m; see docs/envs.md). `score` is the normalised score s = 1 - m / m_Zero on the same episode",
        "(1 perfect, 0 as bad as doing nothing). `vs baseline`: the mean per-episode difference of the main",
        "metric against the scenario's best classical baseline (negative = better), its 95 % interval, and",
        "the probability that the controller beats the baseline on an episode.",
        "",
        "## Across scenarios",
        "",
        "IQM of the normalised score, 95 % stratified-bootstrap interval (over the scenarios each controller "
        "applies to).",
        "",
        "| controller | scenarios | IQM score |",
        "|---|---|---|",
    ]
    lines += [f"| {r['controller']} | {r['scenarios']} | {_fmt(r['iqm'])} |" for r in agg]
    judged = verdicts(table, scenarios)
    if judged:
        lines += [
            "",
            "## Learned and plug-in controllers against the best classical baseline",
            "",
            "Beats the baseline = lower main metric with the paired 95 % interval of the per-episode "
            f"difference below 0, effort_rms at most {MAX_EFFORT_RATIO}x the baseline's, and no new "
            "limit cycle (limit_cycle_amp at most 1.2x the baseline's plus the settling band).",
            "",
            "| scenario | controller | baseline | difference of the main metric | effort ratio | limit cycle "
            "(vs baseline) | beats the baseline |",
            "|---|---|---|---|---|---|---|",
        ]
        for j in judged:
            v = j["vs_baseline"]
            lines.append(
                f"| {j['scenario']} | {j['controller']} | {j['baseline']} | "
                f"{_fmt((v['diff'], v['diff_lo'], v['diff_hi']))} | {j['effort_ratio']:.2f} | "
                f"{j['limit_cycle_amp']:.3g} ({j['baseline_limit_cycle_amp']:.3g}) | "
                + ("yes" if j["beats_baseline"] else f"no: {j['why_not']}")
                + " |"
            )
    for sc, rows in table.items():
        s = scenarios[sc]
        sec = list(s.secondary_metrics)
        lines += [
            "",
            f"## {sc}",
            "",
            f"Why: {s.why}",
            "",
            f"| controller | episodes | {s.main_metric} (main) | score | "
            + " | ".join(sec)
            + " | vs baseline |",
            "|---|---|---|---|" + "---|" * len(sec) + "---|",
        ]
        for r in rows:
            div = f" ({r['diverged']} diverged)" if r["diverged"] else ""
            lines.append(
                f"| {r['controller']} | {r['episodes']}{div} | {_fmt(r['main'])} | {_fmt(r['score'])} | "
                + " | ".join(_fmt(r["metrics"][m]) for m in sec)
                + f" | {_vs(r)} |"
            )
    return "\n".join(lines) + "\n"


def write_table_csv(table: dict[str, list[dict]], scenarios: dict[str, Scenario], path: Path) -> None:
    """The tables: one row per (scenario, controller): main metric and score (mean, lo, hi), the paired
    comparison against the baseline, and every metric (mean, lo, hi)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            *("scenario", "controller", "episodes", "diverged", "main_metric", "main_mean", "main_lo"),
            *("main_hi", "score_mean", "score_lo", "score_hi", "baseline", "diff_mean", "diff_lo"),
            *("diff_hi", "p_improve"),
            *(f"{m}_{k}" for m in METRIC_NAMES for k in ("mean", "lo", "hi")),
        ]
    )
    for sc, rows in table.items():
        for r in rows:
            v = r["vs_baseline"] or {}
            w.writerow(
                [sc, r["controller"], r["episodes"], r["diverged"], scenarios[sc].main_metric]
                + [repr(x) for x in (*r["main"], *r["score"])]
                + [r["baseline"]]
                + [repr(v.get(k, math.nan)) for k in ("diff", "diff_lo", "diff_hi", "p_improve")]
                + [repr(x) for m in METRIC_NAMES for x in r["metrics"][m]]
            )
    atomic_text(path, buf.getvalue())


def _save_png(fig, path: Path) -> str:
    """Save a figure atomically (temporary file, then rename) and close it; returns the file name."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=110, format="png"))
    plt.close(fig)
    return path.name


def plots(
    results: list[EpisodeResult],
    table: dict[str, list[dict]],
    agg: list[dict],
    out: Path,
    scenarios: dict[str, Scenario],
    randomize: dict[str, bool],
    models: tuple[str, ...] = (),
) -> list[str]:
    """Normalised scores per scenario (strip plots), the aggregate IQM with intervals, the performance
    profile, and per scenario the time responses of its best and worst episodes (by the main metric)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ctrls = [r["controller"] for r in agg]
    colour = {c: f"C{i % 10}" for i, c in enumerate(ctrls)}
    names = []
    scs = list(table)
    fig, axes = plt.subplots(1, len(scs), figsize=(3.2 * len(scs), 3.8), squeeze=False)
    for ax, sc in zip(axes[0], scs, strict=True):
        order = [r["controller"] for r in table[sc]]
        for i, c in enumerate(order):
            s = np.array([r.score for r in results if r.scenario == sc and r.controller == c])
            jitter = np.random.default_rng(i).uniform(-0.15, 0.15, len(s))
            ax.plot(i + jitter, s, "o", ms=3, alpha=0.6, color=colour[c])
            ax.plot([i - 0.3, i + 0.3], [np.nanmean(s)] * 2, "k-", lw=1.5)
        ax.set_xticks(range(len(order)), order, rotation=45, ha="right", fontsize=7)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_title(sc, fontsize=8)
    axes[0][0].set_ylabel("normalised score 1 - m/m_Zero")
    names.append(_save_png(fig, out / "scores.png"))

    fig, ax = plt.subplots(figsize=(6, 0.4 * len(agg) + 1.2))
    for i, r in enumerate(agg):
        m, lo, hi = r["iqm"]
        ax.errorbar(m, i, xerr=[[m - lo], [hi - m]], fmt="o", color=colour[r["controller"]], capsize=3)
    ax.set_yticks(range(len(agg)), [f"{r['controller']} ({r['scenarios']})" for r in agg])
    ax.invert_yaxis()
    ax.set(xlabel="IQM of the normalised score (95 % stratified bootstrap)", title="Across scenarios")
    names.append(_save_png(fig, out / "aggregate_iqm.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    for c in ctrls:
        ax.plot(TAUS, stats.performance_profile([r.score for r in results if r.controller == c], TAUS),
                label=c, color=colour[c])  # fmt: skip
    ax.set(
        xlabel="normalised score τ", ylabel="fraction of episodes with score > τ", title="Performance profile"
    )
    ax.legend(fontsize=7)
    names.append(_save_png(fig, out / "performance_profile.png"))

    for sc in scs:
        main = scenarios[sc].main_metric
        rs = [r for r in results if r.scenario == sc and math.isfinite(r.metrics[main])]
        if not rs:
            continue
        vals = [r.metrics[main] for r in rs]
        best, worst = with_logs([rs[int(np.argmin(vals))], rs[int(np.argmax(vals))]], randomize[sc], models)
        fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        for r, style in ((best, "-"), (worst, "--")):
            g = r.log
            lab = f"{r.controller} seed {r.seed} ({main} {r.metrics[main]:.3g})"
            ax[0].plot(g["t"], g["output"], style, label=f"output, {'best' if r is best else 'worst'}: {lab}")
            ax[1].step(g["t"], g["command"], style, where="pre")
        ax[0].plot(best.log["t"], best.log["reference"], "k:", label="reference")
        ax[0].set(title=f"{sc}: best and worst episode", ylabel="output")
        ax[0].legend(fontsize=7)
        ax[1].set(xlabel="t (s)", ylabel="command")
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
        score=float(row["score"]),
    )


def with_logs(
    picked: list[EpisodeResult], randomize: bool, models: tuple[str, ...] = ()
) -> list[EpisodeResult]:
    """The same episodes re-run with their time logs (deterministic: the same seeds give the same runs)."""
    envs = EnvCache()
    return [
        run_episode(
            registry.make(r.controller, models), Episode(r.scenario, r.seed, randomize), True, envs=envs
        )
        for r in picked
    ]


def run(
    suite: str = "default",
    controllers: list[str] | None = None,
    out: Path | None = None,
    progress: bool = True,
    workers: int = 1,
    episodes: list[Episode] | None = None,
    models: tuple[str, ...] = (),
    ray: engine.Ray | None = None,
) -> tuple[list[EpisodeResult], dict[str, list[dict]]]:
    """Evaluate (the suite, or the given episodes) with the Zero reference always included, and
    summarize. With out: results go to out/episodes.csv incrementally (a rerun resumes), then
    leaderboard.md, leaderboard.csv (the tables) and PNG plots, each written atomically."""
    models = tuple(str(m) for m in models)
    available = registry.available(models)
    names = controllers or list(available)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(f"unknown controllers {unknown}; available: {list(available)}")
    names = [REFERENCE, *(n for n in names if n != REFERENCE)]
    episodes = episodes if episodes is not None else load_suite(suite)
    if out is None:
        jobs, skipped = engine.plan(names, episodes, models)
        rows: list[dict[str, Any]] = []
        engine.run_jobs(jobs, workers, rows.extend, progress, models, ray)
        rows = engine.canonical(rows, jobs, engine.main_metrics(episodes))
    else:
        options = {"episodes": [asdict(e) for e in episodes], "controllers": names, "models": list(models)}
        rows, skipped = engine.evaluate_to(out, names, episodes, options, workers, progress, models, ray)
    for name, scenario, reason in skipped:
        if progress:
            print(f"skipped {name} on {scenario}: {reason}")
    results = [result_of(r) for r in rows]
    scenarios = {name: load_scenario(name) for name in {e.scenario for e in episodes}}
    table, agg = summarize(results, scenarios), aggregate(results)
    if out is not None:
        write_table_csv(table, scenarios, out / "leaderboard.csv")
        figs = plots(results, table, agg, out, scenarios, {e.scenario: e.randomize for e in episodes}, models)
        md = markdown(table, agg, suite, scenarios)
        atomic_text(out / "leaderboard.md", md + "\n" + "".join(f"![{f}]({f})\n" for f in figs))
    return results, table
