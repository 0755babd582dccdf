"""The evaluation engine: episodes are jobs (controller, scenario, seed, randomize, pinned params), run
serially or on a process pool, their rows written to DIR/episodes.csv as they finish.

- A worker builds each controller once and each env once per (scenario, controller hardware), and resets
  it per episode; every random quantity comes from the episode's seed, so a job's row is the same in any
  worker, in any order: a parallel run equals a serial one bit for bit.
- Rows are appended with one write and an fsync per finished chunk; on the next run with the same --out,
  finished jobs are skipped and a torn last line (a killed writer) is dropped. When the run completes the
  file is rewritten in canonical order (atomically: temporary file, then rename), so an interrupted and
  resumed run ends with the same file as a clean one.
- DIR/run.json records the run's options; a run with other options into the same DIR is refused.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from tqdm import tqdm

from frictiongym.agents import registry
from frictiongym.agents.evaluation.evaluate import (
    LOCKSTEP,
    EnvCache,
    EpisodeResult,
    params_text,
    run_episodes,
)
from frictiongym.agents.evaluation.stats import Scoring, attach_scores
from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.records import atomic_text, git_commit, package_version
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

PARENT_POLL_S = 0.5  # how often a pool worker checks that its parent is alive (s)
CHUNK = LOCKSTEP  # episodes per task, stepped together; a killed run loses little, the pool stays balanced
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "MUJOCO_NUM_THREADS")
FIELDS = (  # episodes.csv's columns: the job's identity (Job.key), the result, provenance
    "controller",
    "scenario",
    "seed",
    "randomize",
    "params",
    "return",
    "diverged",
    *METRIC_NAMES,
    "score",
    "g",
    "g_tracking",
    "controller_params",
    "env_id",
    "package_version",
    "git_commit",
    "row_digest",  # the first 16 hex digits of the SHA-256 of the row's other fields (row_digest)
)


@dataclass(frozen=True)
class Job:
    controller: str
    scenario: str
    seed: int
    randomize: bool
    params: str = ""  # pinned parameters as sorted JSON ("" = none)

    @property
    def episode(self) -> Episode:
        pinned = tuple(sorted(json.loads(self.params).items())) if self.params else ()
        return Episode(self.scenario, self.seed, self.randomize, pinned)

    def key(self) -> tuple[str, str, int, bool, str]:
        """The job's identity, as its result's (EpisodeResult.key)."""
        return (self.controller, self.scenario, self.seed, self.randomize, self.params)


def plan(
    controllers: list[str], episodes: list[Episode], models: tuple[str, ...] = ()
) -> tuple[list[Job], list[tuple[str, str, str]]]:
    """The jobs (episode-major, controllers in the given order) and the skipped (controller, scenario,
    reason) pairs of controllers not defined for a scenario."""
    envs, checks = EnvCache(), {name: registry.why_not(name, models) for name in controllers}
    jobs, skipped, seen = [], [], set()
    for e in episodes:
        for name, why_not in checks.items():
            reason = why_not(envs.scenario(e))
            if reason is None:
                jobs.append(Job(name, e.scenario, e.seed, e.randomize, params_text(e)))
            elif (name, e.scenario) not in seen:
                seen.add((name, e.scenario))
                skipped.append((name, e.scenario, reason))
    return jobs, skipped


def provenance() -> dict[str, str]:
    """Package version and git commit (if the code runs from a git checkout), for every row."""
    return {"package_version": package_version(), "git_commit": git_commit()}


# ------------------------------------------------------------------------------------------- workers
_CONTROLLERS: dict[str, Any] = {}
_ENVS = EnvCache()


class Interrupted(KeyboardInterrupt):
    """A stop asked by a signal other than Ctrl-C (SIGTERM), handled as Ctrl-C is."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _watch_parent(parent: int) -> None:
    """Exit this worker once its parent is gone (killed with SIGKILL, it cannot stop its pool): a
    worker blocked on its task queue would otherwise live on as an orphan, holding the parent's pipes."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def init_worker(parent: int | None = None) -> None:
    """A pool worker: one thread for BLAS, torch, JAX and MuJoCo (the pool is the parallelism); Ctrl-C
    left to the parent, which stops the pool; exits when `parent` (a pid) dies."""
    if "jax" not in sys.modules:  # read when JAX starts (sbx learners)
        one = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
        os.environ.setdefault("XLA_FLAGS", one)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    if parent is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def stop_workers() -> None:
    """Terminate this process's pool workers at once (an interrupted run keeps what it has written)."""
    children = multiprocessing.active_children()
    for p in children:
        p.terminate()
    for p in children:
        p.join(timeout=5)


