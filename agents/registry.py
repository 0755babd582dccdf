"""Controllers by name: the built-in set, the `frictiongym.controllers` entry-point group (a package
registers `name = "module:factory"`, the factory taking no arguments and returning a Controller), a
user's own controller named by where it is defined, without packaging (`my_module:MyController` or
`path/to/file.py:MyController`, as Gymnasium's `gym.make("module:Env")`: a Controller class or a
factory taking no arguments; it is listed under its controller's `name`), and saved models: a folder
with a manifest.yaml and policy.safetensors (agents/learned/folder.py: a format that cannot run code), or
a folder of such folders. A run's `models` sources hold the model folders and the user's controllers
alike, so worker processes build the same controllers by name.

    manifest.yaml:  name: SAC-kang          # the leaderboard's name for it
                    algorithm: SAC          # the algorithm that trained it (a record)
                    model: policy.safetensors   # a file of the folder: weights, bounds, statistics
                    network: {layers: [linear, relu, linear, relu, linear, tanh], observes: [14], ...}
                    sha256: {policy.safetensors: 5f1c...}   # checked before the file is read
                    plants: [kang_robot]    # optional: plants it applies to
                    base_controller: RDFC   # optional: residual over this base (BUILTIN or BASES)...
                    alpha: 0.05             # ...with this authority (default 1)
                    inputs: {history: 0, privileged: false, base_action: true}   # optional
                    ...                     # anything else (training record) is kept, not read here
    SHA256SUMS:     every file of the folder, the manifest included, with its SHA-256 (the seal:
                    learned.folder.read_sealed; any changed byte anywhere refuses the folder)
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache, partial
from importlib.metadata import entry_points
from pathlib import Path

from frictiongym.agents.evaluation.limits import Ideal, Oracle, TrackingLimit
from frictiongym.agents.evaluation.optimum import Optimum
from frictiongym.agents.learned.folder import read_policy, read_sealed
from frictiongym.agents.learned.manifest import MANIFEST, Manifest
from frictiongym.agents.learned.policy import LearnedPolicy, policy_why_not
from frictiongym.agents.tuning.tuned import SUFFIX, Tuned, tunable, tuned_entries
from frictiongym.envs.config import ConfigError
from frictiongym.envs.scenario import Scenario, load_scenario

from .base import ZERO, Controller, Zero
from .classical import (
    PD,
    PID,
    RDFC,
    AdaptiveCoulomb,
    CascadeModelFF,
    CoulombViscousFF,
    DisturbanceObserver,
    FeedForwardSettings,
    IterativeLearning,
    LabPD,
    LuGreObserver,
    ModelFFDisturbanceObserver,
    PIDCoulombViscousFF,
    PIDModelFF,
    ResidualBaseSettings,
    Southward,
    SpeedScheduled,
    StateFeedback,
    TaskScheduled,
)

ENTRY_POINT_GROUP = "frictiongym.controllers"

BUILTIN: dict[str, Callable[[], Controller]] = {
    ZERO: Zero,
    "PD": PD,
    "PID": PID,
    "LabPD": LabPD,
    "Southward": Southward,
    "RDFC": RDFC,
    "SF": StateFeedback,
    "SF+relay": partial(StateFeedback, "relay"),
    "SF+highgain": partial(StateFeedback, "highgain"),
    "LuGreObserver": LuGreObserver,
    "CoulombViscousFF": CoulombViscousFF,
    "PID+FF": PIDCoulombViscousFF,
    "PID+MFF": PIDModelFF,
    "Cascade+MFF": CascadeModelFF,
    "DOB": DisturbanceObserver,
    "MFF+DOB": ModelFFDisturbanceObserver,
    "ILC": IterativeLearning,
    "AdaptiveFF": AdaptiveCoulomb,
}


def _tuned_twins() -> dict[str, Callable[[], Controller]]:
    """`<family>[tuned]` for every family of configs/tuned.yaml (agents/tuning/search.py): a classical
    baseline like its family, with the settings tuned on the validation suite."""
    out: dict[str, Callable[[], Controller]] = {}
    for family, entries in tuned_entries().items():
        if family not in BUILTIN or tunable(BUILTIN[family]) is None:
            raise ConfigError(
                family, f"configs/tuned.yaml: not a tunable built-in family; one of {list(BUILTIN)}"
            )
        out[family + SUFFIX] = partial(Tuned, family, BUILTIN[family], entries)
    return out


BUILTIN.update(_tuned_twins())


def builtin(name: str) -> Controller:
    """A new built-in controller called name (an unknown name is an error listing them)."""
    if name not in BUILTIN:
        raise ValueError(f"{name!r} is not a built-in controller; one of {list(BUILTIN)}")
    return BUILTIN[name]()


# Residual bases that are not baselines (no seed describes them), those the committed models run over:
# made by name like any controller (a leaderboard runs one when asked for it, as an entry), never in a
# default run or a baseline. Their settings are controllers.yaml's (speed_scheduled, task_scheduled,
# state_feedback_residual_base).
BASES: dict[str, Callable[[], Controller]] = {
    "SpeedScheduled": partial(SpeedScheduled, builtin),
    "TaskScheduled": partial(TaskScheduled, builtin),
    # Wallenborg's SF+relay at state_feedback_residual_base's ω_cl, its observer fed the residual
    "SF+relay/residual-base": lambda: StateFeedback(
        "relay",
        w_cl=ResidualBaseSettings.defaults().w_cl,
        observe_residual=True,
        name="SF+relay/residual-base",
    ),
}


def base_controller(name: str) -> Controller:
    """A new residual base: a built-in controller other than Zero, or one of BASES."""
    factories = {**{n: f for n, f in BUILTIN.items() if n != ZERO}, **BASES}
    if name not in factories:
        raise ValueError(f"unknown base controller {name!r}; allowed: {sorted(factories)}")
    return factories[name]()


def uncompensated_loop(name: str) -> Controller:
    """A scenario's uncompensated loop (benchmark.uncompensated): a built-in classical controller."""
    if name not in BUILTIN or name == ZERO:
        loops = [n for n in BUILTIN if n != ZERO]
        raise ValueError(f"benchmark.uncompensated: {name!r} is not a built-in controller; one of {loops}")
    return BUILTIN[name]()


