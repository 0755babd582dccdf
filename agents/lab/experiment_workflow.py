"""The identification workflow behind scripts/identify.py: get the data (a CSV log, a simulated experiment,
or the M220 document's own numbers), fit, and write the report, plots, result.json and identified.yaml
(a scenario override the envs load: gym.make(..., overrides=yaml.safe_load(open("identified.yaml")))).
"""

from __future__ import annotations

import datetime
import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from tqdm import tqdm

from frictiongym.envs.config import configs_dir
from frictiongym.envs.plants import plant_config, plant_spec
from frictiongym.envs.records import atomic_text, command_line, package_version, pyplot

from ..figures import save_figure
from . import experiments as ex
from .fits import (
    IDENTIFIABLE,
    Estimate,
    FrictionId,
    Log,
    coulomb_viscous_fit,
    fit_step,
    identify_coulomb_viscous,
    identify_lugre,
    identify_simulated,
    read_log,
    rows_reproducing,
    static_friction_model,
    step_through_points,
    truth_values,
    two_point_step_id,
    write_log,
)

TABLE = "iurian2005_m220_friction_table.csv"
IDENTIFIED = "identified.yaml"  # the override file an identification writes
RECOMMENDED_MIN_SPEED_COUNTS_S = 7000.0  # above the low-speed hump of rows 1-4 (stick-slip, Stribeck)


def provenance(data: str) -> str:
    """One line: the data (file and SHA-256, or the simulation), the command, package and date."""
    p = Path(data)
    what = f"{data} (sha256 {hashlib.sha256(p.read_bytes()).hexdigest()[:16]})" if p.is_file() else data
    today = datetime.date.today().isoformat()
    return f"data: {what}; command: {command_line()}; frictiongym {package_version()}; {today}"


def write_identified(out: Path, values: dict[str, float], source: str) -> Path:
    """identified.yaml: the scenario override that puts the identified friction into a plant."""
    body = {
        "plant_overrides": {
            "friction_identified": {**{k: float(v) for k, v in values.items()}, "source": source}
        }
    }
    text = (
        "# Drive-referred friction identified by scripts/identify.py (command units, rad/s). Load it with\n"
        '#   gym.make("frictiongym/<Plant>-v1", scenario=...,\n'
        '#            overrides=yaml.safe_load(open("identified.yaml")))\n'
        + yaml.safe_dump(body, sort_keys=False)
    )
    path = out / IDENTIFIED
    atomic_text(path, text)
    return path


def _fmt(e: Estimate) -> str:
    ci = "" if not (math.isfinite(e.low) and math.isfinite(e.high)) else f" [{e.low:.5g}, {e.high:.5g}]"
    return f"{e.value:.6g}{ci}"


def _plot_static(fid: FrictionId, unit: str, path: Path, truth: dict[str, float] | None = None) -> None:
    plt = pyplot()

    v = fid.values()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for d, sign in (("pos", 1), ("neg", -1)):
        sp, cmd = fid.points[d]
        ax.plot(sp, cmd, "o", label=f"steady holds ({d})")
        grid = np.geomspace(max(abs(sp).min() / 3, 1e-6), abs(sp).max(), 200)
        model = static_friction_model(
            grid, v[f"coulomb_{d}"], v[f"static_{d}"], v["stribeck_velocity_rad_s"], v["viscous_per_rad_s"]
        )
        ax.plot(sign * grid, sign * model, "-", label=f"fit ({d})")
        if truth is not None:
            tm = static_friction_model(
                grid,
                truth[f"coulomb_{d}"],
                truth[f"static_{d}"],
                truth["stribeck_velocity_rad_s"] if math.isfinite(truth["stribeck_velocity_rad_s"]) else 1.0,
                truth["viscous_per_rad_s"],
            )
            ax.plot(sign * grid, sign * tm, "k:", lw=1, label="truth" if d == "pos" else None)
    ax.set(xlabel="speed (rad/s)", ylabel=f"command ({unit})", xscale="symlog", title="steady-state friction")
    ax.axhline(0, color="0.8", lw=0.5)
    ax.legend(fontsize=7)
    save_figure(fig, path.parent, path.name, dpi=90)


