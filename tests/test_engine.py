"""The evaluation engine: jobs, serial == parallel, incremental and resumable results, applicability."""

import csv
import hashlib
import io
import json
import math
import shutil
from dataclasses import asdict
from importlib.metadata import EntryPoint

import pytest

from frictiongym.agents import registry
from frictiongym.agents.base import Zero
from frictiongym.agents.evaluation import engine
from frictiongym.agents.learned.convert import convert_folder
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

EPISODES = [
    Episode(s, seed, True) for s in ("kang_regulation", "flexible_speed_step") for seed in (11, 12, 13)
]
CONTROLLERS = ["Zero", "PD", "RDFC", "SF"]
OPTIONS = {"test": "engine"}


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    rows, skipped = engine.evaluate_to(out, CONTROLLERS, EPISODES, OPTIONS, workers=1, progress=False)
    return out, rows, skipped


def test_applicability_skips_with_a_reason_and_never_crashes(serial):
    _, rows, skipped = serial
    assert {(r.controller, r.scenario) for r in rows} == {
        ("Zero", "kang_regulation"), ("PD", "kang_regulation"), ("RDFC", "kang_regulation"),
        ("Zero", "flexible_speed_step"), ("SF", "flexible_speed_step"),
    }  # fmt: skip
    reasons = {(c, s): why for c, s, why in skipped}
    assert "tachometers" in reasons[("SF", "kang_regulation")]
    assert "encoder" in reasons[("PD", "flexible_speed_step")]  # PD needs a position sensor


@pytest.mark.slow  # a process pool
def test_parallel_run_equals_serial_bit_for_bit(serial, tmp_path):
    out, _, _ = serial
    engine.evaluate_to(tmp_path, CONTROLLERS, EPISODES, OPTIONS, workers=2, progress=False)
    assert (tmp_path / "episodes.csv").read_bytes() == (out / "episodes.csv").read_bytes()


def test_killed_run_resumes_to_the_same_file(serial, tmp_path):
    out, _, _ = serial
    lines = (out / "episodes.csv").read_text().splitlines(keepends=True)
    shutil.copy(out / "run.json", tmp_path / "run.json")
    (tmp_path / "episodes.csv").write_text("".join(lines[:4]) + lines[4][:25])  # 3 rows + a torn write
    rows, _ = engine.evaluate_to(tmp_path, CONTROLLERS, EPISODES, OPTIONS, workers=1, progress=False)
    assert (tmp_path / "episodes.csv").read_bytes() == (out / "episodes.csv").read_bytes()
    assert len(rows) == len(lines) - 1


def _corrupt(line: str, field: str, value: str) -> str:
    """An episodes.csv line with one field replaced."""
    values = next(csv.reader([line]))
    if field == "main":  # the episode's scenario's main metric
        field = load_scenario(values[engine.FIELDS.index("scenario")]).main_metric
    values[engine.FIELDS.index(field)] = value
    values[-1] = engine.row_digest(dict(zip(engine.FIELDS, values, strict=True)))  # as a writer of it would
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def _flip(line: str, field: str) -> str:
    """An episodes.csv line with one field changed and nothing else (its digest not rewritten): a
    True/False flag flipped, a number's last digit moved by one."""
    values = next(csv.reader([line]))
    i = engine.FIELDS.index(field)
    v = values[i]
    flags = {"True": "False", "False": "True"}
    values[i] = flags[v] if v in flags else v[:-1] + str((int(v[-1]) + 1) % 10)
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


