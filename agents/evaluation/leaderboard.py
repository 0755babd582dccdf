"""Leaderboard: every applicable controller, and the reference rows, on the identical episodes of a suite.

Reference rows, run on every episode and never ranked (agents/evaluation/limits.py): `Zero` (doing nothing),
the scenario's uncompensated loop (benchmark.uncompensated, also an entry), `Ideal` (that loop on the
friction-free twin of the episode), `Oracle` (that loop plus the true friction torque) and `Optimum` (the
friction-free optimum: the best commands within the actuator's limit on the twin, knowing the whole
reference; agents/evaluation/optimum.py).

Per scenario: its main metric (declared in the scenario's YAML, lower is better) with a 95 % bootstrap
interval, g = the friction penalty removed (stats.limit_score: 1 as if friction were gone, 0 no better
than the uncompensated loop), the normalised score s = 1 - m / m_Zero, the secondary metrics, and a
paired comparison of every controller against the scenario's best classical baseline on the same
episodes. Per plant, over equal sets of scenarios only: the IQM of g with stratified-bootstrap
intervals, the probability of improvement between the top entries, performance profiles of g.

Computed here (a Board: board.py), rendered by report.py (text, CSV, figures) and page.py (the web
page), then written (`write`).
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.agents import registry
from frictiongym.agents.evaluation import engine, judging, report, stats
from frictiongym.agents.evaluation.board import Board
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, run_episode, run_episodes
from frictiongym.agents.evaluation.page import page
from frictiongym.agents.evaluation.stats import why_not_beats
from frictiongym.agents.figures import save_figure, smallest_text_px
from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.records import atomic_text, command_line, csv_text, git_commit, package_version
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.suites import Episode, load_suite, suite_names

REFERENCES = registry.REFERENCES  # Zero, Ideal, Oracle: run on every episode, never ranked
TOP = 5  # entries per set in the probability-of-improvement matrix


def classical(name: str) -> bool:
    """Built-in baselines (not the reference rows, not plug-ins or trained models)."""
    return name in registry.BUILTIN and name not in REFERENCES


def entry(name: str) -> bool:
    """A ranked row: anything but the reference rows."""
    return name not in REFERENCES


def conduct(row: dict) -> stats.Conduct:
    """What the rule reads of a summarized row (its metric means)."""
    return stats.Conduct.of({m: ci[0] for m, ci in row["metrics"].items()})


def point_of(rows: list[dict]) -> stats.Conduct | None:
    """A scenario's reference point (stats.reference_point) from its summarized rows: the uncompensated
    loop and TrackingLimit (Ideal where TrackingLimit does not apply); None without the loop."""
    loop = next((r for r in rows if r["uncompensated"]), None)
    if loop is None:
        return None
    return stats.point_with(conduct(loop), {r["controller"]: conduct(r) for r in rows})


def chatters(row: dict, point: stats.Conduct | None, scenario: Scenario) -> str:
    """Why a row is not a result on its scenario ("" if it is one, or without a reference point): the
    one rule (stats.why_not_result) every row meets, classical and learned. Only a classical row that is
    a result can be the scenario's baseline."""
    if point is None or row["uncompensated"]:
        return ""
    return "; ".join(stats.why_not_result(conduct(row), point, scenario.action_scale, scenario.settle_band))


def per_seed(rs: list[EpisodeResult], metric: str) -> dict[int, float]:
    """{seed: metric} of one controller's episodes on one scenario."""
    return {r.seed: r.metrics[metric] for r in rs}


@dataclass(frozen=True)
class Judgement:
    """The rows of the episodes that judge a run's rows (judging.py): the selection episodes' (classical
    rows and the reference point's) and the robustness set's with each episode's variant."""

    selection: list[EpisodeResult]
    robustness: list[EpisodeResult]
    variants: dict[Episode, str]


def selected_baselines(
    selection: list[EpisodeResult], scenarios: dict[str, Scenario], fragile: dict[tuple[str, str], str]
) -> dict[str, str | None]:
    """Each scenario's baseline chosen on its selection episodes: the classical row with the lowest mean
    main metric there among those that are results there (the rule against the point of the same
    episodes) and not fragile; None if none is."""
    out: dict[str, str | None] = {}
    for sc, table in summarize(selection, scenarios).items():
        ok = [r for r in table if classical(r["controller"]) and not r["chatters"]]
        ok = [r for r in ok if (sc, r["controller"]) not in fragile]
        out[sc] = ok[0]["controller"] if ok else None
    return out