# ------------------------------------------------------------------------------------------- step
def step_from_document() -> tuple[str, dict[str, Any]]:
    """§2.2: the two-point method as printed, and the full model through the same two points."""
    doc = plant_spec("m220").document
    t, y, v = tuple(doc.step_points_t_s), tuple(doc.step_points_counts), doc.step_input_v
    two = two_point_step_id(t, y, v)
    full = step_through_points(t, y, v)
    lines = [
        "## §2.2 step identification from the document's two points",
        "",
        f"Points (t s, counts): {list(zip(t, y, strict=True))}, step v = {v} V.",
        "",
        f"- Two-point line (as printed): α1 = {two['alpha1']:.3f}, α2 = {two['alpha2']:.3f}, "
        f"a = {two['a']:.6f} 1/s, k = {two['k']:.3f} counts/(V·s²) (document: "
        f"{doc.document_a_per_s}, {doc.document_k_counts_per_v_s2}).",
        f"- Full response θ = α1·t + α2 + α3·e^(-a·t) through the same points: a = {full['a']:.6f} 1/s, "
        f"k = {full['k']:.3f} counts/(V·s²): a differs by {full['a'] / two['a'] - 1:+.2%}, k by "
        f"{full['k'] / two['k'] - 1:+.2%}. The two-point line ignores the exponential term (ERRATA 000), so "
        "the printed model does not pass through the points it was fitted to: it predicts "
        + ", ".join(
            f"{float(p):.0f}"
            for p in (
                two["alpha1"] * np.array(t) + two["alpha2"] - two["alpha2"] * np.exp(-two["a"] * np.array(t))
            )
        )
        + " counts at the two times.",
    ]
    return "\n".join(lines), {"two_point": two, "full_through_points": full}


def step_from_log(log: Log, v: float) -> tuple[str, dict[str, Any]]:
    """Least-squares k, a of k/(s(s+a)) from a step log (position), and the two-point method on its last
    points."""
    if log.position is None:
        raise ValueError("a step fit needs a position column (k/(s(s+a)) is the position response)")
    t = log.t - log.t[0]
    theta = log.position - log.position[0]
    fit = fit_step(t, theta, v)
    i, j = int(0.88 * (len(t) - 1)), len(t) - 1  # two late points, as in §2.2 (4.44 and 4.91 s of 5 s)
    two = two_point_step_id((t[i], t[j]), (theta[i], theta[j]), v)
    text = "\n".join(
        [
            "## Step identification",
            "",
            f"- Least squares, full response: k = {_fmt(fit['k'])} rad/(cu·s²), a = {_fmt(fit['a'])} 1/s.",
            f"- Two-point line at t = {t[i]:.2f}, {t[j]:.2f} s: k = {two['k']:.6g}, a = {two['a']:.6g} "
            f"({two['k'] / fit['k'].value - 1:+.1%}, {two['a'] / fit['a'].value - 1:+.1%} from the full "
            "fit).",
            "- Friction acts as an input offset: k here is the gain for the step minus the Coulomb level "
            "(the §2.2 model has no friction).",
        ]
    )
    return text, {"least_squares": {k: vars(e) for k, e in fit.items()}, "two_point": two}


# ------------------------------------------------------------------------------------------- friction
def _m220_rad_per_count() -> float:
    """The M220 encoders' resolution (rad per count), from the plant's configuration (§2.2)."""
    return plant_spec("m220").document.rad_per_count


def document_lines() -> dict[str, tuple[str, str]]:
    """§2.3's fitted lines as printed: (slope V·s/count, intercept V) per direction, as strings (their
    digits matter). They are the M220 preset's friction (configs/plants/m220.yaml); the shortest repr of
    a float gives back the printed digits (none of them ends in 0)."""

    def printed(x: float) -> str:
        return re.sub(r"e([+-])0+(\d)", r"e\1\2", repr(x))  # 2.3517e-06 -> 2.3517e-6, as printed

    f = plant_config("m220")["friction"]
    return {
        "up": (printed(f["viscous_pos_v_s_per_count"]), printed(f["coulomb_pos_v"])),
        "down": (printed(f["viscous_neg_v_s_per_count"]), printed(-f["coulomb_neg_v"])),
    }


def document_table() -> dict[str, np.ndarray]:
    """The §2.3 table (configs/published), counts/s and V."""
    t = np.genfromtxt(configs_dir() / "published" / TABLE, delimiter=",", names=True)
    return {k: np.asarray(t[k]) for k in t.dtype.names}