def disk_error(e: OSError, out: Path) -> str:
    """One line for a file-system failure of a run writing into `out` (a full or read-only disk, a
    dangling --out link): what, where, and that what was finished stays there."""
    return f"error: {e.strerror or e}: {e.filename or out} (what was finished stays in {out})"


def one_line_errors(fn: Callable[[], int], out: Path) -> int:
    """fn()'s exit code, or one line on stderr for what a user can cause or meet: another run in `out`, a
    bad option, model or config (RunMismatch, ValueError: 2) or a file-system failure (disk_error: 1)."""
    try:
        return fn()
    except (RunMismatch, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(disk_error(e, out), file=sys.stderr)
        return 1


def run_interruptibly(fn: Callable[[], int], resume: str) -> int:
    """fn()'s exit code, with Ctrl-C (SIGINT) and SIGTERM stopping it within moments: every row
    finished before the signal stays where fn wrote it, the message says how to resume (`resume`), and
    the code is 128 + the signal's number, as a shell reports a process the signal ended."""

    def term(signum: int, _frame: Any) -> None:
        raise Interrupted(signum)

    old = signal.signal(signal.SIGTERM, term)
    try:
        return fn()
    except KeyboardInterrupt as e:
        signum = e.signum if isinstance(e, Interrupted) else signal.SIGINT
        print(f"\ninterrupted ({signal.Signals(signum).name}): {resume}", file=sys.stderr)
        return 128 + signum
    finally:
        signal.signal(signal.SIGTERM, old)


def run_chunk(jobs: list[Job], prov: dict[str, str], models: tuple[str, ...] = ()) -> list[EpisodeResult]:
    """The results of some jobs of one controller (a chunk), in this process, stepped together
    (evaluate.run_episodes); controllers and envs are cached per process; `models`: the saved-model
    folders the registry loads (registry.available)."""
    name = jobs[0].controller
    if any(j.controller != name for j in jobs):
        raise ValueError(f"a chunk runs one controller; got {sorted({j.controller for j in jobs})}")
    if name not in _CONTROLLERS:
        _CONTROLLERS[name] = registry.make(name, models)
    results = run_episodes(_CONTROLLERS[name], [j.episode for j in jobs], envs=_ENVS)
    for r in results:
        r.provenance = prov
    return results


def chunks(jobs: list[Job], size: int = CHUNK) -> list[list[Job]]:
    """Consecutive jobs of the same (scenario, randomize, controller), at most `size` each."""
    groups: dict[tuple, list[Job]] = {}
    for j in jobs:
        groups.setdefault((j.scenario, j.randomize, j.controller), []).append(j)
    return [g[i : i + size] for g in groups.values() for i in range(0, len(g), size)]


@dataclass(frozen=True)
class Ray:
    """Run the jobs as Ray tasks: on a local Ray instance with `workers` CPUs, or on the cluster at
    `address` ("auto", "ray://host:10001", "host:6379"). Results are the same rows as the local pool's
    (every job is a function of its seed); a task whose worker dies is retried (max_retries), and its rows
    are written once, by this process, when the task returns."""

    address: str | None = None
    max_retries: int = 3


def ray_init(workers: int, address: str | None) -> None:
    import ray

    if ray.is_initialized():
        return
    env = {"env_vars": dict.fromkeys(THREAD_VARS, "1")}  # one thread per task
    if address is None:  # local: no dashboard, nothing listening beyond loopback
        ray.init(num_cpus=workers, include_dashboard=False, runtime_env=env, log_to_driver=False)
    else:
        ray.init(address=address, runtime_env=env, log_to_driver=False)


def _run_chunk_ray(jobs: list[Job], prov: dict[str, str], models: tuple[str, ...]) -> list[EpisodeResult]:
    init_worker()
    return run_chunk(jobs, prov, models)


def run_jobs(
    jobs: list[Job],
    workers: int,
    on_rows: Callable[[list[EpisodeResult]], None],
    progress: bool = True,
    models: tuple[str, ...] = (),
    ray: Ray | None = None,
) -> None:
    """Run jobs (workers = 1: in this process; `ray`: as Ray tasks) and hand each finished chunk's results
    to on_rows."""
    prov = provenance()
    todo = chunks(jobs)
    bar = tqdm(total=len(jobs), desc="episodes", unit="ep", disable=not progress)
    if ray is not None:
        import ray as ray_

        ray_init(workers, ray.address)
        task = ray_.remote(num_cpus=1, max_retries=ray.max_retries)(_run_chunk_ray)
        pending = {task.remote(chunk, prov, models): len(chunk) for chunk in todo}
        try:
            while pending:
                done, _ = ray_.wait(list(pending), num_returns=1)
                for ref in done:
                    on_rows(ray_.get(ref))
                    bar.update(pending.pop(ref))
        except BaseException:  # stop the tasks still running or queued
            for ref in pending:
                ray_.cancel(ref, force=True)
            raise
        finally:
            bar.close()
        return
    if workers <= 1 or len(todo) <= 1:
        for chunk in todo:
            on_rows(run_chunk(chunk, prov, models))
            bar.update(len(chunk))
        bar.close()
        return
    saved = {v: os.environ.get(v) for v in THREAD_VARS}
    os.environ.update(dict.fromkeys(THREAD_VARS, "1"))  # inherited by the spawned workers
    pool = ProcessPoolExecutor(
        workers, mp_context=get_context("spawn"), initializer=init_worker, initargs=(os.getpid(),)
    )
    try:
        pending = {pool.submit(run_chunk, chunk, prov, models): len(chunk) for chunk in todo}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                on_rows(f.result())
                bar.update(pending.pop(f))
    except BaseException:  # Ctrl-C, SIGTERM, a failed job: stop now, not after every pending chunk
        pool.shutdown(wait=False, cancel_futures=True)
        stop_workers()
        raise
    finally:
        pool.shutdown()
        for v, old in saved.items():
            if old is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = old
        bar.close()


# ------------------------------------------------------------------------------------------- results
class RunMismatch(RuntimeError):
    """The output folder holds a run with other options."""


def csv_fields(r: EpisodeResult) -> dict[str, Any]:
    """A result as its episodes.csv row (FIELDS); floats as repr, so they read back exactly."""
    values = {
        "controller": r.controller,
        "scenario": r.scenario,
        "seed": r.seed,
        "randomize": r.randomize,
        "params": r.params,
        "return": r.episode_return,
        "diverged": r.diverged,
        **r.metrics,
        "score": r.score,
        "g": r.g,
        "g_tracking": r.g_tracking,
        "controller_params": r.controller_params,
        "env_id": r.env_id,
        **r.provenance,
    }
    text = {k: repr(v) if isinstance(v, float) else "" if v is None else str(v) for k, v in values.items()}
    out = {k: text.get(k, "") for k in FIELDS[:-1]}  # a result not run by the engine has no provenance
    out["row_digest"] = row_digest(out)
    return out


def row_digest(row: dict[str, str]) -> str:
    """A row's check value: the first 16 hex digits of the SHA-256 of its other fields' text, so a value
    changed on disk (a flipped `diverged`, a digit) is a row that is refused, not reused."""
    text = "\x1f".join(row[k] for k in FIELDS[:-1])
    return hashlib.sha256(text.encode("utf-8", errors="surrogatepass")).hexdigest()[:16]


MAX_ROW_BYTES = 64 * 1024  # a row is a few hundred bytes; one longer than this is junk, not a result


def _flag(text: str, field_name: str) -> bool:
    if text not in ("True", "False"):
        raise ValueError(f"field {field_name!r} must be True or False, got {text[:40]!r}")
    return text == "True"


def _number(row: dict[str, str], key: str, nan_ok: bool = True) -> float:
    """A float field: finite, or NaN where `nan_ok` (an undefined metric, an unscored row: written as nan
    or, by earlier versions, empty); never ±inf, which no metric or score takes."""
    text = row[key]
    try:
        x = float(text or "nan")
    except ValueError:
        raise ValueError(f"field {key!r} is not a number: {text[:40]!r}") from None
    if math.isinf(x) or (math.isnan(x) and not nan_ok):
        want = "a number or nan" if nan_ok else "finite"
        raise ValueError(f"field {key!r} must be {want}, got {text[:40]!r}")
    return x


def parse_row(row: dict[str, str]) -> EpisodeResult:
    """The result an episodes.csv row holds: the one reader of the file's rows (csv_fields inverted), every
    field checked (the names non-empty, the seed a non-negative integer, the flags True or False, numbers
    finite or an undefined nan, the return finite); a ValueError names the field."""
    for key in ("controller", "scenario", "env_id"):
        if not row[key]:
            raise ValueError(f"field {key!r} is empty")
    if not row["seed"].isdigit():
        raise ValueError(f"field 'seed' must be a non-negative integer, got {row['seed'][:40]!r}")
    result = EpisodeResult(
        controller=row["controller"],
        scenario=row["scenario"],
        seed=int(row["seed"]),
        metrics={m: _number(row, m) for m in METRIC_NAMES},
        episode_return=_number(row, "return", nan_ok=False),
        diverged=_flag(row["diverged"], "diverged"),
        score=_number(row, "score"),
        g=_number(row, "g"),
        g_tracking=_number(row, "g_tracking"),
        randomize=_flag(row["randomize"], "randomize"),
        params=row["params"],
        controller_params=row["controller_params"],
        env_id=row["env_id"],
        provenance={k: row[k] for k in ("package_version", "git_commit")},
    )
    if row["row_digest"] != row_digest(row):
        raise ValueError("field 'row_digest' does not match the row's values (changed after it was written)")
    return result


def _csv_text(results: Iterable[EpisodeResult], header: bool = False) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=FIELDS, lineterminator="\n")
    if header:
        w.writeheader()
    w.writerows(csv_fields(r) for r in results)
    return buf.getvalue()


