"""The leaderboard's report: its computed Board (agents/leaderboard.py) rendered as leaderboard.md's text,
the leaderboard.csv and aggregate.csv texts, and its figures. Rendering only: nothing here evaluates,
scores or writes a file (the leaderboard computes, renders with this module, then writes), as
python-control keeps timeresp (computing) apart from timeplot (drawing)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.records import pyplot
from frictiongym.envs.scenario import Scenario

from . import registry, stats
from .base import ZERO
from .stats import MAX_EFFORT_RATIO

if TYPE_CHECKING:
    from .leaderboard import Board

REFERENCES = registry.REFERENCES  # Zero, Ideal, Oracle: drawn as references, never ranked
TAUS = np.linspace(-0.5, 1.5, 201)  # performance-profile thresholds of g


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
    "leaves so large an error on most scenarios that every compensator scores 0.99+ on it. "
    "g (tracking limit) is the same with m_ideal replaced by the TrackingLimit row: the friction-free twin "
    "under the plant's linear two-degree-of-freedom loop (model feed-forward plus the loop), the best a "
    "linear design tracks without friction; 1 = there, and it stands for Ideal at a set-point. The "
    "headline (the per-plant IQM) uses g, friction removed."
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


def markdown(board: Board) -> str:
    """leaderboard.md's text (without the figure links): the per-plant aggregates, the verdicts on the
    learned and plug-in controllers, one table per scenario."""
    table, scenarios, suite = board.table, board.scenarios, board.suite
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
        "beats the baseline on an episode. The baseline is the best classical row that is a result: one",
        f"spending more than {MAX_EFFORT_RATIO}x the uncompensated loop's effort_rms or adding a limit cycle",
        "chatters (marked so) and is not one.",
        "",
        "## Per plant",
        "",
        "IQM of g over the plant's scored scenarios, 95 % stratified-bootstrap interval. Each set of "
        "scenarios is ranked on its own: a controller defined for fewer scenarios is never ranked against "
        "a larger set.",
    ]
    lines += _aggregate_md(board.aggregate)
    judged = board.verdicts
    if judged:
        lines += [
            "",
            "## Learned and plug-in controllers against the best classical baseline",
            "",
            "Beats the baseline = lower main metric with the paired 95 % interval of the per-episode "
            f"difference below 0, effort_rms at most {judged[0]['max_effort_ratio']}x the baseline's, and no "
            "new "
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
            _penalty_line(s, board.penalties[sc]),
            "",
            f"| controller | episodes | {s.main_metric} (main) | g | g (tracking limit) | 1 - m/m_Zero | "
            + " | ".join(sec)
            + " | vs baseline |",
            "|---|---|---|---|---|---|" + "---|" * len(sec) + "---|",
        ]
        for r in rows:
            div = f" ({r['diverged']} diverged)" if r["diverged"] else ""
            name = r["controller"]
            name = f"*{name}* (reference)" if r["reference"] else name
            name = f"{name} (uncompensated)" if r["uncompensated"] else name
            name = f"{name} (chatters: {r['chatters']})" if r.get("chatters") else name
            lines.append(
                f"| {name} | {r['episodes']}{div} | {_fmt(r['main'])} | {_fmt(r['g'])} | "
                f"{_fmt(r['g_tracking'])} | {_fmt(r['score'])} | "
                + " | ".join(_fmt(r["metrics"][m]) for m in sec)
                + f" | {_vs(r)} |"
            )
    return "\n".join(lines) + "\n"


def answer(board: Board) -> str:
    """answer.md: the suite's question per plant, one row per scenario: the best classical row that is a
    result (the baseline), the best entry that is not a built-in (a trained model or a plug-in) and
    whether it beats the baseline (the verdicts' rule), and the two limits, each main metric's mean and
    95 % interval on the run's episodes."""
    judged = {(v["scenario"], v["controller"]): v for v in board.verdicts}
    by_plant: dict[str, list[str]] = {}
    for sc, rows in board.table.items():
        s = board.scenarios[sc]
        by = {r["controller"]: r for r in rows}
        base = next((r for r in rows if r["controller"] == r["baseline"]), None)
        other = [r for r in rows if (sc, r["controller"]) in judged]
        wins = [r for r in other if judged[(sc, r["controller"])]["beats_baseline"]]
        best = (wins or other or [None])[0]  # rows are sorted by the main metric

        def cell(r: dict | None) -> str:
            return "n/a" if r is None else f"{r['controller']}: {_fmt(r['main'])}"

        verdict = "n/a"
        if best is not None:
            v = judged[(sc, best["controller"])]
            verdict = "beats it" if v["beats_baseline"] else f"no ({v['why_not']})"
        count = f"{len(wins)} of {len(other)}" if other else "n/a"
        limit = by.get("TrackingLimit") or by.get("Ideal")
        by_plant.setdefault(s.spec.name, []).append(
            f"| {sc} ({s.main_metric}) | {cell(base)} | {cell(best)} | {verdict} | {count} | "
            f"{cell(by.get('Ideal'))} | {cell(limit)} |"
        )
    lines = [
        f"# The suite's question on `{board.suite}`",
        "",
        "Per scenario: the best classical controller that is a result (no more than "
        f"{MAX_EFFORT_RATIO}x the uncompensated loop's effort, no new limit cycle), the best learned or "
        "plug-in entry (the best that beats the baseline, else the best), whether it beats the baseline "
        "(paired 95 % interval below 0, effort and limit-cycle rule), how many such entries do, and the "
        "two limits (Ideal: friction removed under the uncompensated loop; TrackingLimit: the friction-free "
        "twin under the linear two-degree-of-freedom loop, Ideal at a set-point). Mean [95 % interval] of "
        "the main metric, lower is better.",
    ]
    for plant, rows in by_plant.items():
        lines += [
            "",
            f"## {plant}",
            "",
            "| scenario (main metric) | best classical | best learned or plug-in | vs the classical | "
            "entries that beat it | Ideal | tracking limit |",
            "|---|---|---|---|---|---|---|",
            *rows,
        ]
    return "\n".join(lines) + "\n"


def table_csv(board: Board) -> str:
    """leaderboard.csv, the tables: one row per (scenario, controller): main metric, g and score (mean, lo,
    hi), the paired comparison against the baseline, and every metric (mean, lo, hi)."""
    table, scenarios = board.table, board.scenarios
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            *("scenario", "controller", "reference", "episodes", "diverged", "main_metric", "main_mean"),
            *(
                "main_lo",
                "main_hi",
                "g_mean",
                "g_lo",
                "g_hi",
                "g_tracking_mean",
                "g_tracking_lo",
                "g_tracking_hi",
            ),
            *("score_mean", "score_lo", "score_hi"),
            *("baseline", "diff_mean", "diff_lo", "diff_hi", "p_improve"),
            *(f"{m}_{k}" for m in METRIC_NAMES for k in ("mean", "lo", "hi")),
        ]
    )
    for sc, rows in table.items():
        for r in rows:
            v = r["vs_baseline"] or {}
            w.writerow(
                [sc, r["controller"], r["reference"], r["episodes"], r["diverged"], scenarios[sc].main_metric]
                + [repr(x) for x in (*r["main"], *r["g"], *r["g_tracking"], *r["score"])]
                + [r["baseline"]]
                + [repr(v.get(k, math.nan)) for k in ("diff", "diff_lo", "diff_hi", "p_improve")]
                + [repr(x) for m in METRIC_NAMES for x in r["metrics"][m]]
            )
    return buf.getvalue()


