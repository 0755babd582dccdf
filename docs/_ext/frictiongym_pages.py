"""Sphinx extension: the documentation pages that are generated from the code and the configs, so that
they cannot drift from them. At `builder-inited` it writes generated/ (not committed):

- plants/<plant>.md: one page per plant, as Gymnasium documents its envs (description, the plant's
  parameters with units, observation, action, reward, starting state, episode end, arguments, the
  plant's scenarios, version history, a rendered frame from _static/frames/, written by
  `frictiongym render`);
- scenarios.md: every scenario and the suites that hold it;
- controllers.md: every built-in controller family, its source (its module's docstring), where it
  applies, and the settings file;
- api/: the API reference (autodoc): an index and a page per module a user calls.
"""

from __future__ import annotations

import inspect
from functools import partial
from pathlib import Path

import gymnasium as gym

DOCS = Path(__file__).parents[1]
OUT = DOCS / "generated"

# The modules of the API reference, in the order a user meets them.
API_MODULES = (
    "frictiongym.envs",
    "frictiongym.envs.servo_env",
    "frictiongym.envs.scenario",
    "frictiongym.envs.suites",
    "frictiongym.envs.vector",
    "frictiongym.envs.friction",
    "frictiongym.envs.metrics",
    "frictiongym.envs.units",
    "frictiongym.agents.base",
    "frictiongym.agents.registry",
    "frictiongym.agents.evaluation.evaluate",
    "frictiongym.agents.evaluation.leaderboard",
    "frictiongym.agents.evaluation.limits",
    "frictiongym.agents.evaluation.stats",
    "frictiongym.agents.tuning.tuned",
    "frictiongym.agents.deploy.runtime",
    "frictiongym.agents.learned.folder",
)


def md_cell(text: str) -> str:
    """Text for a Markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def table(head: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(md_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def scenario_names() -> list[str]:
    from frictiongym.envs.config import preset_names

    return preset_names("scenarios")


def suites_of() -> dict[str, list[str]]:
    from frictiongym.envs.suites import load_suite, suite_names

    out: dict[str, list[str]] = {}
    for s in suite_names():
        for name in dict.fromkeys(e.scenario for e in load_suite(s)):
            out.setdefault(name, []).append(s)
    return out


def env_classes() -> dict[str, type]:
    from frictiongym.envs import ENV_IDS

    load = gym.envs.registration.load_env_creator
    return {i: load(f"frictiongym.envs.{e}") for i, (e, _) in ENV_IDS.items()}


def plant_page(env_id: str, cls: type, scenarios: list, suites: dict[str, list[str]]) -> str:
    from frictiongym.envs import VERSION_HISTORY, scenario_env_id
    from frictiongym.envs.servo_env import ARGUMENTS_DOC, OBSERVATION_DOC

    default = next(s for s in scenarios if s.name == cls.default_scenario)
    spec = default.spec
    env = gym.make(env_id)
    try:
        obs_space, act_space = env.observation_space, env.action_space
    finally:
        env.close()
    rows = []
    for j in spec.joints:
        u = spec.joint_unit(j.name)
        inertia = f"{j.inertia:.4g} {'kg' if u == 'm' else 'kg·m²'}"
        force = "N" if u == "m" else "N·m"
        f = j.friction
        fr = (
            "none"
            if f is None
            else f"Fc {f.fc:.4g} {force}, Fs {f.fs:.4g} {force}, vs {f.vs:.3g} {u}/s, σ0 {f.sigma0:.4g} "
            f"{force}/{u}, σ1 {f.sigma1:.4g} {force}·s/{u}, σ2 {f.sigma2:.4g} {force}·s/{u}, "
            f"bias {f.bias:.3g} {force}"
        )
        rows.append([f"`{j.name}` ({j.kind})", inertia, f"{j.viscous:.4g} {force}·s/{u}", fr])
    friction = f"friction ({spec.friction_model} structure, nominal)"
    joints = table(["joint", "inertia", "viscous", friction], rows)
    plant = table(
        ["", ""],
        [
            ["env class", f"`{cls.__module__}.{cls.__qualname__}`"],
            ["action space", f"`{act_space}`"],
            ["observation space (default scenario)", f"`{obs_space}`"],
            ["command", f"±{spec.command_limit:g} {spec.command_unit} into `{spec.actuator_joint}`"],
            ["sensors", ", ".join(f"`{s}` ({spec.sensor_unit(s)})" for s in spec.sensor_names)],
            ["control period", f"{spec.control_period * 1e3:g} ms"],
            ["physics", f"{spec.timestep * 1e6:g} µs steps, {spec.integrator} integrator"],
            ["actuation delay", f"{spec.delay * 1e3:g} ms (nominal)"],
            ["default scenario", f"`{cls.default_scenario}`"],
        ],
    )
    ranges = table(
        ["randomised at reset", "range"],
        [[f"`{k}`", f"{lo:g} to {hi:g}"] for k, (lo, hi) in spec.randomization.items()],
    )
    scen = table(
        ["scenario", "env id", "task", "episode", "main metric", "start (qpos, qvel)", "suites"],
        [
            [
                f"`{s.name}`",
                f"`{scenario_env_id(s.name)}`",
                s.task + (" (held out)" if s.held_out else ""),
                f"{s.episode_steps * s.control_period:g} s",
                s.main_metric,
                f"{s.qpos_range.tolist()}, {s.qvel_range.tolist()}",
                ", ".join(suites.get(s.name, [])) or "none",
            ]
            for s in scenarios
        ],
    )
    versions = "\n".join(f"- {v}: {what}" for v, what in VERSION_HISTORY.items())
    title = cls.description.split(" (")[0].removeprefix("The ")
    return f"""# {title}