@pytest.mark.parametrize(
    ("corrupt", "why"),
    [
        (lambda ls: [*ls[:2], _corrupt(ls[2], "main", "nan"), *ls[3:]], "a non-finite return or"),
        (lambda ls: [*ls, ls[3]], "a second row"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "git_commit", "0" * 40), *ls[3:]], "another code version"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "seed", "9999"), *ls[3:]], "not an episode of this run"),
        (lambda ls: [*ls[:2], ls[2].rsplit(",", 3)[0] + "\n", *ls[3:]], "fields where the header has"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "diverged", "maybe"), *ls[3:]], "must be True or False"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "seed", "11.5"), *ls[3:]], "'seed' must be a non-negative"),
        (lambda ls: [*ls[:2], "\x00\xff garbage \x01\n", *ls[3:]], "binary data (a NUL byte)"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "ise", "inf"), *ls[3:]], "'ise' must be a number or nan"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "params", "x" * 200_000), *ls[3:]], "a line of 20"),
        (lambda ls: [*ls[:2], '"unclosed, quote' + ls[2][15:], *ls[3:]], "fields where the header has"),
        (lambda ls: [*ls[:2], _corrupt(ls[2], "controller", ""), *ls[3:]], "'controller' is empty"),
        # a value changed on disk, the row's digest not rewritten: a flipped flag, one digit
        (lambda ls: [*ls[:2], _flip(ls[2], "diverged"), *ls[3:]], "'row_digest' does not match"),
        (lambda ls: [*ls[:2], _flip(ls[2], "return"), *ls[3:]], "'row_digest' does not match"),
    ],
)
def test_a_resumed_row_that_cannot_be_reused_is_named_and_rerun(serial, tmp_path, capsys, corrupt, why):
    """A reused row must be a job of run.json, once, from this code version, with finite values where
    the episode did not diverge; any other row (or one that does not parse) is named on stderr with the
    file, the line and why, dropped and re-run: the file ends as the clean run's, never miscounted."""
    out, _, _ = serial
    lines = (out / "episodes.csv").read_text().splitlines(keepends=True)
    shutil.copy(out / "run.json", tmp_path / "run.json")
    (tmp_path / "episodes.csv").write_text("".join(corrupt(lines)))
    rows, _ = engine.evaluate_to(tmp_path, CONTROLLERS, EPISODES, OPTIONS, workers=1, progress=False)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{tmp_path / 'episodes.csv'}: line ") and why in err[0], err
    assert (tmp_path / "episodes.csv").read_bytes() == (out / "episodes.csv").read_bytes()
    assert len(rows) == len(lines) - 1


def test_other_options_into_the_same_folder_are_refused(serial):
    out, _, _ = serial
    with pytest.raises(engine.RunMismatch, match="other options"):
        engine.evaluate_to(out, ["Zero"], EPISODES, {"test": "other"}, progress=False)


def test_rows_carry_metrics_and_provenance(serial):
    out, rows, _ = serial
    header = (out / "episodes.csv").read_text().splitlines()[0]
    assert tuple(header.split(",")) == engine.FIELDS
    r = rows[0]
    assert r.provenance["package_version"] and r.metrics["iae"] > 0
    assert r.env_id.startswith("frictiongym/") and json.loads(r.controller_params) == {}  # Zero: no params


def test_a_result_reads_back_from_its_csv_row_exactly(serial):
    """episodes.csv holds each EpisodeResult as one row (engine.csv_fields) and parse_row, the file's one
    reader, gives it back field for field: the floats (repr), nan metrics, the flags, the scores."""
    out, rows, _ = serial
    back = [engine.parse_row(r) for r in csv.DictReader((out / "episodes.csv").read_text().splitlines())]
    assert [repr(asdict(r)) for r in back] == [repr(asdict(r)) for r in rows]  # types and bits; nan == nan
    assert any(math.isnan(v) for r in rows for v in r.metrics.values())  # nan is read back as nan...
    assert [r.score for r in back if r.controller == "Zero"] == [0.0] * 6  # and a score is a float
    row = {k: str(v) for k, v in engine.csv_fields(rows[0]).items()}
    with pytest.raises(ValueError, match="'diverged' must be True or False"):
        engine.parse_row({**row, "diverged": "yes"})


def test_entry_point_controllers_are_registered(monkeypatch):
    ep = EntryPoint(name="MyZero", value="frictiongym.agents.base:Zero", group=registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry, "entry_points", lambda group: [ep] if group == ep.group else [])
    registry._available.cache_clear()  # the registry is built once per process; this test changes it
    assert isinstance(registry.make("MyZero"), Zero)
    with pytest.raises(ValueError, match="unknown controllers"):
        registry.make("Nobody")
    registry._available.cache_clear()


