"""One training run (config, scenario, seed) into a model folder, resumable; many runs on a process pool;
the exported folder the leaderboard loads."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import multiprocessing as mp
import os
import shutil
import sys
import time
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.engine import init_worker, provenance, stop_workers
from frictiongym.agents.evaluation.evaluate import EnvCache
from frictiongym.agents.evaluation.stats import why_not_beats
from frictiongym.agents.learned.folder import seal
from frictiongym.agents.learned.manifest import MANIFEST, MODEL, NORMALIZER, Manifest
from frictiongym.agents.learned.policy import algorithm_class
from frictiongym.envs.config import (
    ConfigError,
)
from frictiongym.envs.records import atomic_text, atomic_write, command_line, csv_text, pyplot
from frictiongym.envs.scenario import load_scenario

from ..base import ZERO
from ..figures import save_figure
from ..registry import base_controller
from .config import VALIDATION_SUITE, RunConfig
from .env import make_training_env
from .model import build_model
from .validation import (
    Baseline,
    PendingEvaluation,
    Snapshot,
    best_classical,
    classical_rows,
    evaluate_controller,
    evaluate_snapshot,
    gradient_steps,
    means,
    reference_point,
    validation_episodes,
)
from .vec_env import SEEDS_PER_RUN, TRAINING_SEEDS

VALIDATION_CSV = "validation.csv"  # a run's validation rows, one per evaluation
STATE, LATEST, REPLAY_BUFFER = "state.json", "LATEST", "replay_buffer.pkl"  # a checkpoint's files


class NothingSelected(RuntimeError):
    """A run none of whose validation evaluations met the effort rule: no model, a result to report."""


class TrainingRun:
    """One (config, scenario, seed) run into `out`, resumable from out/checkpoint."""

    def __init__(
        self,
        cfg: RunConfig,
        seed: int,
        out: Path,
        command: str,
        progress: bool = True,
        parallel_validation: bool = False,
    ):
        self.cfg, self.seed, self.out, self.command, self.progress = cfg, seed, Path(out), command, progress
        # validation in a worker process on the other core (scripts/train.py's runs), with the same results
        # as in turn (the same saved snapshot is evaluated). The worker is spawned: a calling script needs
        # multiprocessing's `if __name__ == "__main__":` guard; a daemonic pool worker may not have children.
        self.parallel_validation = parallel_validation and not mp.current_process().daemon
        self.pool: ProcessPoolExecutor | None = None
        self.pending: list[PendingEvaluation] = []
        self.name = f"{cfg.name}-{cfg.scenario}-s{seed}"  # unique across a config's scenarios
        # the selection scenarios and their episodes: the scenario's own, then validation.scenarios'
        self.scenarios = {sc: load_scenario(sc) for sc in (cfg.scenario, *cfg.eval_scenarios)}
        self.groups = {sc: validation_episodes(sc)[: cfg.eval_episodes] for sc in self.scenarios}
        for sc, episodes in self.groups.items():
            if not episodes:
                field = "scenario" if sc == cfg.scenario else "validation.scenarios"
                raise ConfigError(field, f"{sc} is not in the {VALIDATION_SUITE} suite", cfg.source)
            if len(episodes) < cfg.eval_episodes:  # never select on fewer episodes than asked, silently
                raise ConfigError(
                    "validation.episodes",
                    f"{cfg.eval_episodes} asked, the {VALIDATION_SUITE} suite has {len(episodes)} of {sc}",
                    cfg.source,
                )
        self.episodes = self.groups[cfg.scenario]
        self.main = self.scenarios[cfg.scenario].main_metric
        self.envs = EnvCache()
        self.history: list[dict[str, float]] = []
        self.best: dict[str, float] | None = None
        self.next_eval = cfg.eval_every_steps
        self.wall_before, self.stopped_early = 0.0, False
        self.eval_s = 0.0  # wall time the training waited for validation (train_s = elapsed - eval_s)
        self.stop_after_train_s: float | None = None  # also stop after this much training time (bench)
        self.reporter: Callable[[dict[str, float]], None] | None = None  # e.g. Ray Tune's report
        self.logger: Any = None  # the model's logger (validation metrics to TensorBoard)
        self.last_snapshot: Snapshot | None = None  # the model of the latest validation (the checkpoint's)
        self.best_files: dict[str, Any] = {}  # the selected model's manifest fields (Snapshot.write_model)
        # the code that trains the model: package version and commit when the run starts (a resumed run
        # keeps its first start's, train); read before the baselines' evaluation, which takes a while
        self.prov: dict[str, str] = provenance()

    def elapsed(self) -> float:
        return self.wall_before + time.monotonic() - self.t0

    # ----------------------------------------------------------------------------- evaluation
    def train_s(self) -> float:
        """Wall time spent training (learning and env stepping), waits for validation excluded."""
        return self.elapsed() - self.eval_s

    def validate(self, model: Any) -> Snapshot:
        """Start the evaluation of the model as it is now (a saved snapshot, in the validation worker, or
        here); collect() records it. Returns the snapshot (the checkpoint's model)."""
        t0 = time.monotonic()
        snap = Snapshot.of(model)
        job = (self.cfg, self.name, snap, self.groups)
        if self.parallel_validation:
            if self.pool is None:
                self.pool = ProcessPoolExecutor(
                    1, mp.get_context("spawn"), initializer=init_worker, initargs=(os.getpid(),)
                )
            result = self.pool.submit(evaluate_snapshot, *job)
        else:
            result = Future()
            result.set_result(evaluate_snapshot(*job))
        meta = {"step": model.num_timesteps, "gradient_steps": gradient_steps(model)}
        self.eval_s += time.monotonic() - t0
        meta |= {"wall_s": round(self.elapsed(), 1), "train_s": round(self.train_s(), 1)}
        self.pending.append(PendingEvaluation(meta, snap, result))
        self.collect(block=False)
        return snap

    def collect(self, block: bool) -> None:
        """Record the finished evaluations in order (all of them, waiting, if block)."""
        while self.pending and (block or self.pending[0].result.done()):
            p = self.pending.pop(0)
            t0 = time.monotonic()
            try:
                m = p.result.result()
            except BrokenProcessPool:  # the worker died (e.g. killed): validate here from now on
                print(f"{self.name}: the validation worker stopped; validating in turn", file=sys.stderr)
                self.parallel_validation, self.pool = False, None
                m = evaluate_snapshot(self.cfg, self.name, p.snapshot, self.groups)
            self.eval_s += time.monotonic() - t0
            self._record(p.meta, p.snapshot, m)

    def _record(
        self, meta: dict[str, Any], snap: Snapshot, by_scenario: dict[str, list[dict[str, float]]]
    ) -> None:
        """One evaluation's row (from its episode rows by scenario); its model becomes the selected one if
        it is the best so far: the lowest main metric among the admissible rows or, with
        validation.scenarios, the most scenarios whose best classical baseline it beats by the
        leaderboard's rule, then the lowest geometric mean of main metric / baseline's over them."""
        m = means(by_scenario[self.cfg.scenario])
        zero = self.zero[self.main]
        row = {
            **meta,
            "main": m[self.main],
            "score": 1.0 - m[self.main] / zero if zero > 0 else math.nan,
            "effort_rms": m["effort_rms"],
            "command_roughness": m["command_roughness"],
            "iae": m["iae"],
        }
        row["admissible"] = float(row["effort_rms"] <= self.cfg.max_effort_ratio * self.effort_ref)
        if self.cfg.eval_scenarios:
            row |= self._across(by_scenario)
        self.history.append(row)
        if self.logger is not None:
            for k in ("main", "score", "effort_rms"):
                self.logger.record(f"validation/{k}", row[k])
        if self.cfg.eval_scenarios:
            better = self.best is None or (row["won"], -row["ratio"]) > (
                self.best["won"],
                -self.best["ratio"],
            )
        else:
            better = row["admissible"] and (self.best is None or row["main"] < self.best["main"])
        if better:
            self.best = row
            self.best_files = snap.write_model(self.out)
        atomic_text(self.out / VALIDATION_CSV, csv_text(self.history))
        if self.reporter is not None:
            self.reporter(row)

    def _across(self, by_scenario: dict[str, list[dict[str, float]]]) -> dict[str, float]:
        """Scenarios whose best classical baseline the model beats by the leaderboard's rule
        (stats.why_not_beats: paired interval of the per-episode difference below 0, and a result against
        the scenario's reference point; on the same validation episodes) and the geometric mean of main
        metric / baseline's (means) over the selection scenarios."""
        won, logs = 0, []
        for sc, rows in by_scenario.items():
            b, base_rows, scenario = self.baselines[sc], self.baseline_rows[sc], self.scenarios[sc]
            main, m = scenario.main_metric, means(rows)
            v = stats.paired([r[main] for r in rows], [r[main] for r in base_rows])
            why = why_not_beats(
                v, stats.Conduct.of(m), self.points[sc], scenario.action_scale, scenario.settle_band
            )
            won += not why
            logs.append(math.log(max(m[main], 1e-300) / max(b.main, 1e-300)))
        return {"won": float(won), "ratio": math.exp(sum(logs) / len(logs))}

    # ----------------------------------------------------------------------------- checkpoints
    def checkpoint(self, model: Any, snap: Snapshot) -> None:
        """One consistent set for --resume: the model now (snap: its snapshot), its normalizer, replay
        buffer, the run's state and a copy of the selected model's files, written into a new folder
        out/checkpoint/<step>-<id>/ that is complete before out/checkpoint/LATEST (one atomic rename)
        names it; the sets it replaces are removed after. A stop at any point leaves LATEST naming a
        complete set. An evaluation still running is re-run on --resume."""
        root = self.out / "checkpoint"
        root.mkdir(parents=True, exist_ok=True)
        ck = root / f"{model.num_timesteps:012d}-{uuid.uuid4().hex[:8]}"
        snap.write(ck)
        if hasattr(model, "replay_buffer") and model.replay_buffer is not None:
            atomic_write(ck / REPLAY_BUFFER, lambda p: model.save_replay_buffer(p))
        best = ck / "best"
        best.mkdir()
        for f in self.best_files.get("sha256", {}):
            shutil.copy2(self.out / f, best / f)
        state = {
            "num_timesteps": model.num_timesteps,
            "wall_s": self.elapsed(),
            "history": self.history,
            "eval_s": self.eval_s,
            "best": self.best,
            "best_files": self.best_files,
            "next_eval": self.next_eval,
            "episodes": model.get_env().get_attr("episodes"),
            "pending": [p.meta for p in self.pending],  # at most the checkpoint's own model
            "provenance": self.prov,
        }
        atomic_text(ck / STATE, json.dumps(state))
        _fsync_dir(ck)
        atomic_text(root / LATEST, ck.name + "\n")
        for old in root.iterdir():
            if old.is_dir() and old != ck:
                shutil.rmtree(old, ignore_errors=True)

    def latest_checkpoint(self) -> Path | None:
        """The complete set out/checkpoint/LATEST names (None without one); a checkpoint of another form
        (an older version's, or LATEST naming no complete set) is refused with one line."""
        root = self.out / "checkpoint"
        if (root / STATE).exists():
            raise ConfigError(
                "--resume",
                "this checkpoint was written by an older frictiongym; start the run again",
                str(root),
            )
        if not (root / LATEST).exists():
            return None
        ck = root / (root / LATEST).read_text().strip()
        if ck.parent != root or not (ck / STATE).is_file() or not (ck / MODEL).is_file():
            raise ConfigError("--resume", f"LATEST names {ck.name}, not a complete checkpoint", str(root))
        return ck

    # ----------------------------------------------------------------------------- the run
    def train(self, resume: bool = False) -> dict[str, Any]:
        """Train, select, write the model folder; returns the manifest."""
        import torch
        from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

        from .callbacks import callbacks  # stable-baselines3 (the rl extra): at training time only

        torch.set_num_threads(1)
        cfg, out = self.cfg, self.out
        ck = self.latest_checkpoint()
        if (out / MANIFEST).exists() and not resume:
            raise FileExistsError(f"{out} holds a finished run; use another --out, or --resume to extend it")
        if not resume and ck is not None:
            raise FileExistsError(f"{out} holds an unfinished run: continue it with --resume")
        out.mkdir(parents=True, exist_ok=True)
        rows = {sc: classical_rows(episodes, self.envs) for sc, episodes in self.groups.items()}
        by_scenario = {sc: {name: means(r) for name, r in by_name.items()} for sc, by_name in rows.items()}
        self.baselines = {sc: best_classical(sc, classical) for sc, classical in by_scenario.items()}
        # and their episode rows, for the paired intervals of selection on several scenarios
        self.baseline_rows = {sc: rows[sc][b.name] for sc, b in self.baselines.items()}
        self.points = {  # selection on several scenarios judges each, the run's own among them
            sc: reference_point(sc, rows[sc], self.groups[sc], self.envs)
            for sc in (self.groups if cfg.eval_scenarios else ())
        }
        classical = by_scenario[cfg.scenario]
        self.baseline, self.zero = self.baselines[cfg.scenario], classical[ZERO]
        # admissible effort: relative to the best baseline, and to the base controller in residual mode
        base_effort = math.inf
        if cfg.base is not None:
            base = classical.get(cfg.base) or evaluate_controller(
                base_controller(cfg.base), self.groups[cfg.scenario], self.envs
            )  # a base that is not a baseline (registry.BASES) runs here on the same episodes
            base_effort = base["effort_rms"]
        self.effort_ref = min(self.baseline.effort_rms, base_effort)
        (out / "monitor").mkdir(exist_ok=True)
        venv: Any = VecMonitor(make_training_env(cfg, self.seed), str(out / "monitor"))
        gamma = cfg.hyperparams.get("gamma", 0.99)
        state = None
        if resume and ck is not None:
            state = json.loads((ck / STATE).read_text())
            if (ck / NORMALIZER).exists():
                venv = VecNormalize.load(str(ck / NORMALIZER), venv)
                venv.training = True
            model = algorithm_class(cfg.algorithm).load(str(ck / MODEL), env=venv, device="cpu")
            model.tensorboard_log = str(out / "tb")
            if (ck / REPLAY_BUFFER).exists():
                model.load_replay_buffer(str(ck / REPLAY_BUFFER))
            for i, n in enumerate(state["episodes"]):
                venv.env_method("set_episodes", n, indices=[i])
            self.history, self.best, self.next_eval = state["history"], state["best"], state["next_eval"]
            self.best_files = state["best_files"]
            for f in self.best_files.get("sha256", {}):  # the selected model as the checkpoint knew it
                data = (ck / "best" / f).read_bytes()
                atomic_write(out / f, lambda p, data=data: p.write_bytes(data))
            self.wall_before, self.eval_s = state["wall_s"], state.get("eval_s", 0.0)
            self.prov = state.get("provenance") or self.prov  # the code the run first started with
            for meta in state.get("pending", []):  # the checkpoint's model, not evaluated before the stop
                snap = Snapshot.read(ck, cfg.algorithm)
                self._record(meta, snap, evaluate_snapshot(cfg, self.name, snap, self.groups))
        else:
            if cfg.normalize_observation or cfg.normalize_reward:
                venv = VecNormalize(
                    venv, norm_obs=cfg.normalize_observation, norm_reward=cfg.normalize_reward, gamma=gamma
                )
            model = build_model(cfg, venv, self.seed, str(out / "tb"))
        done = model.num_timesteps
        self.t0 = time.monotonic()
        remaining = cfg.total_timesteps - done
        try:
            if remaining > 0:
                model.learn(
                    remaining,
                    callback=callbacks(self),
                    reset_num_timesteps=state is None,
                    progress_bar=self.progress,
                    tb_log_name="run",
                )
                self.collect(block=True)  # so that a pending evaluation is always the checkpoint's model
                evaluated = self.history and self.history[-1]["step"] == model.num_timesteps
                snap = Snapshot.of(model) if evaluated else self.validate(model)
                self.checkpoint(model, snap)
                self.collect(block=True)  # the final model's evaluation
                self.checkpoint(model, snap)
        finally:
            if self.pool is not None:
                self.pool.shutdown(cancel_futures=True)
                self.pool = None
        if self.best is None:
            raise NothingSelected(
                f"{self.name}: no validation evaluation had effort_rms <= {cfg.max_effort_ratio} x "
                f"{self.effort_ref:.4g} (the baseline's): nothing to select (rows: {out / VALIDATION_CSV})"
            )
        manifest = self.manifest(model.num_timesteps)
        manifest.write(out)
        plot_curve(self.history, self.baseline, self.main, out / "training_curve.png", self.name)
        seal(out, sealed_files(out, manifest))
        return manifest.as_dict()

    def manifest(self, steps: int) -> Manifest:
        import stable_baselines3

        cfg, prov = self.cfg, self.prov
        return Manifest(
            name=self.name,
            algorithm=cfg.algorithm,
            model=self.best_files["model"],
            network=self.best_files.get("network", {}),
            sha256=self.best_files["sha256"],
            scenario=cfg.scenario,
            plants=(load_scenario(cfg.scenario).spec.name,),
            base_controller=cfg.base,
            alpha=cfg.alpha,
            inputs=cfg.inputs,
            seed=self.seed,
            steps=int(steps),
            selected_step=int(self.best["step"]),
            wall_time_s=round(self.elapsed(), 1),
            stopped_at_wall_time_limit=self.stopped_early,
            command=self.command,
            package_version=prov["package_version"],
            git_commit=prov["git_commit"],
            stable_baselines3=stable_baselines3.__version__,
            torch_threads=1,
            training_seeds=(
                f"{TRAINING_SEEDS + self.seed * SEEDS_PER_RUN} + k·{cfg.n_envs} + i (env i, episode k)"
            ),
            validation={
                "suite": VALIDATION_SUITE,
                "episodes": len(self.episodes),
                "seeds": [e.seed for e in self.episodes],
                "main_metric": self.main,
                "value": self.best["main"],
                "score": self.best["score"],
                "effort_rms": self.best["effort_rms"],
                "command_roughness": self.best["command_roughness"],
                "best_classical": dataclasses.asdict(self.baseline),
                "admissible_effort_rms": self.cfg.max_effort_ratio * self.effort_ref,
                **(
                    {
                        "selection": {
                            "scenarios": list(self.groups),
                            "won": int(self.best["won"]),
                            "ratio": self.best["ratio"],
                            "best_classical": {sc: dataclasses.asdict(b) for sc, b in self.baselines.items()},
                        }
                    }
                    if cfg.eval_scenarios
                    else {}
                ),
            },
            config={**cfg.as_dict(), "inputs": dataclasses.asdict(cfg.inputs)},
        )


def _fsync_dir(folder: Path) -> None:
    """A folder's entries (the files just renamed into it) on disk, before anything names the folder."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def plot_curve(
    history: list[dict[str, float]], baseline: Baseline, main: str, path: Path, title: str
) -> None:
    """Validation main metric and effort against training steps, with the best classical baseline."""
    plt = pyplot()

    steps = [h["step"] for h in history]
    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    ax[0].plot(steps, [h["main"] for h in history], "o-", label="policy (validation mean)")
    ax[0].axhline(baseline.main, color="k", ls="--", label=f"{baseline.name} (best classical)")
    ax[0].set(ylabel=main, yscale="log")
    ax[0].legend()
    ax[1].plot(steps, [h["effort_rms"] for h in history], "o-")
    ax[1].axhline(baseline.effort_rms, color="k", ls="--")
    ax[1].set(ylabel="effort_rms", xlabel="training steps")
    ax[0].set_title(title)
    save_figure(fig, path.parent, path.name, dpi=90)


# ------------------------------------------------------------------------------------------- runs
def run_dir(out: Path, cfg: RunConfig, seed: int) -> Path:
    return Path(out) / cfg.name / cfg.scenario / f"seed{seed}"


RECORDS = (VALIDATION_CSV, "training_curve.png")  # a run's records copied with its model


def export_model(run: Path, dest: Path) -> Path:
    """Copy a finished run's model folder (manifest, the files it names, validation record, curve; not
    the checkpoint or logs) to dest/<name>/, e.g. into agents/models/generalist/ to commit it."""
    m = Manifest.read(Path(run))
    folder = Path(dest) / m.name
    folder.mkdir(parents=True, exist_ok=True)
    for f in sealed_files(Path(run), m):
        shutil.copy2(Path(run) / f, folder / f)
    seal(folder, sealed_files(folder, m))
    return folder


def sealed_files(run: Path, m: Manifest) -> list[str]:
    """A run's model folder files: the manifest, the files it names and the records present (not the
    checkpoints, logs or monitor files beside them in a run's folder)."""
    return [f for f in (MANIFEST, *m.sha256, *RECORDS) if (Path(run) / f).is_file()]