```{{image}} ../../_static/frames/{spec.name}.png
:alt: a rendered frame of {spec.name}
:width: 480px
```

{cls.description}

Gymnasium id: `{env_id}`, and one id per scenario (below).

{plant}

## The plant

{joints}

Friction levels are the nominal preset's (configs/plants/{spec.name}.yaml); a structure other than
LuGre is chosen by a scenario's `friction_model` ([physics](../../physics.md)).

## Observation, action and reward

```{{eval-rst}}
{inspect.cleandoc(OBSERVATION_DOC)}
```

## Starting state

Each scenario starts the joints at rest at a position drawn from its `qpos_range` (rad or m, one row per
joint) with speeds from its `qvel_range` (table below); with `randomize`, each reset also draws the
plant's parameters from these ranges (scales are factors of the nominal values, `asymmetry_shift` a
fraction of the Coulomb level, times in s), from the episode's seed alone:

{ranges}

## Episode end

The episode is truncated at its scenario's length (below; the per-scenario id's `max_episode_steps`
says the same), and terminated early only if the simulation diverges (`info["diverged"]`).

## Arguments

```{{eval-rst}}
{inspect.cleandoc(ARGUMENTS_DOC)}
```

## Scenarios

{scen}

## Version history

{versions}
"""


SCENARIO_COLUMNS = [
    "scenario", "plant", "task", "episode", "main metric", "limit score", "suites", "what it tests"
]


def scenarios_page(scenarios: list, suites: dict[str, list[str]]) -> str:
    from frictiongym.envs.suites import load_suite, seed_ranges, suite_names

    rows = [
        [
            f"`{s.name}`",
            s.spec.name,
            s.task + (" (held out)" if s.held_out else ""),
            f"{s.episode_steps * s.control_period:g} s",
            s.main_metric,
            s.limit_score,
            ", ".join(suites.get(s.name, [])) or "none",
            s.why,
        ]
        for s in scenarios
    ]
    ranges = seed_ranges()
    srows = []
    for name in suite_names():
        eps = load_suite(name)
        lo, hi = ranges.get(name, (None, None))
        srows.append(
            [
                f"`{name}`",
                str(len(dict.fromkeys(e.scenario for e in eps))),
                str(len(eps)),
                f"{lo} to {hi}" if lo is not None else "",
            ]
        )
    return f"""# Scenarios and suites

Generated from configs/scenarios/ and configs/suites.yaml. A scenario is a plant, a reference, a length
and what is scored; a suite is a list of episodes (scenario, seed), the same for every controller.
`limit_score` says how the friction penalty removed is scored (docs: [scores](../envs.md)).

{table(["suite", "scenarios", "episodes", "seed range"], srows)}

{table(SCENARIO_COLUMNS, rows)}
"""


def controllers_page(scenarios: list) -> str:
    import importlib

    from frictiongym.agents import registry

    rows, sources = [], {}
    for name, factory in registry.BUILTIN.items():
        target = factory.func if isinstance(factory, partial) else factory
        module = importlib.import_module(target.__module__)
        why = registry.why_not(name)
        runs = sorted({s.spec.name for s in scenarios if why(s) is None})
        rows.append([f"`{name}`", f"`{target.__module__}.{target.__qualname__}`", ", ".join(runs) or "none"])
        sources.setdefault(target.__module__, (module.__doc__ or "").strip())
    families = "\n\n".join(
        f"### `{mod}`\n\n```text\n{doc}\n```" for mod, doc in sources.items() if doc
    )
    return f"""# Controllers

