"""The leaderboard's report: its computed Board (board.py, from leaderboard.py) rendered as
leaderboard.md's text, the leaderboard.csv and aggregate.csv texts, and its figures. Rendering only:
nothing here evaluates, scores or writes a file (the leaderboard computes, renders with this module, then
writes), as python-control keeps timeresp (computing) apart from timeplot (drawing)."""

from __future__ import annotations

import csv
import io
import math
import re
import textwrap
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from frictiongym.agents import registry
from frictiongym.agents.base import ZERO
from frictiongym.agents.evaluation import judging, stats
from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.records import pyplot
from frictiongym.envs.scenario import Scenario

if TYPE_CHECKING:
    from frictiongym.agents.evaluation.board import Board

REFERENCES = registry.REFERENCES  # Zero, Ideal, Oracle: drawn as references, never ranked
RULE = (
    "A row is a result when, against its scenario's reference point (the larger of the uncompensated "
    "loop's and the friction-free linear design's on the same episodes: TrackingLimit, Ideal at a "
    f"set-point), it does not chatter (the command's rms change per control period at most "
    f"{stats.CHATTER_RATIO:g}x the point's plus {100 * stats.CHATTER_FLOOR:g} % of the command's range), "
    f"saturate (saturated periods at most {stats.SATURATION_RATIO:g}x the point's share plus "
    f"{100 * stats.SATURATION_FLOOR:g} %) or add a limit cycle (the error's sustained oscillation where "
    f"the reference rests at most {stats.CYCLE_RATIO:g}x the point's plus the settling band), and is not "
    f"fragile: on {judging.ROBUSTNESS_SEEDS} validation-range episodes per scenario, each with "
    f"{', '.join(judging.VARIANTS.values())} (where the plant has noise or a spring), it neither diverges, "
    "saturates beyond the uncompensated loop's share nor falls behind the loop's main metric where, on "
    "the same episodes as drawn, it is ahead of it; the same "
    "rule for classical and learned rows. The baseline is the classical row that is a result with the "
    f"lowest main metric on the scenario's first {judging.SELECTION_EPISODES} validation-range episodes, "
    "never on the episodes it is judged on."
)
NOT_JUDGED = (
    "**Not judged** (a quick look, `--no-judging`): this run skipped the judging sets, so its baselines are "
    "chosen on its own episodes and no row was checked for margins; not an answer to quote."
)


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
        "nothing), `Ideal` (the uncompensated loop without the nonlinear friction), `TrackingLimit` (on",
        "tracking scenarios: the friction-free twin under the linear two-degree-of-freedom loop), `Oracle`",
        "(the uncompensated loop plus the true friction torque, sampled and delayed as the loop is),",
        "`Optimum` (the friction-free optimum: the best commands within the actuator's limit on the twin,",
        "knowing the whole reference; no controller goes below it there).",
        "",
        G_MEANING,
        "",
        "`vs baseline`: the mean per-episode difference of the main metric against the scenario's best",
        "classical baseline (negative = better), its 95 % interval, and the probability that the controller",
        "beats the baseline on an episode. The baseline is the best classical row that is a result; a row",
        "that is not one is marked with why.",
        "",
        RULE,
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
            "difference below 0, and a result by the rule above. Beside each entry, what the rule reads "
            "(the reference point's in brackets).",
            "",
            "| scenario | controller | baseline | difference of the main metric | rms change per period | "
            "saturated share | oscillation at rest | beats the baseline |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for j in judged:
            v, p = j["vs_baseline"], j["point"]
            lines.append(
                f"| {j['scenario']} | {j['controller']} | {j['baseline']} | "
                f"{_fmt((v['diff'], v['diff_lo'], v['diff_hi']))} | "
                f"{j['roughness']:.3g} ({p.roughness:.3g}) | "
                f"{j['saturated']:.3g} ({p.saturated:.3g}) | {j['rest_cycle']:.3g} ({p.rest_cycle:.3g}) | "
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


ANSWER_HEAD = ["scenario (main metric)", "best classical", "best learned", "learned vs the classical",
               "best plug-in", "plug-in vs the classical", "Ideal", "tracking limit",
               "friction-free optimum"]  # fmt: skip
KINDS = ("learned", "plug-in")  # the answer's two sides against the classical: saved models, user code


def kind(board: Board, name: str) -> str:
    """An entry's kind: "learned" for a saved model of the run (board.about), else "plug-in" (user code)."""
    return "learned" if name in board.about else "plug-in"


SEED_SUFFIX = re.compile(r"-s\d+$")  # a trained model's seed in its name: ResSAC-kang_regulation-s2


def designs(rows: list[dict]) -> dict[str, list[dict]]:
    """Rows grouped by design: the name without its training seed's suffix (`-s<seed>`); a row without
    one is a design of its own."""
    out: dict[str, list[dict]] = {}
    for r in rows:
        out.setdefault(SEED_SUFFIX.sub("", r["controller"]), []).append(r)
    return out


def _sort_key(r: dict) -> float:
    return r["main"][0] if math.isfinite(r["main"][0]) else math.inf


def median_seed(rows: list[dict]) -> dict:
    """A design's median training seed by its mean main metric (of an even count the worse of the middle
    two): the seed that speaks for the design, as a design beats the baseline when its median seed does."""
    return sorted(rows, key=_sort_key)[len(rows) // 2]


def answer_rows(board: Board) -> dict[str, list[dict]]:
    """The suite's question per plant, a row per scenario: {"scenario": "name (main metric)", "cells":
    [best classical, best learned, its verdict, best plug-in, its verdict, Ideal, tracking limit,
    friction-free optimum], each
    cell "n/a", a text or (text, the main metric's mean to sort by); "sides": per kind (KINDS), its best
    design's median seed, how many of its designs beat the baseline and how many ran}. The best classical
    is the baseline (chosen on the selection episodes); a design (designs) is judged by its median seed
    (median_seed), and the best of a kind is the best design that beats it, else the best design."""
    judged = {(v["scenario"], v["controller"]): v for v in board.verdicts}
    by_plant: dict[str, list[dict]] = {}
    for sc, rows in board.table.items():
        s = board.scenarios[sc]
        by = {r["controller"]: r for r in rows}
        base = next((r for r in rows if r["controller"] == r["baseline"]), None)

        def cell(r: dict | None) -> tuple[str, float] | str:
            return "n/a" if r is None else (f"{r['controller']}: {_fmt(r['main'])}", r["main"][0])

        cells: list = [cell(base)]
        sides = {}
        for k in KINDS:
            other = [r for r in rows if (sc, r["controller"]) in judged and kind(board, r["controller"]) == k]
            medians = [(median_seed(seeds), len(seeds)) for seeds in designs(other).values()]
            medians.sort(key=lambda m: _sort_key(m[0]))
            wins = [m for m in medians if judged[(sc, m[0]["controller"])]["beats_baseline"]]
            best, seeds = (wins or medians or [(None, 0)])[0]
            verdict = "n/a"
            if best is not None:
                v = judged[(sc, best["controller"])]
                verdict = "beats it" if v["beats_baseline"] else f"no ({v['why_not']})"
                verdict += f" (the median of {seeds} seeds)" if seeds > 1 else ""
                verdict += f"; {len(wins)} of {len(medians)} designs beat it"
            cells += [cell(best), verdict]
            sides[k] = {"best": best, "wins": len(wins), "entries": len(medians)}
        limit = by.get("TrackingLimit") or by.get("Ideal")
        cells += [cell(by.get("Ideal")), cell(limit), cell(by.get("Optimum"))]
        by_plant.setdefault(s.spec.name, []).append(
            {
                "scenario": f"{sc} ({s.main_metric})",
                "cells": cells,
                "name": sc,
                "baseline": base,
                "sides": sides,
            }
        )
    return by_plant


def headline(board: Board) -> list[tuple[str, str, list[str]]]:
    """The answer in a few lines, per plant: (plant, its verdict per kind, a line per scenario a learned
    or plug-in entry wins there, with both rows' main metric). The console, answer.md and the page open
    with it."""
    out = []
    for plant, rows in answer_rows(board).items():
        verdicts, lines = [], []
        for k in KINDS:
            judged = [r for r in rows if r["sides"][k]["entries"]]
            won = [r for r in judged if r["sides"][k]["wins"]]
            if judged:
                verdicts.append(f"a {k} design beats the best classical on {len(won)} of {len(judged)}")
            for r in won:
                main = board.scenarios[r["name"]].main_metric
                best = r["sides"][k]["best"]
                lines.append(
                    f"{r['name']} ({main} in {board.scenarios[r['name']].metric_unit(main)}): "
                    f"{best['controller']} {_fmt(best['main'])} against "
                    f"{r['baseline']['controller']} {_fmt(r['baseline']['main'])}"
                )
        verdict = "; ".join(f"{v} scenarios" for v in verdicts) or "no learned or plug-in entry ran"
        out.append((plant, verdict, lines))
    return out


def headline_text(board: Board) -> str:
    """headline() as Markdown bullets."""
    lines = []
    for plant, verdict, wins in headline(board):
        lines.append(f"- **{plant}**: {verdict}" + ("; " + "; ".join(wins) if wins else ""))
    return "\n".join(lines)


def answer(board: Board) -> str:
    """answer.md: the suite's question per plant (answer_rows), each main metric's mean and 95 % interval
    on the run's episodes."""
    lines = [
        f"# The suite's question on `{board.suite}`",
        "",
        "Per scenario: the best classical controller that is a result (the rule below); the best learned "
        "entry (a saved model) and the best plug-in (a user's controller), each the best of its kind that "
        "beats the baseline, else the best, whether it beats the baseline (paired 95 % interval below 0, "
        "and a result) and how many of its kind do; and the "
        "limits (Ideal: friction removed under the uncompensated loop; TrackingLimit: the friction-free "
        "twin under the linear two-degree-of-freedom loop, Ideal at a set-point; the friction-free optimum: "
        "the best commands within the actuator's limit on that twin knowing the whole reference, where no "
        "controller goes below it; n/a where the drive's jitter makes the twin vary in time). Mean [95 % "
        "interval] of the main metric, lower is better.",
        "",
        RULE if board.judged else f"{RULE}\n\n{NOT_JUDGED}",
        "",
        "## The answer",
        "",
        headline_text(board),
    ]
    for plant, rows in answer_rows(board).items():
        lines += [
            "",
            f"## {plant}",
            "",
            "| " + " | ".join(ANSWER_HEAD) + " |",
            "|---" * len(ANSWER_HEAD) + "|",
        ]
        for row in rows:
            cells = [c if isinstance(c, str) else c[0] for c in row["cells"]]
            lines.append(f"| {row['scenario']} | " + " | ".join(cells) + " |")
    return "\n".join(lines + budget_lines(board)) + "\n"


def budget_lines(board: Board) -> list[str]:
    """answer.md's budgets: what each tuned or trained entry the answer names spent, in env steps and wall
    time (registry.budgets), so both sides' budgets read in the same units."""
    named: dict[tuple[str, str], None] = {}
    for plant, rows in answer_rows(board).items():
        for row in rows:
            for r in [row["baseline"], *(side["best"] for side in row["sides"].values())]:
                if r is not None and (r["controller"], plant) in board.budgets:
                    named[r["controller"], plant] = None
    if not named:
        return []
    lines = [
        "",
        "## Budgets",
        "",
        "What each tuned or trained entry the tables name spent (a tuned twin: its search on validation "
        "episodes; a learned model: its training; each in env steps, one step a control period, and wall "
        "time on 2 cores).",
        "",
        "| entry | plant | env steps | wall time (s) | counted |",
        "|---|---|---|---|---|",
    ]
    for name, plant in named:
        b = board.budgets[name, plant]
        lines.append(f"| {name} | {plant} | {b.env_steps:,} | {b.wall_s:.0f} | {b.counted} |")
    return lines


def table_csv(board: Board) -> str:
    """leaderboard.csv, the tables: one row per (scenario, controller): main metric, g and score (mean, lo,
    hi), the paired comparison against the baseline, why the row is not a result ("" if it is one), and
    every metric (mean, lo, hi)."""
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
            *("baseline", "diff_mean", "diff_lo", "diff_hi", "p_improve", "not_a_result"),
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
                + [r.get("chatters", "")]
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


def palette(names: list[str]) -> dict[str, Any]:
    """A distinct colour per entry (tab20's dark then light shades, tab20b, tab20c: 60 before one
    repeats), grey for references."""
    from matplotlib import colormaps

    tab20 = colormaps["tab20"].colors  # its dark shades first: neighbours in the list differ in hue
    colours = [*tab20[0::2], *tab20[1::2], *(c for m in ("tab20b", "tab20c") for c in colormaps[m].colors)]
    entries = [n for n in names if n not in REFERENCES]
    return {
        **{n: colours[i % len(colours)] for i, n in enumerate(entries)},
        **dict.fromkeys(REFERENCES, "0.35"),
    }


def span(values: Any, marks: tuple[float, ...] = ()) -> tuple[float, float]:
    """Axis limits set by the bulk of the entries' values (within 3 interquartile ranges of their
    quartiles) and the marks, padded 5 %: a row far outside, a reference (Zero at g = -17,500) or a
    broken entry, is drawn at the edge with its value (off_scale), it does not set the axis."""
    v = np.asarray([x for x in np.ravel(values) if np.isfinite(x)], dtype=float)
    ends = list(marks) or [0.0, 1.0]
    if len(v):
        q1, q3 = np.percentile(v, [25, 75])
        fence = 3.0 * (q3 - q1)
        inside = v[(v >= q1 - fence) & (v <= q3 + fence)]
        ends += [float(inside.min()), float(inside.max())]
    lo, hi = min(ends), max(ends)
    pad = 0.05 * (hi - lo) or 0.5
    return lo - pad, hi + pad


def off_scale(ax: Any, x: float, y: float, lim: tuple[float, float]) -> bool:
    """Mark a value outside the axis at its edge, with its value; whether it was."""
    if lim[0] <= x <= lim[1] or not np.isfinite(x):
        return False
    edge, ha = (lim[0], "left") if x < lim[0] else (lim[1], "right")
    ax.plot(edge, y, "<" if x < lim[0] else ">", color="0.35", ms=5)
    ax.annotate(f"{x:.3g} (off scale)", (edge, y), fontsize=7, ha=ha, va="bottom", color="0.35")
    return True


# the reference rows' lines in the performance profiles: one style each (they share a grey)
REFERENCE_STYLE = {"Zero": ":", "Ideal": "--", "TrackingLimit": "-.", "Oracle": (0, (5, 1, 1, 1, 1, 1))}


def _wrapped(title: str, width: int = 70) -> str:
    """A panel title on lines of at most `width` characters (a long list of scenarios is not clipped)."""
    return textwrap.fill(title, width)


def grid(plt: Any, n: int, ncols: int, width: float, height: float) -> tuple[Any, list[Any]]:
    """A figure of n panels in rows of ncols (unused cells hidden) and its panels in order."""
    ncols = min(ncols, n)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def response_role(name: str, s: Scenario, board: Board) -> str:
    """What a row of a response figure is: the best learned or plug-in entry, the best classical result
    (the baseline), the uncompensated loop or the friction-free one (Ideal)."""
    if name == "Ideal":
        return "friction removed"
    if name == s.uncompensated:
        return "uncompensated loop"
    rows = board.table[s.name]
    if any(r["controller"] == name and r["controller"] == r["baseline"] for r in rows):
        return "best classical result"
    return "best learned or plug-in"


def figures(board: Board) -> Iterator[tuple[str, Any]]:
    """(file name, matplotlib figure) in leaderboard.md's order: per scenario the episodes' g (1 - m/m_Zero
    where g is not scored) of every row, ranked; the per-plant IQM of g with intervals; the per-plant
    performance profiles of g; and per scenario the time response of the best learned or plug-in entry
    and the best classical result against the uncompensated loop and Ideal (board.responses). Axes are
    set by the entries, never by a reference row; panels sit in a grid of at most two columns (the page
    shows each at its natural width). One at a time: the caller saves and closes each before the next."""
    results, table, agg, scenarios = board.results, board.table, board.aggregate, board.scenarios
    plt = pyplot()
    colour = palette(list(dict.fromkeys(r.controller for r in results)))
    scores: dict[tuple[str, str], list[float]] = {}
    for r in results:
        scored = scenarios[r.scenario].limit_score != "none"
        scores.setdefault((r.scenario, r.controller), []).append(r.g if scored else r.score)

    scs = list(table)
    tallest = max(len(rows) for rows in table.values())
    fig, axes = grid(plt, len(scs), 2, 5.0, 0.17 * tallest + 1.3)
    for ax, sc in zip(axes, scs, strict=True):
        scored = scenarios[sc].limit_score != "none"
        order = [r["controller"] for r in table[sc] if r["controller"] != ZERO or not scored]
        points = {c: np.asarray(scores[sc, c], dtype=float) for c in order}
        lim = span(
            [x for c in order if c not in REFERENCES for x in points[c]], (0.0, 1.0) if scored else (0.0,)
        )
        for i, c in enumerate(order):
            s, ref = points[c], c in REFERENCES
            jitter = np.random.default_rng(i).uniform(-0.2, 0.2, len(s))
            ax.plot(np.clip(s, *lim), i + jitter, "s" if ref else "o", ms=2.5, alpha=0.6, color=colour[c])
            mean = float(np.nanmean(s)) if np.isfinite(s).any() else math.nan
            if not off_scale(ax, mean, i, lim) and math.isfinite(mean):
                ax.plot([min(max(mean, lim[0]), lim[1])] * 2, [i - 0.35, i + 0.35], "k-", lw=1.5)
        ax.set_yticks(range(len(order)), order, fontsize=7)
        ax.invert_yaxis()
        ax.set_xlim(*lim)
        for x in (0.0, 1.0) if scored else (0.0,):
            ax.axvline(x, color="0.6", lw=0.8)
        ax.set_title(sc, fontsize=8)
        ax.set_xlabel("g: friction penalty removed" if scored else "1 - m/m_Zero (g not scored)", fontsize=7)
        ax.tick_params(axis="x", labelsize=7)
    yield "scores.png", fig

    sets = [a for a in agg if a["rows"]]
    if sets:
        tallest = max(len(a["rows"]) + len(a["references"]) for a in sets)
        fig, axes = grid(plt, len(sets), 2, 5.2, 0.2 * tallest + 1.3)
        for ax, a in zip(axes, sets, strict=True):
            rows = a["rows"] + a["references"]
            lim = span([x for r in a["rows"] for x in r["iqm"]], (0.0, 1.0))
            for i, r in enumerate(rows):
                m, lo, hi = r["iqm"]
                ref = r in a["references"]
                if off_scale(ax, m, i, lim):
                    continue
                style = {"fmt": "s" if ref else "o", "color": colour[r["controller"]], "capsize": 3}
                ax.errorbar(m, i, xerr=[[m - lo], [hi - m]], **style)
            ax.set_yticks(range(len(rows)), [r["controller"] for r in rows], fontsize=7)
            ax.invert_yaxis()
            ax.set_xlim(*lim)
            ax.axvline(0.0, color="0.6", lw=0.8)
            ax.axvline(1.0, color="0.6", lw=0.8)
            ax.set_title(_wrapped(f"{a['plant']}: {', '.join(a['scenarios'])}"), fontsize=7)
            ax.set_xlabel("IQM of g (95 % stratified bootstrap); grey squares: references", fontsize=7)
        yield "aggregate_iqm.png", fig

        legend_rows = max(math.ceil(len(a["pooled"]) / 2) for a in sets)
        fig, axes = grid(plt, len(sets), 2, 5.0, 3.0 + 0.16 * legend_rows)
        for ax, a in zip(axes, sets, strict=True):
            entries = [x for c, g in a["pooled"].items() if c not in REFERENCES for x in g]
            taus = np.linspace(*span(entries, (0.0, 1.0)), 201)
            for c, g in a["pooled"].items():
                profile = stats.performance_profile(g, taus)
                ax.plot(taus, profile, linestyle=REFERENCE_STYLE.get(c, "-"), label=c, color=colour[c], lw=1)
            ax.set_xlabel("g threshold τ", fontsize=7)
            ax.set_title(_wrapped(f"{a['plant']}: {', '.join(a['scenarios'])}"), fontsize=7)
            # below the panel, so that no curve is hidden behind it
            ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.22), frameon=False)
        axes[0].set_ylabel("fraction of episodes with g > τ", fontsize=7)
        yield "performance_profile.png", fig

    for sc, runs in board.responses.items():
        s = scenarios[sc]
        unit, cmd = s.output_unit, s.spec.command_unit
        fig, ax = plt.subplots(3, 1, figsize=(7.5, 6.5), sharex=True)
        ref = runs[0].log
        ax[0].plot(ref["t"], ref["reference"], "k:", lw=1, label="reference")
        metric_unit = s.metric_unit(s.main_metric)
        for r in runs:
            g = r.log
            ideal = r.controller == "Ideal"
            label = f"{r.controller} ({response_role(r.controller, s, board)}): {s.main_metric} "
            label += f"{r.metrics[s.main_metric]:.3g} {metric_unit}"
            style, c = ("--", "0.45") if ideal else ("-", None)
            ax[0].plot(g["t"], g["output"], style, lw=1.2, color=c, label=label)
            ax[1].plot(g["t"], g["output"] - g["reference"], style, lw=1, color=c)
            ax[2].step(g["t"], g["command"], style, lw=1, where="pre", color=c)
        ax[0].set_title(
            _wrapped(f"{sc}, seed {runs[0].seed}: the median episode of {runs[0].controller}"), fontsize=9
        )
        ax[0].set(ylabel=f"output ({unit})")
        ax[0].legend(fontsize=7)
        ax[1].set(ylabel=f"error ({unit})")
        ax[2].set(xlabel="t (s)", ylabel=f"command ({cmd})")
        yield f"response_{sc}.png", fig