def read_rows(path: Path) -> tuple[list[tuple[int, EpisodeResult]], list[tuple[int, str]]]:
    """episodes.csv's rows as (line, result), and the (line, why) of those that are not a result (a short
    or long row, binary junk, an oversized line, a value that does not parse or check); a last line
    without its newline is a torn write and not read. Each line is read on its own (a row never holds a
    newline), so no line can stop the reading of the others. Reads only."""
    if not path.exists():
        return [], []
    data = path.read_bytes()
    data = data[: data.rfind(b"\n") + 1]  # a torn last line is not read
    lines = data.split(b"\n")[:-1]
    if not lines:
        return [], []
    header = lines[0].decode("utf-8", errors="replace").split(",")
    if header != list(FIELDS):
        return [], [(1, f"the header is not episodes.csv's ({len(header)} columns)")]
    rows, refused = [], []
    for number, raw in enumerate(lines[1:], start=2):
        why = None
        if len(raw) > MAX_ROW_BYTES:
            why = f"a line of {len(raw)} bytes (a row is at most {MAX_ROW_BYTES})"
        elif b"\x00" in raw:
            why = "binary data (a NUL byte)"
        else:
            try:
                [values] = csv.reader([raw.decode("utf-8")])
            except (UnicodeDecodeError, csv.Error, ValueError) as e:
                why = f"not a CSV row of text ({type(e).__name__})"
            else:
                if len(values) != len(FIELDS):
                    why = f"{len(values)} fields where the header has {len(FIELDS)}"
                else:
                    try:
                        rows.append((number, parse_row(dict(zip(FIELDS, values, strict=True)))))
                    except ValueError as e:
                        why = str(e).split("\n")[0]
        if why is not None:
            refused.append((number, why))
    return rows, refused