# The physical-limit rows (agents/evaluation/limits.py): with Zero, the references every leaderboard runs
# on every episode; never ranked as entries, never a baseline.
def linear_loop(name: str) -> Controller:
    """A model feed-forward family without its friction term (the TrackingLimit row's loop)."""
    settings = FeedForwardSettings.defaults()
    for plant in settings.plants:
        settings = settings.replaced(plant, {"friction_scale": 0.0})
    return BUILTIN[name](ff=settings)


LIMITS: dict[str, Callable[[], Controller]] = {
    "Ideal": partial(Ideal, uncompensated_loop),
    "TrackingLimit": partial(TrackingLimit, uncompensated_loop, linear_loop),
    "Oracle": partial(Oracle, uncompensated_loop),
    "Optimum": Optimum,
}
REFERENCES = (ZERO, *LIMITS)


MODELS_DIR = Path(__file__).parent / "models"  # committed trained models, by group


# The committed groups the default leaderboard runs: the specialists, each trained on one scenario, and
# one compensator per plant for all of its scenarios (issue 21; docs/research.md "Generalists").
LEADERBOARD_GROUPS = ("specialist", "generalist")


def committed_models(*groups: str) -> list[Path]:
    """The committed model folders of the groups (agents/models/<group>/*/manifest.yaml), group by group:
    `specialist` and `generalist` (on the default leaderboard, `LEADERBOARD_GROUPS`) or `sim2real` (the
    friction-randomisation study's agents)."""
    out: list[Path] = []
    for group in groups:
        folder = MODELS_DIR / group
        out += sorted(d for d in folder.iterdir() if (d / MANIFEST).is_file()) if folder.is_dir() else []
    return out


def is_controller_spec(source: str | Path) -> bool:
    """Whether a source names a user's controller ("module:attr" or "file.py:attr"), not a model folder."""
    text = str(source)
    module, _, attr = text.rpartition(":")
    return bool(module) and attr.isidentifier() and not Path(text).exists()