@pytest.mark.slow  # trains a model
def test_saved_model_is_an_entry_and_a_mismatched_scenario_is_skipped_with_its_reason(tmp_path):
    from stable_baselines3 import PPO

    from frictiongym.agents.evaluation import leaderboard
    from frictiongym.envs.servo_env import ServoEnv

    sb3 = tmp_path / "sb3" / "ppo_kang"
    sb3.mkdir(parents=True)
    PPO("MlpPolicy", ServoEnv("kang_regulation"), n_steps=64, seed=0, device="cpu").save(sb3 / "model.zip")
    (sb3 / "manifest.yaml").write_text("name: PPO-kang\nalgorithm: PPO\nmodel: model.zip\n")
    folder = convert_folder(sb3, tmp_path / "models", trust_pickle=True)
    episodes = [Episode("kang_regulation", 5, True), Episode("m220_reversal_tracking", 5, True)]
    out = tmp_path / "lb"
    models = (tmp_path / "models",)
    leaderboard.run("inline", ["PD", "PPO-kang"], out, False, 1, episodes, models, judge=False)
    rows = list(csv.DictReader((out / "episodes.csv").read_text().splitlines()))
    model_rows = [r for r in rows if r["controller"] == "PPO-kang"]
    assert [r["scenario"] for r in model_rows] == ["kang_regulation"]  # 3 observations there, 9 on the M220
    assert (
        json.loads(model_rows[0]["controller_params"])["model_sha256"]
        == hashlib.sha256((folder / "policy.safetensors").read_bytes()).hexdigest()
    )
    _, skipped = engine.plan(["PPO-kang"], episodes, (str(tmp_path / "models"),))
    assert skipped == [
        ("PPO-kang", "m220_reversal_tracking", "the model observes shape (3,), the scenario gives (9,)")
    ]
    with pytest.raises(ValueError, match=r"no manifest\.yaml"):
        registry.available((tmp_path / "lb",))


@pytest.mark.slow
def test_sigkill_then_resume_gives_the_clean_runs_file(tmp_path):
    """A real kill: the leaderboard script is SIGKILLed once some rows are on disk; rerunning the same
    command finishes the run, and episodes.csv equals a clean run's byte for byte."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    script = str(Path(__file__).parents[1] / "scripts" / "leaderboard.py")
    args = ["--scenarios", "flexible_speed_step_fast", "--seeds", "1-6", "--randomize"]
    args += ["--controllers", "PID", "SF", "--workers", "1"]
    killed, clean = tmp_path / "killed", tmp_path / "clean"
    proc = subprocess.Popen([sys.executable, script, *args, "--out", str(killed)], stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        f = killed / "episodes.csv"
        if f.exists() and f.read_text().count("\n") >= 3:  # header + at least 2 finished rows
            break
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    partial = (killed / "episodes.csv").read_text().count("\n") - 1
    assert 2 <= partial < 18  # 6 seeds x (Zero, PID, SF): killed mid-run
    for out in (killed, clean):
        run = subprocess.run(
            [sys.executable, script, *args, "--out", str(out)], capture_output=True, timeout=600
        )
        assert run.returncode == 0, run.stderr
    assert (killed / "episodes.csv").read_bytes() == (clean / "episodes.csv").read_bytes()


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("{not json", "not JSON (JSONDecodeError)"),
        ("[1, 2]", "expected a mapping of exactly episodes, controllers and models"),
        ('{"episodes": [], "controllers": [], "models": []}', "episodes must be a non-empty list"),
        ('{"episodes": [{"scenario": "kang_ramp", "seed": 1, "randomize": true, "params": [], "x": 1}], '
         '"controllers": ["PD"], "models": []}', "episodes[0] is not"),
        ('{"episodes": [{"scenario": "kang_ramp", "seed": "1", "randomize": true, "params": []}], '
         '"controllers": ["PD"], "models": []}', "episodes[0] is not"),
        ('{"episodes": [{"scenario": "kang_ramp", "seed": 1, "randomize": true, "params": []}], '
         '"controllers": [["PD"]], "models": []}', "controllers must be a list of names"),
        ("[" * 100_000, "not JSON"),
    ],
)
def test_a_run_json_that_is_not_one_is_named_in_one_line(tmp_path, capsys, text, why):
    """--report-from reads run.json by schema before using anything in it: bad JSON, another shape, an
    episode with another key or type end in one line naming the file (exit 2), nothing written."""
    from frictiongym.scripts import cli

    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(text)
    (run / "episodes.csv").write_text(",".join(engine.FIELDS) + "\n")
    assert cli.main(["leaderboard", "--report-from", str(run), "--models", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith(f"error: {run / 'run.json'}: ") and why in err, err
    assert not (tmp_path / "r").exists()