def reusable(
    rows: list[tuple[int, EpisodeResult]], jobs: list[Job], prov: dict[str, str]
) -> tuple[list[EpisodeResult], list[tuple[int, str]]]:
    """The rows a run can reuse, and the (line, why) of the others: a row must be a job of this run
    (run.json's controllers and episodes), once, written by this code version (package version and
    commit: one run's rows come from one code), with a finite return and main metric unless it
    diverged."""
    planned = {j.key() for j in jobs}
    main = {j.scenario: load_scenario(j.scenario).main_metric for j in jobs}
    kept, seen, dropped = [], set(), []
    for line, r in rows:
        why = None
        if r.key() not in planned:
            why = "not an episode of this run's controllers and episodes (run.json)"
        elif r.key() in seen:
            why = "a second row for an episode already read"
        elif r.provenance != prov:
            why = f"written by another code version ({r.provenance}; this is {prov})"
        elif not r.diverged and not all(map(math.isfinite, (r.episode_return, r.metrics[main[r.scenario]]))):
            why = f"a non-finite return or {main[r.scenario]} in an episode that did not diverge"
        if why is None:
            kept.append(r)
            seen.add(r.key())
        else:
            dropped.append((line, why))
    return kept, dropped


def describe_dropped(path: Path, dropped: list[tuple[int, str]]) -> list[str]:
    """One line per reason: the file, the lines (the first five), why."""
    by_why: dict[str, list[int]] = {}
    for line, why in sorted(dropped):
        by_why.setdefault(why, []).append(line)
    out = []
    for why, lines in by_why.items():
        shown = ", ".join(map(str, lines[:5])) + (f" and {len(lines) - 5} more" if len(lines) > 5 else "")
        out.append(f"{path}: line {shown}: {why}")
    return out


