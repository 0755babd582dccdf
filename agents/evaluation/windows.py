"""Where along an episode a controller breaks: the command's rms and the mean absolute tracking error in
consecutive time windows, averaged over episodes (`scripts/windows.py`).

The leaderboard's metrics are whole-episode figures; on a reference whose character changes along the
episode (a chirp's frequency sweeps linearly, configs/scenarios/flexible_chirp.yaml) they cannot say where
a controller falls behind. Window k covers [k·w, (k+1)·w) s of the logged samples; the units are the
scenario's: the command's (V or N·m) and the measured output's (rad, m, or V for a tachometer).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from frictiongym.agents.base import Controller
from frictiongym.agents.evaluation.evaluate import EnvCache, run_episodes
from frictiongym.agents.figures import save_figure
from frictiongym.envs.metrics import from_first_period
from frictiongym.envs.records import pyplot
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

FIELDS = [
    "controller",
    "scenario",
    "window_start_s",
    "window_end_s",
    "frequency_hz_start",
    "frequency_hz_end",
    "episodes",
    "effort_rms",
    "mean_abs_error",
]


def window_metrics(log: dict[str, np.ndarray], window_s: float) -> list[dict[str, float]]:
    """Per window of window_s seconds of an episode log (run_episode(keep_log=True)), over the samples the
    episode's metrics use (envs.metrics.from_first_period): its start and end (s of episode time), the
    command's rms and the mean |output - reference|. The episode is cut into round(T / window_s) windows
    from t = 0 (at least one; T its last sample's time): a trailing piece shorter than half a window, such
    as the final sample, joins the window before it, whose end is then T."""
    if not window_s > 0:
        raise ValueError(f"window_s must be > 0 s, got {window_s}")
    g = from_first_period(log)
    t = np.asarray(g["t"], float)
    period = float(np.max(np.diff(t), initial=0.0))
    if window_s < period:  # a window could hold no sample
        raise ValueError(f"window_s ({window_s} s) must be at least the sampling period ({period:g} s)")
    n = max(1, round(t[-1] / window_s))
    # 1e-9: a sample on a window edge opens the next window
    k = np.minimum(np.floor(t / window_s + 1e-9).astype(int), n - 1)
    error = np.abs(np.asarray(g["output"], float) - np.asarray(g["reference"], float))
    command = np.asarray(g["command"], float)
    return [
        {
            "window_start_s": i * window_s,
            "window_end_s": float(t[-1]) if i == n - 1 else (i + 1) * window_s,
            "samples": int(np.count_nonzero(k == i)),
            "effort_rms": float(np.sqrt(np.mean(command[k == i] ** 2))),
            "mean_abs_error": float(np.mean(error[k == i])),
        }
        for i in range(n)
    ]


def controller_windows(
    controller: Controller, episodes: Sequence[Episode], window_s: float, envs: EnvCache | None = None
) -> list[dict[str, Any]]:
    """One controller on every episode (one scenario), its window metrics averaged over the episodes; with
    the reference's frequency (Hz) at each window's start and end (a chirp's band; nan without one)."""
    scenarios = {e.scenario for e in episodes}
    if len(scenarios) != 1:
        raise ValueError(f"the episodes must share one scenario, got {sorted(scenarios)}")
    envs = envs or EnvCache()
    # the one evaluation loop, episodes of one env stepped together (each result the episode's alone)
    runs = run_episodes(controller, list(episodes), keep_log=True, envs=envs)
    per_episode = [window_metrics(r.log, window_s) for r in runs]
    n = min(len(w) for w in per_episode)  # the same duration for every episode of a scenario
    reference = load_scenario(episodes[0].scenario).reference
    return [
        {
            "controller": controller.name,
            "scenario": episodes[0].scenario,
            "window_start_s": per_episode[0][i]["window_start_s"],
            "window_end_s": per_episode[0][i]["window_end_s"],
            "frequency_hz_start": float(reference.frequency_hz_at(per_episode[0][i]["window_start_s"])),
            "frequency_hz_end": float(reference.frequency_hz_at(per_episode[0][i]["window_end_s"])),
            "episodes": len(episodes),
            "effort_rms": float(np.mean([w[i]["effort_rms"] for w in per_episode])),
            "mean_abs_error": float(np.mean([w[i]["mean_abs_error"] for w in per_episode])),
        }
        for i in range(n)
    ]


def plot_windows(rows: Sequence[dict[str, Any]], out: Any, fname: str = "windows.png") -> str:
    """The command's rms and the mean |error| per window (x: the window's middle, s), one line per
    controller, as out/fname; returns the file name."""
    plt = pyplot()

    fig, (ax_e, ax_u) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name in dict.fromkeys(r["controller"] for r in rows):
        mine = [r for r in rows if r["controller"] == name]
        mid = [(r["window_start_s"] + r["window_end_s"]) / 2 for r in mine]
        ax_e.plot(mid, [r["mean_abs_error"] for r in mine], marker="o", label=name)
        ax_u.plot(mid, [r["effort_rms"] for r in mine], marker="o", label=name)
    ax_e.set_ylabel("mean |error| (output units)")
    ax_u.set_ylabel("command rms (V or N·m)")
    ax_u.set_xlabel("time in the episode (s), window middle")
    ax_e.set_title(f"{rows[0]['scenario']}: {rows[0]['episodes']} episodes per controller")
    ax_e.legend(fontsize=7)
    return save_figure(fig, out, fname)
