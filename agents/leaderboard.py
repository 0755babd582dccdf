"""Leaderboard: every applicable controller, and the reference rows, on the identical episodes of a suite.

Reference rows, run on every episode and never ranked (agents/limits.py): `Zero` (doing nothing), the
scenario's uncompensated loop (benchmark.uncompensated, also an entry), `Ideal` (that loop on the
friction-free twin of the episode) and `Oracle` (that loop plus the true friction torque).

Per scenario: its main metric (declared in the scenario's YAML, lower is better) with a 95 % bootstrap
interval, g = the friction penalty removed (stats.limit_score: 1 as if friction were gone, 0 no better
than the uncompensated loop), the normalised score s = 1 - m / m_Zero, the secondary metrics, and a
paired comparison of every controller against the scenario's best classical baseline on the same
episodes. Per plant, over equal sets of scenarios only: the IQM of g with stratified-bootstrap
intervals, the probability of improvement between the top entries, performance profiles of g.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from dataclasses import asdict
from pathlib import Path

import numpy as np

from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.records import atomic_text, atomic_write
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.suites import Episode, load_suite

from . import engine, registry, stats
from .base import ZERO
from .evaluate import EnvCache, EpisodeResult, run_episode

REFERENCES = registry.REFERENCES  # Zero, Ideal, Oracle: run on every episode, never ranked
TAUS = np.linspace(-0.5, 1.5, 201)  # performance-profile thresholds of g
TOP = 5  # entries per set in the probability-of-improvement matrix


def classical(name: str) -> bool:
    """Built-in baselines (not the reference rows, not plug-ins or trained models)."""
    return name in registry.BUILTIN and name not in REFERENCES


def entry(name: str) -> bool:
    """A ranked row: anything but the reference rows."""
    return name not in REFERENCES


def per_seed(rs: list[EpisodeResult], metric: str) -> dict[int, float]:
    """{seed: metric} of one controller's episodes on one scenario."""
    return {r.seed: r.metrics[metric] for r in rs}


def summarize(results: list[EpisodeResult], scenarios: dict[str, Scenario]) -> dict[str, list[dict]]:
    """Per scenario, one row per controller (references included and marked), sorted by the mean main
    metric (see the module docstring)."""
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
                    "reference": not entry(name),
                    "uncompensated": name == scenarios[sc].uncompensated,
                    "episodes": len(rs),
                    "diverged": sum(r.diverged for r in rs),
                    "main": stats.mean_ci([r.metrics[main] for r in rs]),
                    "g": stats.mean_ci([r.g for r in rs]),
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


def penalty(results: list[EpisodeResult], scenario: Scenario) -> float:
    """The friction penalty of the scenario's uncompensated loop: the median over episodes of
    (m_unc - m_ideal) / m_unc on the main metric (nan without both rows). It is what decides whether the
    scenario's g is scored (benchmark.limit_score, checked by tests/test_leaderboard.py)."""
    main, loop = scenario.main_metric, scenario.uncompensated
    mine = [r for r in results if r.scenario == scenario.name]
    unc, ideal = (
        per_seed([r for r in mine if r.controller == loop], main),
        per_seed([r for r in mine if r.controller == "Ideal"], main),
    )
    rel = [(unc[s] - ideal[s]) / unc[s] for s in sorted(set(unc) & set(ideal)) if unc[s] > 0]
    return float(np.median(rel)) if rel else math.nan


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
            if not entry(r["controller"]) or r["controller"] in registry.BUILTIN or r["vs_baseline"] is None:
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