class EpisodesFile:
    """DIR/episodes.csv and DIR/run.json (see the module docstring)."""

    def __init__(self, out: Path, options: dict[str, Any]):
        self.out, self.path = out, out / "episodes.csv"
        out.mkdir(parents=True, exist_ok=True)
        run = out / "run.json"
        text = json.dumps(options, indent=1, sort_keys=True)
        if run.exists() and json.loads(run.read_text()) != json.loads(text):
            raise RunMismatch(
                f"{out} holds a run with other options ({run}); use another --out or remove that folder"
            )
        if not run.exists():
            if self.path.exists():
                raise RunMismatch(f"{self.path} exists without {run}; use another --out or remove it")
            atomic_text(run, text + "\n")
        self.rows, self.refused = read_rows(self.path)
        self.results = [r for _, r in self.rows]

    def reconcile(self, jobs: list[Job], prov: dict[str, str]) -> None:
        """Keep the rows this run can reuse (`reusable`); every other row, and every row that does not
        parse, is named on stderr (file, lines, why), dropped from the file and re-run: never counted."""
        self.results, dropped = reusable(self.rows, jobs, prov)
        for line in describe_dropped(self.path, [*self.refused, *dropped]):
            print(f"{line}; re-run", file=sys.stderr)
        atomic_text(self.path, _csv_text(self.results, header=True))  # without a torn tail or dropped rows

    def done(self) -> set[tuple[str, str, int, bool, str]]:
        return {r.key() for r in self.results}

    def append(self, results: list[EpisodeResult]) -> None:
        """One write and an fsync for a finished chunk's results."""
        data = memoryview(_csv_text(results).encode())
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            while data:  # os.write may write less than asked (a full disk raises ENOSPC on the next call)
                data = data[os.write(fd, data) :]
            os.fsync(fd)
        finally:
            os.close(fd)
        self.results += results

    def finish(self, order: list[Job], scoring: dict[str, Scoring]) -> list[EpisodeResult]:
        """Fill in the scores; rewrite the file in the jobs' order (atomically); the results."""
        self.results = canonical(self.results, order, scoring)
        atomic_text(self.path, _csv_text(self.results, header=True))
        return self.results


def evaluate_to(
    out: Path,
    controllers: list[str],
    episodes: list[Episode],
    options: dict[str, Any],
    workers: int = 1,
    progress: bool = True,
    models: tuple[str, ...] = (),
    ray: Ray | None = None,
) -> tuple[list[EpisodeResult], list[tuple[str, str, str]]]:
    """Run every applicable (controller, episode) job not yet in DIR/episodes.csv; returns all results
    (in canonical order, scored) and the skipped (controller, scenario, reason) pairs. The backend
    (`workers`, `ray`) is not part of the run's options: a run can be resumed on another backend."""
    store = EpisodesFile(out, options)
    jobs, skipped = plan(controllers, episodes, models)
    store.reconcile(jobs, provenance())
    done = store.done()
    run_jobs([j for j in jobs if j.key() not in done], workers, store.append, progress, models, ray)
    return store.finish(jobs, scoring(episodes)), skipped


MAX_RUN_JSON_BYTES = 64 * 1024 * 1024  # the largest suite's run.json is a few hundred kB