def controller_factory(spec: str) -> Callable[[], Controller]:
    """The factory a "module:attr" or "path/to/file.py:attr" spec names: a Controller subclass or a
    callable taking no arguments that returns a Controller (checked by calling it once). A file is
    imported by its path, under a module name of its own; a module by its import name. Errors are one
    line naming the spec."""
    module_name, _, attr = str(spec).rpartition(":")
    try:
        if module_name.endswith(".py") or "/" in module_name or "\\" in module_name:
            path = Path(module_name).resolve()
            if not path.is_file():
                raise ValueError(f"{path} is not a file")
            name = "frictiongym_user_" + hashlib.sha256(str(path).encode()).hexdigest()[:12]
            module = sys.modules.get(name)
            if module is None:
                loader = importlib.util.spec_from_file_location(name, path)
                module = importlib.util.module_from_spec(loader)
                sys.modules[name] = module
                loader.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except (ImportError, AttributeError, OSError, ValueError, SyntaxError) as e:  # the module's own import
        raise ValueError(f"controller {spec!r}: {type(e).__name__}: {e}") from None
    try:
        factory = getattr(module, attr)
    except AttributeError:
        own = sorted(
            k
            for k, v in vars(module).items()
            if isinstance(v, type) and issubclass(v, Controller) and v.__module__ == module.__name__
        )
        has = f"its controllers: {', '.join(own)}" if own else "it defines no Controller subclass"
        raise ValueError(f"controller {spec!r}: {module_name} has no {attr!r}; {has}") from None
    try:
        made = factory() if callable(factory) else factory
    except Exception as e:  # the user's code: whatever it raises is named, on one line
        raise ValueError(f"controller {spec!r}: {attr}() failed: {type(e).__name__}: {e}") from None
    if not isinstance(made, Controller):
        raise ValueError(f"controller {spec!r}: {attr} gives a {type(made).__name__}, not a Controller")
    return factory


def unknown_hint(name: str) -> str:
    """What to write instead of an unknown controller name that names a file or a module: its class after a
    colon (path.py:Class, module:Class), with the classes a file defines (read, not run), or ""."""
    path = Path(name)
    if name.endswith(".py") and path.is_file():
        try:
            classes = [n.name for n in ast.parse(path.read_text()).body if isinstance(n, ast.ClassDef)]
        except (SyntaxError, UnicodeDecodeError, OSError):
            classes = []
        defined = f" (it defines {', '.join(classes)})" if classes else ""
        return f"{name} is a file: name its class as {name}:ClassName{defined}"
    if name.endswith(".py") or "/" in name:
        return f"{name}: no such file (a plug-in is path/to/file.py:ClassName)"
    return ""


def spec_of(controller: str | type | Callable[[], Controller]) -> str:
    """A controller as a name or spec the registry and worker processes resolve: a name or spec string as
    it is; a Controller class or a factory function by its module and qualified name (a script's own,
    __main__, by its file's path)."""
    if isinstance(controller, str):
        return controller
    if isinstance(controller, Controller):
        raise TypeError(
            f"{type(controller).__name__}(): pass its class or a 'module:factory' spec instead of an "
            "instance (each worker process builds its own controller)"
        )
    module = controller.__module__
    if module == "__main__":
        module = str(Path(sys.modules["__main__"].__file__).resolve())
    return f"{module}:{controller.__qualname__}"


def entries(
    controllers: Sequence[str | type | Callable[[], Controller]] | None, models: Sequence[str | Path] = ()
) -> tuple[list[str] | None, tuple[str, ...]]:
    """Controllers as the names a run uses, and the run's sources (the model folders, then the specs of
    the user's controllers among `controllers`, spec_of): the same names resolve in every worker
    process through the sources. None stays None (a run's default entries)."""
    sources = [str(m) for m in models]
    if controllers is None:
        return None, tuple(sources)
    names = []
    for c in controllers:
        spec = spec_of(c)
        if is_controller_spec(spec):
            sources.append(spec)
            names.append(controller_factory(spec)().name)
        else:
            names.append(spec)
    return names, tuple(dict.fromkeys(sources))