def summarize(
    results: list[EpisodeResult], scenarios: dict[str, Scenario], judgement: Judgement | None = None
) -> dict[str, list[dict]]:
    """Per scenario, one row per controller (references included and marked), sorted by the mean main
    metric (see the module docstring). With a judgement, a row fragile on the robustness set is not a
    result, and the baseline is chosen on the selection episodes (selected_baselines); without one, on
    these results."""
    fragile = judging.fragile(judgement.robustness, judgement.variants, scenarios) if judgement else {}
    chosen = selected_baselines(judgement.selection, scenarios, fragile) if judgement else {}
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
                    "g_tracking": stats.mean_ci([r.g_tracking for r in rs]),
                    "score": stats.mean_ci([r.score for r in rs]),
                    "metrics": {m: stats.mean_ci([r.metrics[m] for r in rs]) for m in METRIC_NAMES},
                }
            )
        rows.sort(key=lambda r: r["main"][0] if math.isfinite(r["main"][0]) else math.inf)
        point = point_of(rows)
        for r in rows:
            why = [chatters(r, point, scenarios[sc]) if entry(r["controller"]) else "",
                   fragile.get((sc, r["controller"]), "")]  # fmt: skip
            r["chatters"] = "; ".join(filter(None, why))
        best = next((r["controller"] for r in rows if classical(r["controller"]) and not r["chatters"]), None)
        if judgement is not None:
            best = chosen.get(sc) if chosen.get(sc) in by_ctrl else None
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