def friction_from_document() -> tuple[str, dict[str, Any], dict[str, float]]:
    """§2.3: which rows reproduce the printed lines (exhaustive search), and the recommended fit with 95 %
    intervals (rows above 7000 counts/s). Returns the report, the results and the override values (the
    recommended fit, in V and V·s/rad)."""
    t, printed = document_table(), document_lines()
    rad = _m220_rad_per_count()
    res: dict[str, Any] = {}
    lines = ["## §2.3 Coulomb + viscous friction from the document's table", ""]
    for d, (vk, uk) in (
        ("up", ("velocity_up_counts_per_s", "control_up_V")),
        ("down", ("velocity_down_counts_per_s", "control_down_V")),
    ):
        slope, intercept = printed[d]
        rows = rows_reproducing(t[vk], t[uk], slope, intercept)
        all_rows = coulomb_viscous_fit(t[vk], t[uk])
        rec = coulomb_viscous_fit(t[vk], t[uk], RECOMMENDED_MIN_SPEED_COUNTS_S)
        res[d] = {
            "rows_reproducing_printed": rows,
            "all_rows": {
                "coulomb_V": vars(all_rows.coulomb),
                "viscous_V_s_per_count": vars(all_rows.viscous),
            },
            "recommended": {
                "coulomb_V": vars(rec.coulomb),
                "viscous_V_s_per_count": vars(rec.viscous),
                "rows": rec.points,
            },
        }
        only = f"exactly one subset, rows {rows[0]}" if len(rows) == 1 else f"{len(rows)} subsets: {rows}"
        lines += [
            f"**{d}** (printed F_v = {slope} V·s/count, F_C = {intercept} V):",
            "",
            f"- Of all 65,519 subsets of two or more of the 16 rows, {only} gives a least-squares line that "
            "rounds to both printed numbers: the authors left out "
            f"rows {sorted(set(range(1, 17)) - set(rows[0]))}"
            if rows
            else "- no subset reproduces the printed line",
            f"- All 16 rows: F_C = {_fmt(all_rows.coulomb)} V, F_v = {_fmt(all_rows.viscous)} V·s/count.",
            f"- Recommended (rows with |v| >= {RECOMMENDED_MIN_SPEED_COUNTS_S:.0f} counts/s, {rec.points} "
            f"rows, past the low-speed hump of rows 1-4): F_C = {_fmt(rec.coulomb)} V, "
            f"F_v = {_fmt(rec.viscous)} V·s/count (95 % intervals).",
            "",
        ]
    up, down = res["up"]["recommended"], res["down"]["recommended"]
    values = {
        "coulomb_pos": up["coulomb_V"]["value"],
        "coulomb_neg": -down["coulomb_V"]["value"],
        "viscous_per_rad_s": 0.5
        * (up["viscous_V_s_per_count"]["value"] + down["viscous_V_s_per_count"]["value"])
        / rad,
    }
    lines.append(
        "The identified plant (identified.yaml) takes the recommended lines: F_v is the mean of the two "
        "directions (the simulator has one σ2), the static levels equal the Coulomb ones (the table shows no "
        "consistent Stribeck rise) and vs is the preset's."
    )
    return "\n".join(lines), res, values


def friction_report(fid: FrictionId, unit: str, truth: dict[str, float] | None, title: str) -> str:
    lines = [f"## {title}", "", "| parameter | estimate [95 % CI] | truth | error |", "|---|---|---|---|"]
    for k, e in fid.estimates.items():
        tv = truth.get(k) if truth else None
        err = f"{e.value / tv - 1:+.2%}" if tv and math.isfinite(tv) and k not in fid.unidentified else ""
        mark = " (not identified)" if k in fid.unidentified else ""
        lines.append(f"| {k}{mark} | {_fmt(e)} | {'' if tv is None else f'{tv:.6g}'} | {err} |")
    lines += ["", f"Units: levels in {unit}, speeds rad/s, viscous {unit}·s/rad, σ0 {unit}/rad.", ""]
    lines += [f"- {n}" for n in fid.notes]
    lines += ["", "What each experiment identifies:", ""] + [f"- {k}: {v}" for k, v in IDENTIFIABLE.items()]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------- run