def allowed_sources(recorded: tuple[str, ...], allowed: Sequence[str | Path], where: str) -> tuple[str, ...]:
    """A finished run's sources (run.json's model folders and plug-in specs), each checked against what
    the command line allows (`allowed`: --models folders and --controllers specs): a results folder is
    data, so nothing it names is imported or read unless the user names it too. One line naming the first
    that is not, and the flag that allows it."""
    specs = {str(a) for a in allowed if is_controller_spec(a)}
    folders = {p.resolve() for p in model_dirs([a for a in allowed if not is_controller_spec(a)])}
    for source in recorded:
        if is_controller_spec(source):
            if source not in specs:
                raise ValueError(
                    f"{where} names the plug-in {source!r}, whose code would run: pass --controllers "
                    f"{source} to allow it"
                )
        elif not {p.resolve() for p in model_dirs([source])} <= folders:  # a model folder or a group of them
            raise ValueError(f"{where} names the model folder {source!r}: pass --models {source} to allow it")
    return recorded


def model_dirs(paths: Sequence[str | Path]) -> list[Path]:
    """The model folders under the given paths (a path is a model folder, or holds model folders;
    controller specs among them are skipped: controller_factory's)."""
    out = []
    for p in map(Path, (x for x in paths if not is_controller_spec(x))):
        if (p / MANIFEST).is_file():
            found = [p]
        else:
            found = sorted(d for d in p.iterdir() if (d / MANIFEST).is_file()) if p.is_dir() else []
            if links := [d.name for d in found if d.is_symlink()]:
                raise ValueError(
                    f"--models {p}: {links} are links: a collection holds its model folders itself"
                )
        if not found:
            raise ValueError(f"--models {p}: no {MANIFEST} there or in its sub-folders")
        out += found
    return out


def model_factory(
    folder: Path, files: Mapping[str, bytes] | None = None
) -> tuple[str, Callable[[], Controller]]:
    """(name, factory) of a saved model's folder, checked against its seal, its manifest and its files read
    now (learned.folder.read_policy: a changed or malformed file fails here, before any episode runs), or
    from `files`, a sealed folder's files already read and checked (an export's model/); each controller
    the factory makes shares the one immutable network."""
    if files is None:  # the seal checked and every file read once, before any is parsed
        files = read_sealed(folder)
    source = str(Path(folder) / MANIFEST)
    m = Manifest.parse(files, source)
    base = m.base_controller
    if base is not None:
        try:
            base_controller(base)
        except ValueError as e:
            raise ConfigError("base_controller", str(e), source) from None
    network, normalizer = read_policy(files, m, source)
    if m.scenario is not None:  # the inputs it declares are what its network takes on its own scenario
        held = base_controller(base) if base is not None else None
        if why := policy_why_not(
            network.observes, m.policy_inputs, m.plants, held, load_scenario(m.scenario)
        ):
            raise ConfigError("inputs", f"on its own scenario {m.scenario}: {why}", source)

    def factory() -> Controller:
        policy = LearnedPolicy(
            network,
            m.plants,
            m.name,
            normalizer=normalizer,
            inputs=m.policy_inputs,
            base=base_controller(base) if base is not None else None,
            alpha=m.alpha,
        )
        policy.hashes = {"model_sha256": m.sha256[m.model]}
        return policy

    return m.name, factory


@cache
def _manifests(models: tuple[str, ...]) -> dict[str, Manifest]:
    """The manifests of the saved models under `models`, by model name (read once per process)."""
    return {m.name: m for m in (Manifest.read(folder) for folder in model_dirs(models))}


def descriptions(models: Sequence[str | Path]) -> dict[str, str]:
    """What each saved model of `models` is, in words a reader follows beside its id: the design (the
    algorithm, a residual over which base), what it was trained on and its training seed, from its
    manifest (e.g. "SAC residual over PID+FF, trained on emps_random, seed 1")."""
    out = {}
    for name, m in _manifests(tuple(str(x) for x in models)).items():
        design = (
            f"{m.algorithm} residual over {m.base_controller}"
            if m.base_controller
            else f"{m.algorithm} policy"
        )
        trained = f", trained on {m.scenario}" if m.scenario else ""
        seed = f", seed {m.seed}" if m.seed is not None else ""
        out[name] = design + trained + seed
    return out