def aggregate(results: list[EpisodeResult], scenarios: dict[str, Scenario]) -> list[dict]:
    """Per plant, over equal sets of scenarios only. The plant's scored scenarios are those whose g is
    defined (limit_score not none); each entry belongs to the set of scored scenarios it ran on, and each
    set is ranked on its own, largest first: a controller defined for fewer scenarios is never ranked
    against a larger set. Per set: the IQM of g with a 95 % stratified-bootstrap interval (strata:
    scenarios), best first; the reference rows' IQM beside it (not ranked); the probability of improvement
    P(X > Y) between its TOP entries (stats.probability_of_improvement); the pooled g of every row."""
    g: dict[tuple[str, str], dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        sc = scenarios[r.scenario]
        if sc.limit_score != "none":
            g[(sc.spec.name, r.controller)][r.scenario].append(r.g)
    out = []
    for plant in sorted({p for p, _ in g}):
        by_ctrl = {c: dict(v) for (p, c), v in g.items() if p == plant}
        sets: dict[tuple[str, ...], list[str]] = defaultdict(list)
        for c, by_sc in by_ctrl.items():
            if entry(c):
                sets[tuple(sorted(by_sc))].append(c)
        for scs, ctrls in sorted(sets.items(), key=lambda kv: (-len(kv[0]), kv[0])):

            def row(c: str, scs: tuple[str, ...] = scs, by_ctrl: dict = by_ctrl) -> dict:
                return {"controller": c, "iqm": stats.iqm_ci([by_ctrl[c][s] for s in scs])}

            ranked = sorted(
                (row(c) for c in ctrls),
                key=lambda r: -r["iqm"][0] if math.isfinite(r["iqm"][0]) else math.inf,
            )
            refs = [row(c) for c in REFERENCES if c in by_ctrl and all(s in by_ctrl[c] for s in scs)]
            top = [r["controller"] for r in ranked[:TOP]]
            matrix = {
                (a, b): stats.probability_of_improvement(
                    [by_ctrl[a][s] for s in scs], [by_ctrl[b][s] for s in scs]
                )
                for a in top
                for b in top
                if a != b
            }
            pooled = {
                c: [x for s in scs for x in by_ctrl[c][s]] for c in [*ctrls, *(r["controller"] for r in refs)]
            }
            out.append(
                {
                    "plant": plant,
                    "scenarios": list(scs),
                    "rows": ranked,
                    "references": refs,
                    "top": top,
                    "p_improve": matrix,
                    "pooled": pooled,
                }
            )
    return out


def _fmt(ci: tuple[float, float, float]) -> str:
    m, lo, hi = ci
    return "n/a" if not np.isfinite(m) else f"{m:.4g} [{lo:.3g}, {hi:.3g}]"


def _vs(r: dict) -> str:
    v = r["vs_baseline"]
    if v is None:
        return "(baseline)" if r["controller"] == r["baseline"] else "n/a"
    ci = _fmt((v["diff"], v["diff_lo"], v["diff_hi"]))
    return f"{ci}, P(better) {v['p_improve']:.2f}"


G_MEANING = (
    "g is the friction penalty removed on the scenario's main metric m, on the same episode: "
    "g = (m_unc - m) / (m_unc - m_ideal), m_unc the scenario's uncompensated loop, m_ideal that loop on "
    "the friction-free twin of the episode (the Ideal row). 1 = as if friction were gone, 0 = no better "
    "than the uncompensated loop, < 0 = worse, > 1 = better than the friction-free loop (feed-forward can "
    "do that). Where the friction-free loop reaches ~0 (limit score `log`), g counts decades: "
    "log10(m_unc/m) / log10(m_unc/m_ideal), m_ideal floored at the settling band. Where friction costs "
    "the uncompensated loop nothing (limit score `none`: the penalty is negative or tiny), g is n/a and "
    "the table ranks by the metric alone. The old score s = 1 - m/m_Zero stays as a column: doing nothing "
    "leaves so large an error on most scenarios that every compensator scores 0.99+ on it."
)


def _penalty_line(s: Scenario, pen: float) -> str:
    kind = {"linear": "scored linearly", "log": "scored in decades", "none": "not scored"}[s.limit_score]
    pct = "n/a" if not math.isfinite(pen) else f"{100 * pen:.3g} %"
    return (
        f"Uncompensated loop: {s.uncompensated}; its friction penalty (median over episodes of "
        f"(m_unc - m_ideal)/m_unc): {pct}; g {kind} (limit_score: {s.limit_score})."
    )


def _aggregate_md(agg: list[dict]) -> list[str]:
    lines = []
    for a in agg:
        lines += [
            "",
            f"### {a['plant']}: {len(a['scenarios'])} scenario(s) ({', '.join(a['scenarios'])})",
            "",
            "| rank | controller | IQM of g [95 % CI] |",
            "|---|---|---|",
        ]
        lines += [f"| {i + 1} | {r['controller']} | {_fmt(r['iqm'])} |" for i, r in enumerate(a["rows"])]
        lines += [f"| (reference) | {r['controller']} | {_fmt(r['iqm'])} |" for r in a["references"]]
        if len(a["top"]) > 1:
            top = a["top"]
            lines += [
                "",
                "P(row > column): probability that a run of the row's controller has the higher g "
                "(rliable's probability of improvement, averaged over the set's scenarios).",
                "",
                "| | " + " | ".join(top) + " |",
                "|---|" + "---|" * len(top),
            ]
            for x in top:
                cells = ["" if x == y else f"{a['p_improve'][(x, y)]:.2f}" for y in top]
                lines.append(f"| {x} | " + " | ".join(cells) + " |")
    return lines


def markdown(
    table: dict[str, list[dict]],
    agg: list[dict],
    suite: str,
    scenarios: dict[str, Scenario],
    penalties: dict[str, float],
) -> str:
    lines = [
        f"# frictiongym leaderboard, suite `{suite}`",
        "",
        "Per scenario: mean and 95 % bootstrap interval over the suite's episodes, sorted by the",
        "scenario's main metric (lower is better; units: the tracked output in rad, m or V, the command in V",
        "or N·m; see docs/envs.md). Reference rows, on the same episodes and never ranked: `Zero` (doing",
        "nothing), `Ideal` (the uncompensated loop without the nonlinear friction), `Oracle` (the",
        "uncompensated loop plus the true friction torque, sampled and delayed as the loop is).",
        "",
        G_MEANING,
        "",
        "`vs baseline`: the mean per-episode difference of the main metric against the scenario's best",
        "classical baseline (negative = better), its 95 % interval, and the probability that the controller",
        "beats the baseline on an episode.",
        "",
        "## Per plant",
        "",
        "IQM of g over the plant's scored scenarios, 95 % stratified-bootstrap interval. Each set of "
        "scenarios is ranked on its own: a controller defined for fewer scenarios is never ranked against "
        "a larger set.",
    ]
    lines += _aggregate_md(agg)
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
            _penalty_line(s, penalties[sc]),
            "",
            f"| controller | episodes | {s.main_metric} (main) | g | 1 - m/m_Zero | "
            + " | ".join(sec)
            + " | vs baseline |",
            "|---|---|---|---|---|" + "---|" * len(sec) + "---|",
        ]
        for r in rows:
            div = f" ({r['diverged']} diverged)" if r["diverged"] else ""
            name = r["controller"]
            name = f"*{name}* (reference)" if r["reference"] else name
            name = f"{name} (uncompensated)" if r["uncompensated"] else name
            lines.append(
                f"| {name} | {r['episodes']}{div} | {_fmt(r['main'])} | {_fmt(r['g'])} | "
                f"{_fmt(r['score'])} | " + " | ".join(_fmt(r["metrics"][m]) for m in sec) + f" | {_vs(r)} |"
            )
    return "\n".join(lines) + "\n"


