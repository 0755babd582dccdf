"""The run's SB3 callbacks, composed with CallbackList as stable-baselines3's own are (`callbacks(run)`):

- `Validation`: every `eval_every_steps` env steps, evaluate the deterministic policy on the validation
  episodes through the leaderboard's loop (in the validation worker while training goes on, or in turn),
  then run its `callback_after_eval` (as SB3's EvalCallback does): here the `Checkpoint`;
- `Checkpoint`: the model just validated, its normalizer, replay buffer and the run's state, for --resume;
- `WallTimeStop`: end training at the config's wall-time limit (or the bench's training-time budget).

Imported at training time only: stable-baselines3 is the rl extra.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from stable_baselines3.common.callbacks import BaseCallback, CallbackList

if TYPE_CHECKING:
    from .config import RunConfig
    from .validation import Snapshot


class RunHooks(Protocol):
    """What the callbacks use of a run (run.TrainingRun, which imports this module: typed by what it
    does, so the room reads one way)."""

    cfg: RunConfig
    logger: Any
    next_eval: int
    last_snapshot: Snapshot | None
    stop_after_train_s: float | None
    stopped_early: bool

    def collect(self, block: bool) -> None: ...
    def validate(self, model: Any) -> Snapshot: ...
    def checkpoint(self, model: Any, snap: Snapshot) -> None: ...
    def elapsed(self) -> float: ...
    def train_s(self) -> float: ...


class Validation(BaseCallback):
    """Starts an evaluation of the model every `eval_every_steps` (at most one runs beside training: the
    previous one is collected first), then calls `callback_after_eval`."""

    def __init__(self, run: RunHooks, callback_after_eval: BaseCallback | None = None):
        super().__init__()
        self.run, self.callback = run, callback_after_eval

    def _init_callback(self) -> None:
        if self.callback is not None:
            self.callback.init_callback(self.model)

    def _on_training_start(self) -> None:
        self.run.logger = self.logger

    def _on_step(self) -> bool:
        r = self.run
        if self.num_timesteps >= r.next_eval:
            r.next_eval += r.cfg.eval_every_steps
            r.collect(block=True)
            r.last_snapshot = r.validate(self.model)
            if self.callback is not None:
                return self.callback.on_step()
        return True


class Checkpoint(BaseCallback):
    """The model just validated (the run's last snapshot) and the run's state into out/checkpoint."""

    def __init__(self, run: RunHooks):
        super().__init__()
        self.run = run

    def _on_step(self) -> bool:
        self.run.checkpoint(self.model, self.run.last_snapshot)
        return True


class WallTimeStop(BaseCallback):
    """False (stop) once the run's wall time passes max_wall_time_s, or its training time (waits for
    validation excluded) passes stop_after_train_s; the run records that it stopped early."""

    def __init__(self, run: RunHooks):
        super().__init__()
        self.run = run

    def _on_step(self) -> bool:
        r = self.run
        over = r.stop_after_train_s is not None and r.train_s() > r.stop_after_train_s
        if r.elapsed() > r.cfg.max_wall_time_s or over:
            r.stopped_early = True
            return False
        return True


def callbacks(run: RunHooks) -> CallbackList:
    """Validation (then a checkpoint), then the wall-time stop: the order the run's steps need."""
    return CallbackList([Validation(run, callback_after_eval=Checkpoint(run)), WallTimeStop(run)])