def _pinned(kv: Any) -> bool:
    """A pinned parameter as run.json holds it: [name, number or structure name]."""
    return (
        isinstance(kv, list) and len(kv) == 2 and isinstance(kv[0], str) and type(kv[1]) in (int, float, str)
    )


def read_run_json(path: Path) -> dict[str, Any]:
    """A leaderboard run's run.json, checked before use: a mapping of its episodes (each a scenario name,
    a non-negative integer seed, a randomize flag and pinned parameters as [name, value] pairs), its
    controllers' names and its model sources (strings: data, resolved only where the command line allows
    them). Any other shape is one ValueError naming the file and what is wrong."""

    def bad(what: str) -> ValueError:
        return ValueError(f"{path}: {what}; not a leaderboard run's run.json")

    if path.stat().st_size > MAX_RUN_JSON_BYTES:
        raise bad(f"{path.stat().st_size} bytes")
    try:
        options = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        raise bad(f"not JSON ({type(e).__name__})") from None
    if not isinstance(options, dict) or set(options) != {"episodes", "controllers", "models"}:
        raise bad("expected a mapping of exactly episodes, controllers and models")
    for key in ("controllers", "models"):
        if not isinstance(options[key], list) or not all(isinstance(x, str) and x for x in options[key]):
            raise bad(f"{key} must be a list of names")
    if not isinstance(options["episodes"], list) or not options["episodes"]:
        raise bad("episodes must be a non-empty list")
    for i, e in enumerate(options["episodes"]):
        ok = (
            isinstance(e, dict)
            and set(e) == {"scenario", "seed", "randomize", "params"}
            and isinstance(e["scenario"], str)
            and type(e["seed"]) is int
            and e["seed"] >= 0
            and isinstance(e["randomize"], bool)
            and isinstance(e["params"], list)
            and all(_pinned(kv) for kv in e["params"])
        )
        if not ok:
            raise bad(f"episodes[{i}] is not a scenario, seed, randomize flag and pinned parameters")
    return options


def finished_run(
    src: Path, allowed: tuple[str, ...] = ()
) -> tuple[dict[str, Any], list[EpisodeResult], list[Job], list[tuple[str, str, str]]]:
    """A finished run's options (run.json), its results in canonical order and scored, its jobs and
    skipped pairs, read without writing anything into src (read-only media are fine): every planned job
    must have exactly one reusable row, or this names what is missing (resume the run first). The sources
    run.json names (model folders, plug-ins) are used only where `allowed` names them too."""
    run, path = src / "run.json", src / "episodes.csv"
    if not run.is_file() or not path.is_file():
        raise RunMismatch(f"{src} holds no finished run (run.json and episodes.csv)")
    options = read_run_json(run)
    episodes = [Episode.from_dict(e) for e in options["episodes"]]
    models = registry.allowed_sources(tuple(options["models"]), allowed, str(run))
    jobs, skipped = plan(options["controllers"], episodes, models)
    rows, refused = read_rows(path)
    results, dropped = reusable(rows, jobs, provenance())
    missing = len(jobs) - len(results)
    if refused or dropped or missing:
        lines = describe_dropped(path, [*refused, *dropped])
        raise RunMismatch(
            f"{src} is not a finished run of this code: {missing} of {len(jobs)} episodes missing"
            + (f" ({'; '.join(lines)})" if lines else "")
            + "; resume it first (the same command with that --out)"
        )
    return options, canonical(results, jobs, scoring(episodes)), skipped


def scoring(episodes: list[Episode]) -> dict[str, Scoring]:
    """Each scenario's Scoring (stats.attach_scores), from its YAML."""
    out = {}
    for name in {e.scenario for e in episodes}:
        sc = load_scenario(name)
        out[name] = Scoring(sc.main_metric, sc.uncompensated, sc.limit_score, sc.settle_band)
    return out


def canonical(
    results: list[EpisodeResult], order: list[Job], scoring: dict[str, Scoring]
) -> list[EpisodeResult]:
    """The results in the jobs' order, scored (stats.attach_scores)."""
    rank = {j.key(): i for i, j in enumerate(order)}
    results = sorted(results, key=lambda r: rank.get(r.key(), len(rank)))
    attach_scores(results, scoring)
    return results