def verdicts(table: dict[str, list[dict]], scenarios: dict[str, Scenario]) -> list[dict]:
    """For each controller that is not a built-in (plug-ins, trained models) on each scenario: does it beat
    the scenario's best classical baseline? It must lower the main metric with a paired 95 % interval of
    the per-episode difference below 0 and be a result by the rule every row meets (no chatter, saturation
    or limit cycle at rest beyond the scenario's reference point: stats.why_not_beats)."""
    out = []
    for sc, rows in table.items():
        base = next((r for r in rows if r["controller"] == r["baseline"]), None)
        point = point_of(rows)
        if base is None or point is None:
            continue
        s = scenarios[sc]
        for r in rows:
            if not entry(r["controller"]) or r["controller"] in registry.BUILTIN or r["vs_baseline"] is None:
                continue
            v = r["vs_baseline"]
            why = why_not_beats(v, conduct(r), point, s.action_scale, s.settle_band)
            out.append(
                {
                    "scenario": sc,
                    "controller": r["controller"],
                    "baseline": base["controller"],
                    "vs_baseline": v,
                    "roughness": r["metrics"]["command_roughness"][0],
                    "saturated": r["metrics"]["saturated_share"][0],
                    "rest_cycle": r["metrics"]["rest_oscillation"][0],
                    "point": point,
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


def responses(
    results: list[EpisodeResult],
    table: dict[str, list[dict]],
    scenarios: dict[str, Scenario],
    randomize: dict[str, bool],
    models: tuple[str, ...] = (),
) -> dict[str, list[EpisodeResult]]:
    """Per scenario, the best learned or plug-in entry (lowest mean main metric) and the best classical
    row that is a result (the baseline) on the median episode of the first of them, beside the
    uncompensated loop and Ideal (that loop without friction) on the same seed, re-run with logs: what
    each side does against what it improves on and the friction-free reference."""
    by: dict[tuple[str, str], dict[int, EpisodeResult]] = defaultdict(dict)
    for r in results:
        by[r.scenario, r.controller][r.seed] = r
    out = {}
    for sc, rows in table.items():
        main, loop = scenarios[sc].main_metric, scenarios[sc].uncompensated
        learned = next(
            (r["controller"] for r in rows if entry(r["controller"]) and not classical(r["controller"])), None
        )
        best = next((r["controller"] for r in rows if r["controller"] == r["baseline"]), None)
        lead = learned or best
        if lead is None:
            continue
        finite = sorted(
            (r.metrics[main], seed) for seed, r in by[sc, lead].items() if math.isfinite(r.metrics[main])
        )
        if not finite:
            continue
        seed = finite[(len(finite) - 1) // 2][1]  # the median episode (the lower one of an even count)
        names = [n for n in dict.fromkeys([learned, best, loop, "Ideal"]) if n is not None]
        picked = [by[sc, name][seed] for name in names if seed in by[sc, name]]
        out[sc] = with_logs(picked, randomize[sc], models)
    return out


def write(board: Board, out: Path) -> None:
    """leaderboard.csv, aggregate.csv, answer.md (the question per plant), the figures (PNG),
    leaderboard.md (linking them) and index.html (the page: page.py) into out, each
    atomically."""
    atomic_text(out / "leaderboard.csv", report.table_csv(board))
    atomic_text(out / "aggregate.csv", report.aggregate_csv(board.aggregate))
    atomic_text(out / "answer.md", report.answer(board))
    text_px = {}
    for name, fig in report.figures(board):
        text_px[name] = smallest_text_px(fig)
        save_figure(fig, out, name)
    names = list(text_px)
    md = report.markdown(board)
    atomic_text(out / "leaderboard.md", md + "\n" + "".join(f"![{f}]({f})\n" for f in names))
    provenance = {
        "frictiongym": package_version(),
        "commit": git_commit()[:12] or "n/a",
        "written": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "command": command_line(),
        "episodes": f"{len(board.results)} rows",
    }
    figures = {f: (out / f).read_bytes() for f in names}
    atomic_text(out / "index.html", page(board, figures, provenance, text_px))


def run(
    suite: str = "default",
    controllers: list[Any] | None = None,
    out: Path | None = None,
    progress: bool = True,
    workers: int = 1,
    episodes: list[Episode] | None = None,
    models: tuple[str, ...] = (),
    ray: engine.Ray | None = None,
    judge: bool = True,
) -> tuple[list[EpisodeResult], dict[str, list[dict]]]:
    """Evaluate (the suite, or the given episodes) with the reference rows (Zero, Ideal, Oracle) and each
    scenario's uncompensated loop always included, and summarize. `controllers`: names, a user's
    controllers as "module:attr" / "file.py:attr" specs or classes (registry.entries), or None for every
    default entry. With out: results go to
    out/episodes.csv incrementally (a rerun resumes), then leaderboard.md, leaderboard.csv (the tables),
    aggregate.csv (the per-plant aggregates) and PNG plots, each written atomically. Then the judging sets
    (judging.py) choose the baselines and find the fragile rows; judge=False skips them (a quick look: the
    baseline is chosen on these episodes, and the report says the run was not judged)."""
    controllers, models = registry.entries(controllers, models)
    available = registry.available(models)
    names = controllers or registry.default_entries(models)
    unknown = [n for n in names if n not in available]
    if hints := [h for h in map(registry.unknown_hint, unknown) if h]:
        raise ValueError("; ".join(hints))
    if unknown:
        raise ValueError(f"unknown controllers {unknown}; available: {list(available)}")
    episodes = episodes if episodes is not None else load_suite(suite)
    check_plugins(models, episodes)
    scenarios = {name: load_scenario(name) for name in dict.fromkeys(e.scenario for e in episodes)}
    loops = [s.uncompensated for s in scenarios.values()]  # g needs them on every episode
    names = list(dict.fromkeys([*REFERENCES, *loops, *names]))
    backend = (workers, progress, models, ray)
    results, skipped = _evaluate(names, episodes, out, *backend)
    judgement = None
    if judge:
        variants = judging.robustness_episodes(episodes, scenarios)
        picks, robust = judging.selection_episodes(episodes), list(variants)
        pickers = [*filter(classical, names), *stats.POINT_LIMITS]
        judgement = Judgement(
            _evaluate(pickers, picks, out and out / SELECTION, *backend)[0],
            _evaluate(list(filter(entry, names)), robust, out and out / ROBUSTNESS, *backend)[0],
            variants,
        )
    if out is not None and skipped:
        rows = [{"controller": n, "scenario": sc, "reason": why} for n, sc, why in skipped]
        atomic_text(out / "skipped.csv", csv_text(rows))
    if progress and skipped:
        where = f": {out / 'skipped.csv'} gives each with its reason" if out is not None else ""
        print(f"skipped {len(skipped)} (controller, scenario) pairs that do not apply{where}")
    return results, summarize_and_write(suite, episodes, results, models, out, judgement)


SELECTION, ROBUSTNESS = "selection", "robustness"  # a run's sub-folders for its judging episodes' rows


def _evaluate(
    names: list[str],
    episodes: list[Episode],
    out: Path | None,
    workers: int,
    progress: bool,
    models: tuple[str, ...],
    ray: engine.Ray | None,
) -> tuple[list[EpisodeResult], list[tuple[str, str, str]]]:
    """Every applicable (controller, episode) job, scored; with out, through out/episodes.csv (a rerun
    resumes: engine.evaluate_to). Returns the results and the skipped (controller, scenario, reason)."""
    if out is None:
        jobs, skipped = engine.plan(names, episodes, models)
        results: list[EpisodeResult] = []
        engine.run_jobs(jobs, workers, results.extend, progress, models, ray)
        return engine.canonical(results, jobs, engine.scoring(episodes)), skipped
    options = {"episodes": [asdict(e) for e in episodes], "controllers": names, "models": list(models)}
    return engine.evaluate_to(out, names, episodes, options, workers, progress, models, ray)


def check_plugins(sources: tuple[str, ...], episodes: list[Episode]) -> None:
    """One control period of each of the user's controllers (the "file.py:Class" and "module:Class"
    sources) on the first episode of each scenario it applies to, before any episode of the run: a wrong
    signature, an exception or a command that is not one finite real ends the run here, in one line
    naming the controller, scenario, seed and step (evaluate.ControllerError)."""
    firsts: dict[str, Episode] = {}
    for e in episodes:
        firsts.setdefault(e.scenario, e)
    envs = EnvCache()
    for spec in filter(registry.is_controller_spec, sources):
        make = registry.controller_factory(spec)
        for e in firsts.values():
            controller = make()
            if controller.why_not(envs.scenario(e)) is None:
                run_episodes(controller, [e], envs=envs, steps=1)


def summarize_and_write(
    suite: str,
    episodes: list[Episode],
    results: list[EpisodeResult],
    models: tuple[str, ...],
    out: Path | None,
    judgement: Judgement | None = None,
) -> dict[str, list[dict]]:
    """The tables of a run's results (judged by `judgement`: summarize) and, with out, its leaderboard.md,
    leaderboard.csv, aggregate.csv and plots written there."""
    scenarios = {name: load_scenario(name) for name in dict.fromkeys(e.scenario for e in episodes)}
    table = summarize(results, scenarios, judgement)
    if out is not None:
        randomize = {e.scenario: e.randomize for e in episodes}
        board = Board(
            suite,
            scenarios,
            results,
            table,
            aggregate(results, scenarios),
            verdicts(table, scenarios),
            {sc: penalty(results, s) for sc, s in scenarios.items()},
            responses(results, table, scenarios, randomize, models),
            registry.descriptions(models),
            registry.budgets(models),
            judged=judgement is not None,
        )
        out.mkdir(parents=True, exist_ok=True)
        write(board, out)
    return table


def report_from(src: Path, out: Path, allowed: tuple[str, ...] = ()) -> dict[str, list[dict]]:
    """The report of the finished run in src (engine.finished_run: read only, every episode checked)
    written to out, e.g. from read-only media; the tables. Nothing src names is imported or loaded unless
    `allowed` (what the command line names: model folders and plug-in specs) holds it too: a results
    folder is data (registry.allowed_sources)."""
    options, results, _ = engine.finished_run(src, allowed)
    episodes = [Episode.from_dict(e) for e in options["episodes"]]
    suite = next((name for name in suite_names() if load_suite(name) == episodes), "inline")
    scenarios = {name: load_scenario(name) for name in dict.fromkeys(e.scenario for e in episodes)}
    judgement = None
    if (src / SELECTION).exists():  # a run with --no-judging has no judging sets
        judgement = Judgement(
            engine.finished_run(src / SELECTION, allowed)[1],
            engine.finished_run(src / ROBUSTNESS, allowed)[1],
            judging.robustness_episodes(episodes, scenarios),
        )
    return summarize_and_write(suite, episodes, results, tuple(options["models"]), out, judgement)