def write_table_csv(table: dict[str, list[dict]], scenarios: dict[str, Scenario], path: Path) -> None:
    """The tables: one row per (scenario, controller): main metric, g and score (mean, lo, hi), the paired
    comparison against the baseline, and every metric (mean, lo, hi)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            *("scenario", "controller", "reference", "episodes", "diverged", "main_metric", "main_mean"),
            *("main_lo", "main_hi", "g_mean", "g_lo", "g_hi", "score_mean", "score_lo", "score_hi"),
            *("baseline", "diff_mean", "diff_lo", "diff_hi", "p_improve"),
            *(f"{m}_{k}" for m in METRIC_NAMES for k in ("mean", "lo", "hi")),
        ]
    )
    for sc, rows in table.items():
        for r in rows:
            v = r["vs_baseline"] or {}
            w.writerow(
                [sc, r["controller"], r["reference"], r["episodes"], r["diverged"], scenarios[sc].main_metric]
                + [repr(x) for x in (*r["main"], *r["g"], *r["score"])]
                + [r["baseline"]]
                + [repr(v.get(k, math.nan)) for k in ("diff", "diff_lo", "diff_hi", "p_improve")]
                + [repr(x) for m in METRIC_NAMES for x in r["metrics"][m]]
            )
    atomic_text(path, buf.getvalue())


def write_aggregate_csv(agg: list[dict], path: Path) -> None:
    """The per-plant aggregates: one row per (plant, set of scenarios, controller), ranked or reference."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["plant", "scenarios", "rank", "controller", "iqm_g", "iqm_g_lo", "iqm_g_hi"])
    for a in agg:
        scs = " ".join(a["scenarios"])
        for i, r in enumerate(a["rows"]):
            w.writerow([a["plant"], scs, i + 1, r["controller"], *(repr(x) for x in r["iqm"])])
        for r in a["references"]:
            w.writerow([a["plant"], scs, "reference", r["controller"], *(repr(x) for x in r["iqm"])])
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
    """g per scenario (strip plots; 1 - m/m_Zero where g is not scored), the per-plant IQM of g with
    intervals, the per-plant performance profiles of g, and per scenario the time responses of its best
    and worst episodes (by the main metric)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ctrls = list(dict.fromkeys(r.controller for r in results))
    colour = {c: f"C{i % 10}" for i, c in enumerate(ctrls)}
    names = []
    scs = list(table)
    fig, axes = plt.subplots(1, len(scs), figsize=(3.2 * len(scs), 3.8), squeeze=False)
    for ax, sc in zip(axes[0], scs, strict=True):
        scored = scenarios[sc].limit_score != "none"
        order = [r["controller"] for r in table[sc] if r["controller"] != ZERO or not scored]
        for i, c in enumerate(order):
            mine = [r for r in results if r.scenario == sc and r.controller == c]
            s = np.array([r.g if scored else r.score for r in mine])
            jitter = np.random.default_rng(i).uniform(-0.15, 0.15, len(s))
            ax.plot(i + jitter, s, "o", ms=3, alpha=0.6, color=colour[c])
            if np.isfinite(s).any():
                ax.plot([i - 0.3, i + 0.3], [np.nanmean(s)] * 2, "k-", lw=1.5)
        ax.set_xticks(range(len(order)), order, rotation=45, ha="right", fontsize=7)
        for y in (0.0, 1.0) if scored else (0.0,):
            ax.axhline(y, color="0.6", lw=0.8)
        ax.set_title(sc, fontsize=8)
        ax.set_ylabel("g (friction penalty removed)" if scored else "1 - m/m_Zero (g not scored)", fontsize=7)
    names.append(_save_png(fig, out / "scores.png"))

    sets = [a for a in agg if a["rows"]]
    if sets:
        fig, axes = plt.subplots(len(sets), 1, figsize=(6.5, sum(0.3 * len(a["rows"]) + 1.2 for a in sets)),
                                 squeeze=False)  # fmt: skip
        for ax, a in zip(axes[:, 0], sets, strict=True):
            rows = a["rows"] + a["references"]
            for i, r in enumerate(rows):
                m, lo, hi = r["iqm"]
                ref = r in a["references"]
                ax.errorbar(m, i, xerr=[[m - lo], [hi - m]], fmt="s" if ref else "o",
                            color="0.4" if ref else colour[r["controller"]], capsize=3)  # fmt: skip
            ax.set_yticks(range(len(rows)), [r["controller"] for r in rows], fontsize=7)
            ax.invert_yaxis()
            ax.axvline(1.0, color="0.6", lw=0.8)
            ax.set_title(f"{a['plant']}: {len(a['scenarios'])} scenario(s)", fontsize=8)
        axes[-1, 0].set_xlabel("IQM of g (95 % stratified bootstrap)")
        names.append(_save_png(fig, out / "aggregate_iqm.png"))

        fig, axes = plt.subplots(1, len(sets), figsize=(4.2 * len(sets), 3.6), squeeze=False)
        for ax, a in zip(axes[0], sets, strict=True):
            for c, g in a["pooled"].items():
                ref = c in REFERENCES
                ax.plot(TAUS, stats.performance_profile(g, TAUS), "--" if ref else "-", label=c,
                        color="0.4" if ref else colour[c], lw=1)  # fmt: skip
            ax.set(xlabel="g threshold τ", title=f"{a['plant']}: {len(a['scenarios'])} scenario(s)")
            ax.legend(fontsize=6)
        axes[0, 0].set_ylabel("fraction of episodes with g > τ")
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
    """Evaluate (the suite, or the given episodes) with the reference rows (Zero, Ideal, Oracle) and each
    scenario's uncompensated loop always included, and summarize. With out: results go to
    out/episodes.csv incrementally (a rerun resumes), then leaderboard.md, leaderboard.csv (the tables),
    aggregate.csv (the per-plant aggregates) and PNG plots, each written atomically."""
    models = tuple(str(m) for m in models)
    available = registry.available(models)
    names = controllers or list(available)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(f"unknown controllers {unknown}; available: {list(available)}")
    episodes = episodes if episodes is not None else load_suite(suite)
    scenarios = {name: load_scenario(name) for name in dict.fromkeys(e.scenario for e in episodes)}
    loops = [s.uncompensated for s in scenarios.values()]  # g needs them on every episode
    names = list(dict.fromkeys([*REFERENCES, *loops, *names]))
    if out is None:
        jobs, skipped = engine.plan(names, episodes, models)
        results: list[EpisodeResult] = []
        engine.run_jobs(jobs, workers, results.extend, progress, models, ray)
        results = engine.canonical(results, jobs, engine.scoring(episodes))
    else:
        options = {"episodes": [asdict(e) for e in episodes], "controllers": names, "models": list(models)}
        results, skipped = engine.evaluate_to(out, names, episodes, options, workers, progress, models, ray)
    for name, scenario, reason in skipped:
        if progress:
            print(f"skipped {name} on {scenario}: {reason}")
    table, agg = summarize(results, scenarios), aggregate(results, scenarios)
    if out is not None:
        write_table_csv(table, scenarios, out / "leaderboard.csv")
        write_aggregate_csv(agg, out / "aggregate.csv")
        figs = plots(results, table, agg, out, scenarios, {e.scenario: e.randomize for e in episodes}, models)
        pens = {sc: penalty(results, s) for sc, s in scenarios.items()}
        md = markdown(table, agg, suite, scenarios, pens)
        atomic_text(out / "leaderboard.md", md + "\n" + "".join(f"![{f}]({f})\n" for f in figs))
    return results, table
