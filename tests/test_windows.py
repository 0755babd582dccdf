"""Window metrics (agents/evaluation/windows.py, scripts/windows.py): where along an episode a controller
breaks."""

import csv

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.evaluation.evaluate import run_episode
from frictiongym.agents.evaluation.windows import controller_windows, window_metrics
from frictiongym.envs.suites import Episode
from frictiongym.scripts import windows as windows_script


def test_windows_cut_the_metric_samples_and_the_last_sample_joins_the_last_window():
    """The reset sample (t = 0) is left out as the episode metrics leave it out; samples at 0.5, 1.0, 1.5
    and 2.0 s in windows of 1 s: [0, 1) holds 0.5, [1, 2] holds 1.0, 1.5 and the final 2.0."""
    log = {
        "t": np.array([0.0, 0.5, 1.0, 1.5, 2.0]),
        "reference": np.zeros(5),
        "output": np.array([9.0, 1.0, -2.0, 2.0, 2.0]),
        "command": np.array([9.0, 3.0, 1.0, -1.0, 1.0]),
        "velocity": np.zeros(5),
    }
    w = window_metrics(log, 1.0)
    assert [(x["window_start_s"], x["window_end_s"], x["samples"]) for x in w] == [(0, 1, 1), (1, 2, 3)]
    assert [x["effort_rms"] for x in w] == [3.0, 1.0]
    assert [x["mean_abs_error"] for x in w] == [1.0, 2.0]
    with pytest.raises(ValueError, match="window_s must be > 0"):
        window_metrics(log, 0.0)
    with pytest.raises(ValueError, match="at least the sampling period"):
        window_metrics(log, 0.4)  # samples 0.5 s apart: a window could hold none


def test_windows_add_up_to_the_episode_metrics():
    """Over a real episode the windows partition the metrics' samples: the sample-weighted mean of the
    windows' squared command rms is the episode's effort_rms², and their |error| sums times the control
    period make the episode's IAE (rectangle rule, envs/metrics.py)."""
    e = Episode("flexible_chirp", 800000, True)
    r = run_episode(registry.make("PID"), e, keep_log=True)
    w = window_metrics(r.log, 2.5)
    n = np.array([x["samples"] for x in w])
    assert len(w) == 8 and n.sum() == len(r.log["t"]) - 1
    rms2 = np.sum(n * np.array([x["effort_rms"] for x in w]) ** 2) / n.sum()
    assert rms2 == pytest.approx(r.metrics["effort_rms"] ** 2, rel=1e-12)
    dt = r.log["t"][2] - r.log["t"][1]
    iae = dt * np.sum(n * np.array([x["mean_abs_error"] for x in w]))
    assert iae == pytest.approx(r.metrics["iae"], rel=1e-9)


def test_controller_windows_average_episodes_of_one_scenario():
    episodes = [Episode("flexible_chirp", s, True) for s in (800000, 800001)]
    pid = registry.make("PID")
    rows = controller_windows(pid, episodes, 5.0)
    each = [window_metrics(run_episode(pid, e, keep_log=True).log, 5.0) for e in episodes]
    assert [r["episodes"] for r in rows] == [2] * 4
    # the chirp's band per window: 0.02 Hz at 0 s, + 0.049 Hz/s (configs/scenarios/flexible_chirp.yaml)
    assert [r["frequency_hz_start"] for r in rows] == pytest.approx([0.02, 0.265, 0.51, 0.755])
    assert rows[-1]["frequency_hz_end"] == pytest.approx(1.0)
    for i, row in enumerate(rows):
        assert row["effort_rms"] == pytest.approx((each[0][i]["effort_rms"] + each[1][i]["effort_rms"]) / 2)
    with pytest.raises(ValueError, match="one scenario"):
        controller_windows(pid, [episodes[0], Episode("flexible_scurve", 800000, True)], 5.0)


def test_the_script_writes_the_table_and_refuses_what_cannot_be_windowed(tmp_path, capsys):
    """A controller that does not apply to the scenario, or a window shorter than the control period
    (it could hold no sample), is an error naming it."""
    out = tmp_path / "w"
    args = ["--scenario", "flexible_chirp", "--seeds", "800000", "--window-s", "5", "--out", str(out)]
    assert windows_script.main([*args, "--controllers", "PID", "LuGreObserver"]) == 0
    rows = list(csv.DictReader((out / "windows.csv").open()))
    assert [r["controller"] for r in rows] == ["PID"] * 4 + ["LuGreObserver"] * 4
    assert (out / "windows.png").is_file() and "mean |error|" in capsys.readouterr().out
    assert windows_script.main([*args, "--controllers", "RDFC"]) == 2
    assert "RDFC does not apply to flexible_chirp" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        windows_script.main([*args[:-4], "--window-s", "0.01", "--out", str(out)])
    assert "--window-s must be at least the control period, 0.04 s" in capsys.readouterr().err