Every built-in controller, the class that implements it and the plants where it runs (a controller that
does not apply to a scenario says why and is skipped). Generated from the registry
(`frictiongym.agents.registry.BUILTIN`). The `[tuned]` twins run a family with the settings that
`frictiongym tune` committed to configs/tuned.yaml ([the classical side](../classical.md)).

{table(["name", "class", "plants"], rows)}

## The families and their sources

{families}

## Settings (configs/controllers.yaml)

```{{literalinclude}} ../../configs/controllers.yaml
:language: yaml
```
"""


def env_versions() -> str:
    """The environment versions (envs.VERSION_HISTORY) as a table, for the changelog."""
    from frictiongym.envs import VERSION_HISTORY

    return table(["version", "what changed"], [[v, what] for v, what in VERSION_HISTORY.items()]) + "\n"


def api_pages() -> dict[str, str]:
    """The API reference: an index (the modules, each with its docstring's first sentence) and one page
    per module (autodoc), as Gymnasium's and stable-baselines3's are."""
    import importlib

    pages, rows = {}, []
    for m in API_MODULES:
        doc = (importlib.import_module(m).__doc__ or "").strip()
        first = " ".join(doc.split("\n\n")[0].split()).split(". ")[0].rstrip(".")
        rows.append([f"[`{m}`]({m}.md)", md_cell(first)])
        pages[f"{m}.md"] = f"# `{m}`\n\n```{{eval-rst}}\n.. automodule:: {m}\n   :members:\n```\n"
    toc = "\n".join(f"{m}" for m in API_MODULES)
    pages["index.md"] = (
        "# API reference\n\nThe modules a user calls, one page each.\n\n"
        + table(["module", "what it is"], rows)
        + f"\n```{{toctree}}\n:hidden:\n\n{toc}\n```\n"
    )
    return pages


def write(path: Path, text: str) -> None:
    """Write only when the text changed, so Sphinx rebuilds only what did."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def generate(_app: object = None) -> None:
    import frictiongym.envs  # noqa: F401  (registers the ids)
    from frictiongym.envs.scenario import load_scenario

    scenarios = [load_scenario(n) for n in scenario_names()]
    suites = suites_of()
    for env_id, cls in env_classes().items():
        mine = [s for s in scenarios if s.spec.name == cls.plant]
        write(OUT / "plants" / f"{cls.plant}.md", plant_page(env_id, cls, mine, suites))
    write(OUT / "scenarios.md", scenarios_page(scenarios, suites))
    write(OUT / "controllers.md", controllers_page(scenarios))
    pages = api_pages()
    for name, text in pages.items():
        write(OUT / "api" / name, text)
    for old in (OUT / "api").glob("*.md"):  # a module that moved or left: its page goes too
        if old.name not in pages:
            old.unlink()
    write(OUT / "env_versions.md", env_versions())


def plain_docstring(_app: object, _what: str, _name: str, _obj: object, _opts: object, lines: list) -> None:
    """The project's docstrings are plain text (units, formulas, aligned tables), not reStructuredText:
    render them as written. Outside ``inline literals``, | and * are escaped (|e| is not a substitution,
    configs/*.yaml not emphasis); a bullet list ("- " items, their lines continued two spaces in) stays a
    list; any other indented block (a formula, a table) becomes a literal block."""
    out: list[str] = []
    base = min((len(x) - len(x.lstrip()) for x in lines if x.strip()), default=0)
    in_block = in_list = False
    for line in lines:
        indent = len(line) - len(line.lstrip())
        item = line.strip().startswith("- ") and indent == base
        if item and not in_list:  # a list starts: a blank line before it
            if out and out[-1].strip():
                out.append("")
            in_list, in_block = True, False
        elif in_list and line.strip() and not item and indent != base + 2:
            out.append("")  # the list ends: a blank line after it
            in_list = False
        if not in_list and line.strip() and indent > base and not in_block:
            if out and out[-1].strip():
                out.append("")
            out += [" " * base + "::", ""]
            in_block = True
        elif line.strip() and indent <= base:
            if in_block:
                out.append("")
            in_block = False
        if in_block:
            out.append(line)
            continue
        parts = line.split("``")
        for i in range(0, len(parts), 2):  # even parts lie outside inline literals
            parts[i] = parts[i].replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*")
        out.append("``".join(parts))
    lines[:] = out


def setup(app: object) -> dict:
    app.connect("builder-inited", generate)
    app.connect("autodoc-process-docstring", plain_docstring)
    return {"parallel_read_safe": True, "version": "1"}