@dataclass(frozen=True)
class IdentifyOptions:
    """One identification (scripts/identify.py's options): what to identify and from which data; exactly
    one of csv, simulate and document gives the data. Units: SI and the plant's command unit (cu)."""

    kind: str  # "step" (k, a of the open-loop step), "friction" (Coulomb + viscous) or "lugre"
    csv: Path | None = None  # a hardware log: the holds (friction, lugre) or the step (step)
    simulate: str | None = None  # a plant preset: run the identification experiments on its simulation
    seed: int = 0  # the simulated plant's draw (with randomize) and its noise
    randomize: bool = False  # simulate a randomised draw of the plant instead of the nominal preset
    document: bool = False  # the M220 document's own numbers (Iurian et al. 2005 §2.2-2.3): step or friction
    breakaway: tuple[Path, float] | None = None  # a breakaway-ramp log and its threshold speed (rad/s)
    presliding: tuple[Path, float, float] | None = None  # a presliding log, amplitude (cu), frequency (Hz)
    step_v: float | None = None  # the step command of a --csv step log (cu)
    min_speed: float = 0.0  # rad/s: holds below it are left out of the Coulomb + viscous fit


@dataclass
class Identification:
    """What one identification computed: the report's text, result.json's content, the override's
    values (None for a step), the logs of a simulated experiment, and what its figure shows."""

    data: str  # where the data came from (a file, the simulation, the document)
    text: str
    results: dict[str, Any]
    values: dict[str, float] | None = None
    logs: dict[str, Log] = field(default_factory=dict)  # simulated experiments (written to logs/)
    fid: FrictionId | None = None  # a friction fit (figure fit_friction.png)
    unit: str = ""
    truth: dict[str, float] | None = None  # a simulated plant's true values (drawn on the lugre figure)
    table: dict[str, np.ndarray] | None = None  # the document's table (its figure)


def identify(o: IdentifyOptions) -> Identification:
    """Compute one identification: read or simulate the data, fit, and compose the report."""
    truth, proto = None, None
    logs: dict[str, Log] = {}
    simulated: dict[str, Log] = {}
    if o.simulate is not None:
        rig, proto = ex.Rig.of(o.simulate, o.seed, o.randomize), ex.protocol(o.simulate)
        want = {"step": ("step",), "friction": ("holds",), "lugre": ("holds", "breakaway", "presliding")}
        logs = simulated = ex.run_all(rig, proto, want[o.kind])
        truth = truth_values(rig.spec)
        data = f"simulated {o.simulate} (seed {o.seed}, randomize {o.randomize})"
    elif o.csv is not None:
        logs = {"step" if o.kind == "step" else "holds": read_log(o.csv)}
        if o.breakaway is not None:
            logs["breakaway"] = read_log(o.breakaway[0])
        if o.presliding is not None:
            logs["presliding"] = read_log(o.presliding[0])
        data = str(o.csv)
    elif not o.document:
        raise ValueError("give one of --csv, --simulate or --document")
    else:
        data = f"Iurian et al. 2005 §2.2-2.3 (configs/published/{TABLE})"
    ident = Identification(data, "", {"kind": o.kind, "data": data}, logs=simulated, truth=truth)
    sections = [f"# Identification ({o.kind}): {data}", ""]
    if o.kind == "step":
        if o.document:
            text, res = step_from_document()
        else:
            v = o.step_v if o.step_v is not None else (proto.step_v if proto else None)
            if v is None:
                raise ValueError("--step-v (the step command of the log) is required with --csv")
            text, res = step_from_log(logs["step"], v)
        sections.append(text)
        ident.results["step"] = res
    elif o.kind == "friction" and o.document:
        text, res, ident.values = friction_from_document()
        sections.append(text)
        ident.results["friction"] = res
        ident.table = document_table()
    else:
        ident.unit = logs["holds"].command_unit
        if o.kind == "friction":
            fid = identify_coulomb_viscous(logs["holds"], o.min_speed)
        else:
            brk = None
            if "breakaway" in logs:
                brk = (logs["breakaway"], o.breakaway[1] if o.breakaway else proto.threshold)
            pre = None
            if "presliding" in logs:
                amplitude_hz = (
                    o.presliding[1:] if o.presliding else (proto.presliding_amplitude, proto.presliding_hz)
                )
                pre = (logs["presliding"], *amplitude_hz)
            fid = identify_lugre(logs["holds"], brk, pre)
        values = {
            k: v
            for k, v in fid.values().items()
            if k not in fid.unidentified or k == "stribeck_velocity_rad_s"
        }
        if o.kind == "friction":
            values = {k: values[k] for k in ("coulomb_pos", "coulomb_neg", "viscous_per_rad_s")}
        elif "stribeck_velocity_rad_s" in fid.unidentified:
            values.pop("stribeck_velocity_rad_s")
        title = "Friction" if o.kind == "friction" else "LuGre"
        sections.append(friction_report(fid, ident.unit, truth, title))
        ident.results |= {
            "estimates": {k: vars(e) for k, e in fid.estimates.items()},
            "unidentified": sorted(fid.unidentified),
            "notes": fid.notes,
            "truth": truth,
        }
        ident.fid, ident.values = fid, values
        if o.kind != "lugre":
            ident.truth = None  # the Coulomb + viscous figure draws no truth
    if ident.values is not None:
        sections += ["", f"Override for the envs: `{IDENTIFIED}` ({', '.join(ident.values)})."]
        ident.results["identified"] = ident.values
    ident.text = "\n".join(sections) + "\n"
    return ident