def aggregate_csv(agg: list[dict]) -> str:
    """aggregate.csv, the per-plant aggregates: one row per (plant, set of scenarios, controller), ranked
    or reference."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["plant", "scenarios", "rank", "controller", "iqm_g", "iqm_g_lo", "iqm_g_hi"])
    for a in agg:
        scs = " ".join(a["scenarios"])
        for i, r in enumerate(a["rows"]):
            w.writerow([a["plant"], scs, i + 1, r["controller"], *(repr(x) for x in r["iqm"])])
        for r in a["references"]:
            w.writerow([a["plant"], scs, "reference", r["controller"], *(repr(x) for x in r["iqm"])])
    return buf.getvalue()


def figures(board: Board) -> Iterator[tuple[str, Any]]:
    """(file name, matplotlib figure) in leaderboard.md's order: g per scenario (strip plots; 1 - m/m_Zero
    where g is not scored), the per-plant IQM of g with intervals, the per-plant performance profiles of
    g, and per scenario the time responses of its best and worst episodes (board.responses). One at a time:
    the caller saves and closes each before the next is drawn."""
    results, table, agg, scenarios = board.results, board.table, board.aggregate, board.scenarios
    plt = pyplot()

    ctrls = list(dict.fromkeys(r.controller for r in results))
    colour = {c: f"C{i % 10}" for i, c in enumerate(ctrls)}
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
    yield "scores.png", fig

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
        yield "aggregate_iqm.png", fig

        fig, axes = plt.subplots(1, len(sets), figsize=(4.2 * len(sets), 3.6), squeeze=False)
        for ax, a in zip(axes[0], sets, strict=True):
            for c, g in a["pooled"].items():
                ref = c in REFERENCES
                ax.plot(TAUS, stats.performance_profile(g, TAUS), "--" if ref else "-", label=c,
                        color="0.4" if ref else colour[c], lw=1)  # fmt: skip
            ax.set(xlabel="g threshold τ", title=f"{a['plant']}: {len(a['scenarios'])} scenario(s)")
            ax.legend(fontsize=6)
        axes[0, 0].set_ylabel("fraction of episodes with g > τ")
        yield "performance_profile.png", fig

    for sc, (best, worst) in board.responses.items():
        main = scenarios[sc].main_metric
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
        yield f"response_{sc}.png", fig