def train_one(args: tuple[RunConfig, int, str, str, bool, bool]) -> dict[str, Any] | NothingSelected:
    """One run (picklable for a process pool): (config, seed, out dir, command, resume, progress), its
    validation beside it; its manifest, or the NothingSelected of a run that selected no model."""
    cfg, seed, out, command, resume, progress = args
    with contextlib.redirect_stdout(sys.stderr) if not progress else contextlib.nullcontext():
        run = TrainingRun(cfg, seed, Path(out), command, progress, parallel_validation=True)
        try:
            return run.train(resume)
        except NothingSelected as e:  # a result of the run, not a failure of the others
            return e


def train_many(
    cfgs: Sequence[RunConfig], seeds: Sequence[int], out: Path, resume: bool, workers: int
) -> list[dict[str, Any] | NothingSelected]:
    """Every (config, seed) run, in order: its manifest, or NothingSelected for a run that selected no
    model (the others go on); with workers > 1 on a spawn pool, one torch thread each."""
    command = command_line()
    jobs = [(c, s, str(run_dir(out, c, s)), command, resume, workers == 1) for c in cfgs for s in seeds]
    if workers == 1:
        return [train_one(j) for j in jobs]
    # Ctrl-C is the parent's (workers ignore it; the pool's processes are terminated); a killed parent's
    # workers exit by themselves. The pool's processes are not daemonic, so that each run can start its
    # validation worker on the other core (TrainingRun.parallel_validation).
    pool = ProcessPoolExecutor(
        workers,
        mp.get_context("spawn"),
        initializer=init_worker,
        initargs=(os.getpid(),),
        max_tasks_per_child=1,
    )
    try:
        return list(pool.map(train_one, jobs))
    except BaseException:
        stop_workers()
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