def write(ident: Identification, out: Path) -> None:
    """Write an identification into out/: logs/ (simulated experiments), fit_friction.png, identified.yaml,
    report.md and result.json, each atomically."""
    out.mkdir(parents=True, exist_ok=True)
    if ident.logs:
        (out / "logs").mkdir(exist_ok=True)
        for name, log in ident.logs.items():
            write_log(out / "logs" / f"{name}.csv", log)
    if ident.table is not None:
        _plot_document(ident.table, ident.values, out / "fit_friction.png")
    elif ident.fid is not None:
        _plot_static(ident.fid, ident.unit, out / "fit_friction.png", ident.truth)
    if ident.values is not None:
        write_identified(out, ident.values, provenance(ident.data))
    atomic_text(out / "report.md", ident.text)
    atomic_text(out / "result.json", json.dumps(ident.results, indent=1, default=float))


def run(options: IdentifyOptions, out: Path) -> str:
    """One identification into out/; returns the report's text."""
    ident = identify(options)
    write(ident, out)
    return ident.text


def _plot_document(t: dict[str, np.ndarray], values: dict[str, float], path: Path) -> None:
    plt = pyplot()

    rad = _m220_rad_per_count()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for vk, uk, c, s in (
        ("velocity_up_counts_per_s", "control_up_V", "coulomb_pos", 1),
        ("velocity_down_counts_per_s", "control_down_V", "coulomb_neg", -1),
    ):
        ax.plot(t[vk], t[uk], "o", label=f"table ({'up' if s > 0 else 'down'})")
        v = np.linspace(0, abs(t[vk]).max(), 50) * s
        ax.plot(v, s * values[c] + values["viscous_per_rad_s"] * rad * v, "-", label="recommended fit")
    ax.set(xlabel="velocity (counts/s)", ylabel="control (V)", title="Iurian et al. 2005 §2.3")
    ax.legend(fontsize=7)
    save_figure(fig, path.parent, path.name, dpi=90)


def recovery(plants: list[str], draws: int) -> tuple[str, dict[str, dict[str, list[float]]]]:
    """The acceptance study: LuGre identification on `draws` randomised plants per plant (noise and
    quantisation on): the relative error of every identified parameter. Returns a markdown table."""

    errors: dict[str, dict[str, list[float]]] = {}
    for plant in plants:
        p = ex.protocol(plant)
        errors[plant] = {}
        for seed in tqdm(range(draws), desc=f"recovery {plant}", unit="plant"):
            rig = ex.Rig.of(plant, seed, True)
            fid = identify_simulated(ex.run_all(rig, p, ("holds", "breakaway", "presliding")), p)
            tv = truth_values(rig.spec)
            for k, e in fid.estimates.items():
                if k in tv and math.isfinite(tv[k]) and k not in fid.unidentified:
                    errors[plant].setdefault(k, []).append(e.value / tv[k] - 1)
    lines = [
        "| plant | parameter | draws identified | max abs error | mean error |",
        "|---|---|---|---|---|",
    ]
    for plant, by in errors.items():
        for k, v in by.items():
            lines.append(
                f"| {plant} | {k} | {len(v)}/{draws} | {np.max(np.abs(v)):.2%} | {np.mean(v):+.2%} |"
            )
    return "\n".join(lines) + "\n", errors