@dataclass(frozen=True)
class Budget:
    """What an entry's tuning or training spent, in the same units on both sides: env steps (control
    periods simulated) and wall time (s), and what was counted."""

    env_steps: int
    wall_s: float
    counted: str


def budgets(models: Sequence[str | Path] = ()) -> dict[tuple[str, str], Budget]:
    """{(entry, plant): Budget} of every tuned twin (configs/tuned.yaml: its trials x its validation
    episodes' control periods, the design and the reference rows it also ran left out) and every saved
    model of `models` (its manifest: the training env steps; the validation evaluations left out), with
    their wall times."""
    out = {}
    for family, plants in tuned_entries().items():
        for plant, e in plants.items():
            m = e.get("manifest", {})
            if "trials" not in m or "validation" not in m:
                continue
            periods = sum(len(eps) * load_scenario(sc).episode_steps for sc, eps in m["validation"].items())
            counted = f"tuning: {m['trials']} trials x {periods:,} control periods of validation episodes"
            steps = m.get("env_steps", m["trials"] * periods)  # written by tunes since 2026-12-07
            out[family + SUFFIX, plant] = Budget(steps, float(m["wall_s"]), counted)
    for name, m in _manifests(tuple(str(x) for x in models)).items():
        if m.steps is not None and m.wall_time_s is not None:
            for plant in m.plants:
                out[name, plant] = Budget(m.steps, m.wall_time_s, "training: env steps")
    return out


def why_not(name: str, models: Sequence[str | Path] = ()) -> Callable[[Scenario], str | None]:
    """make(name, models).why_not, without loading a saved model whose manifest names its training
    scenario: that model observes what the policy saw there (learned.policy_why_not decides both)."""
    m = _manifests(tuple(str(x) for x in models)).get(name)
    if m is None or m.scenario is None:
        return make(name, models).why_not
    base = base_controller(m.base_controller) if m.base_controller is not None else None
    observes = (m.policy_inputs.size(load_scenario(m.scenario)),)
    return partial(policy_why_not, observes, m.policy_inputs, m.plants, base)


def available(models: Sequence[str | Path] = ()) -> dict[str, Callable[[], Controller]]:
    """Every controller factory by name: built-ins, the physical-limit references, the residual bases, the
    entry-point group's, then the saved models under
    `models` (none may shadow an earlier name). Built once per set of model folders and process."""
    return dict(_available(tuple(str(m) for m in models)))


@cache
def _available(models: tuple[str, ...]) -> dict[str, Callable[[], Controller]]:
    out = {**BUILTIN, **LIMITS, **BASES}
    extra = [(ep.name, ep.value, ep.load) for ep in entry_points(group=ENTRY_POINT_GROUP)]
    for spec in (m for m in models if is_controller_spec(m)):
        factory = controller_factory(spec)
        extra.append((factory().name, spec, lambda f=factory: f))
    for folder in model_dirs(models):
        name, factory = model_factory(folder)
        extra.append((name, str(folder), lambda f=factory: f))
    for name, where, load in extra:
        if name in out:
            raise ValueError(f"controller {name!r} ({where}) shadows another controller of that name")
        out[name] = load()
    return out


def default_entries(models: Sequence[str | Path] = ()) -> list[str]:
    """The controllers a run takes when none are named: every available one but the residual bases."""
    return [n for n in _available(tuple(str(m) for m in models)) if n not in BASES]


def make(name: str, models: Sequence[str | Path] = ()) -> Controller:
    """A new controller called name (unknown names are an error listing the available ones)."""
    factories = _available(tuple(str(m) for m in models))
    if name not in factories:
        raise ValueError(f"unknown controllers [{name!r}]; available: {list(factories)}")
    return factories[name]()
