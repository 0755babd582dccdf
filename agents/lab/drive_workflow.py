"""Bringing a real drive into the suite (docs/emps.md): identify it from its closed-loop logs, draft its
plant preset, and check the simulated drive against a measurement. Compute (`identify`, `check`),
render (`*_markdown`) and write (`write_*`) are apart; scripts/identify.py is the front end.

The EMPS logs are the default and the worked example; any drive log of the documented CSV columns
(drive_log.py) takes the same path.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from frictiongym.envs.config import ConfigError, load_yaml
from frictiongym.envs.records import atomic_text

from . import closed_loop, idim
from .drive_log import DriveLog, emps_log, read_drive_log


@dataclass(frozen=True)
class IdentifyOptions:
    """What to identify: the estimation log and, optionally, a validation log for the cross-test (None:
    the EMPS sets), the structures and actuation delays of the table, and the processing (EMPS §3)."""

    estimation: Path | None = None
    validation: Path | None = None
    structures: tuple[str, ...] = tuple(idim.STRUCTURES)
    delays: tuple[int, ...] = (0, 1)
    settings: idim.IdimSettings = field(default_factory=idim.IdimSettings)


@dataclass(frozen=True)
class Identification:
    """The logs, every fitted structure (with its cross-test when there is a validation log), and the
    fit the draft preset uses (the simulator's structure: symmetric Coulomb + viscous + offset)."""

    estimation: DriveLog
    validation: DriveLog | None
    rows: tuple[idim.ModelRow, ...]
    preset_fit: idim.Fit


def identify(opts: IdentifyOptions) -> Identification:
    """Fit every structure on the estimation log; cross-test on the validation log if there is one."""
    if opts.estimation is None:
        est, val = emps_log("estimation"), emps_log("validation")
        if opts.validation is not None:
            val = read_drive_log(opts.validation)
    else:
        est = read_drive_log(opts.estimation)
        val = read_drive_log(opts.validation) if opts.validation is not None else None
    if val is not None and val.unit != est.unit:
        raise ConfigError("validation", f"in {val.unit}, the estimation log in {est.unit}", val.source)
    unknown = sorted(set(opts.structures) - set(idim.STRUCTURES))
    if unknown:
        raise ConfigError("structures", f"unknown {unknown}; available: {sorted(idim.STRUCTURES)}")
    rows = idim.model_table(est, val, opts.structures, opts.delays, opts.settings)
    base = next(
        (r.fit for r in rows if r.fit.structure == "coulomb_viscous" and r.fit.settings == opts.settings),
        None,
    )
    if base is None:  # the table did not fit the preset's structure under the options' own processing
        base = idim.fit("coulomb_viscous", idim.states(est, opts.settings), opts.settings)
    return Identification(est, val, tuple(rows), base)


def identify_markdown(r: Identification) -> str:
    """The report: the structure table (with cross-tests), and the parameters of every fit."""
    lines = [
        "# Identification of a drive from closed-loop logs (IDIM-LS, EMPS §3)",
        "",
        f"- estimation log: `{r.estimation.source}` ({len(r.estimation.t)} samples, "
        f"{1 / r.estimation.period:.6g} Hz, drive gain {r.estimation.drive_gain:.6g})",
        f"- validation log: `{r.validation.source}`"
        if r.validation
        else "- no validation log: no cross-test",
        "",
    ]
    if r.validation is not None:
        lines += [idim.markdown_table(r.rows), ""]
    for f in (row.fit for row in r.rows):
        nl = f", {f.nonlinear[0]} profiled" if f.nonlinear else ""
        lines += [
            f"## {f.structure}, delay {f.settings.delay_samples} (estimation error "
            f"{f.relative_error_pct:.3f} %, cond {f.condition_number:.3g}{nl}"
            f"{'' if f.identifiable else ', NOT identifiable'})",
            "",
            idim.markdown_parameters(f),
            "",
        ]
    return "\n".join(lines)


def resolution(position: np.ndarray) -> float | None:
    """The encoder step of a logged position: the smallest step, if every step is a whole multiple of
    it (to 1e-6 of a step); None if the log is not on a grid (processed, or a non-quantised sensor)."""
    steps = np.abs(np.diff(position))
    steps = steps[steps > 0]
    if steps.size == 0:
        return None
    q = float(steps.min())
    n = steps / q
    return q if np.abs(n - np.round(n)).max() < 1e-6 * max(1.0, float(n.max())) else None


def draft_preset(r: Identification) -> tuple[dict[str, Any], list[str]]:
    """A plant preset for the drive (the EMPS preset's structure and module, the identified numbers) and
    the provenance of every value it changes. Linear drives only (the EMPS module is a slide joint)."""
    log, f = r.estimation, r.preset_fit
    if log.unit != "m":
        raise ConfigError(
            "unit", "the draft preset is a linear drive (m); for a rotary drive start from a hinge plant"
        )
    p = load_yaml("emps")
    src = Path(log.source).name
    prov = [f"identified by frictiongym.agents.lab (IDIM-LS, EMPS §3) from {src}"]
    mass, fc = f.value("mass_kg"), f.value("coulomb_n")
    p["description"] = f"Linear drive identified from {src}"
    p["carriage"]["mass_kg"] = mass
    fr = p["friction"]
    fr.update(
        coulomb_n=fc,
        static_n=fc,
        offset_n=f.value("offset_n"),
        viscous_n_s_per_m=f.value("viscous_n_s_per_m"),
    )
    prov.append("carriage.mass_kg, friction.coulomb_n/offset_n/viscous_n_s_per_m: the symmetric fit (eq. 1)")
    lugre = next((x.fit for x in r.rows if x.fit.structure == "lugre_asym" and x.fit.identifiable), None)
    if lugre is not None:  # presliding length resolved by this log: σ0 = Fc/L, critically damped σ1
        fr["sigma0_n_per_m"] = fc / lugre.extra()
        prov.append(f"friction.sigma0_n_per_m: Fc / presliding length {lugre.extra():.3g} m (lugre_asym)")
    else:
        prov.append("friction.sigma0_n_per_m: the EMPS's (the presliding length is not resolved by this log)")
    fr["sigma1_n_s_per_m"] = 2 * math.sqrt(fr["sigma0_n_per_m"] * mass)
    p["actuator"]["gain_n_per_v"] = log.drive_gain
    prov.append("actuator.gain_n_per_v: the log's drive gain")
    if log.kp is not None and log.kv is not None:
        p["lab_controller"].update(kp_per_s=log.kp, kv_v_per_m_s=log.kv)
        prov.append("lab_controller: the log's kp, kv")
    p["sampling"]["control_period_s"] = round(log.period, 9)
    # four physics steps per period, finer if the bristles need it (h·sqrt(σ0/M) <= 0.13 at nominal)
    h = min(log.period / 4, 0.13 / math.sqrt(fr["sigma0_n_per_m"] / mass))
    p["sampling"]["timestep_s"] = log.period / math.ceil(log.period / h)
    prov.append("sampling: the log's period; timestep for the bristle numerics (docs/physics.md)")
    res = resolution(log.position)
    if res is not None:
        p["sensors"]["encoder"]["resolution_m"] = res
        prov.append(f"sensors.encoder.resolution_m: the log's position grid ({res:.3g} m)")
    else:
        prov.append("sensors.encoder.resolution_m: the EMPS's (the log's position is not on a grid)")
    prov.append("randomization: the EMPS's ranges; set them from your fits' spread (docs/emps.md)")
    _all_finite(p, log.source)
    return p, prov


def _all_finite(node: Any, source: str, path: str = "") -> None:
    """Refuse a draft preset holding a NaN or an infinite number (a fit that failed), naming its key: a
    preset is never written with one."""
    if isinstance(node, dict):
        for k, v in node.items():
            _all_finite(v, source, f"{path}{k}.")
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _all_finite(v, source, f"{path}{i}.")
    elif isinstance(node, float) and not math.isfinite(node):
        raise ConfigError(path.rstrip("."), f"the identified value is {node}: no preset written", source)


def write_identification(r: Identification, out: Path) -> list[Path]:
    """report.md, result.json (every fit) and, for a linear drive, plant.yaml (the draft preset)."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "report.md", out / "result.json"]
    atomic_text(written[0], identify_markdown(r))
    res = [
        {
            "structure": f.structure,
            "delay_samples": f.settings.delay_samples,
            "parameters": {n: float(x) for n, x in zip(f.names, f.theta, strict=True)},
            "std": {n: float(x) for n, x in zip(f.names, f.std, strict=True)},
            "nonlinear": {f.nonlinear[0]: f.nonlinear[1].value} if f.nonlinear else {},
            "estimation_relative_error_pct": f.relative_error_pct,
            "cross_test_relative_error_pct": v.relative_error_pct if v is not None else None,
            "condition_number": f.condition_number,
            "identifiable": f.identifiable,
        }
        for f, v in ((row.fit, row.validation) for row in r.rows)
    ]
    atomic_text(written[1], json.dumps(res, indent=1))
    if r.estimation.unit == "m":
        preset, prov = draft_preset(r)
        head = "".join(f"# {line}\n" for line in prov)
        atomic_text(out / "plant.yaml", head + yaml.safe_dump(preset, sort_keys=False))
        written.append(out / "plant.yaml")
    return written


def check(
    log: Path | None, plant: str | None = None, controller: str = "LabPD"
) -> list[closed_loop.Comparison]:
    """The simulated drive against a measured log in closed loop (the EMPS sets without a log), and the
    open-loop simulation on the log's ν."""
    if log is None:
        return [closed_loop.closed_loop(w, controller) for w in closed_loop.SCENARIOS] + [
            closed_loop.open_loop(w) for w in closed_loop.SCENARIOS
        ]
    d = read_drive_log(log)
    return [closed_loop.closed_loop(d, controller, plant=plant), closed_loop.open_loop(d, plant)]


def check_markdown(comparisons: list[closed_loop.Comparison]) -> str:
    """Relative errors (%) of every signal and the position RMSE, one row per comparison."""
    lines = [
        "| log | loop | "
        + " | ".join(f"{s} rel. error %" for s in closed_loop.SIGNALS)
        + " | position RMSE (m) |",
        "|---|---|" + "---|" * (len(closed_loop.SIGNALS) + 1),
    ]
    n = len(comparisons) // 2
    for i, c in enumerate(comparisons):
        errs = " | ".join(f"{c.relative_error_pct[s]:.4g}" for s in closed_loop.SIGNALS)
        lines.append(
            f"| {Path(c.log).name} | {'closed' if i < n else 'open'} | {errs} | {c.position_rmse_m:.3g} |"
        )
    return "\n".join(lines)


SCAN_KNOBS = ("sigma0_n_per_m", "delay_s")  # what `scan` varies (the preset values the data choose between)


def scan(
    knob: str, values: tuple[float, ...], log: Path | None = None, plant: str | None = None
) -> list[tuple[float, closed_loop.Comparison]]:
    """The closed-loop check repeated over values of one preset knob: the bristle stiffness σ0 (with σ1
    kept critically damped, 2·sqrt(σ0·M)) or the actuation delay; on the EMPS estimation log without
    `log`. How configs/plants/emps.yaml chose both (docs/emps.md)."""
    if knob not in SCAN_KNOBS:
        raise ConfigError("scan", f"{knob!r} not in {list(SCAN_KNOBS)}")
    spec_path = plant or "emps"
    mass = load_yaml(spec_path)["carriage"]["mass_kg"]
    which = read_drive_log(log) if log is not None else "estimation"
    out = []
    for x in values:
        if knob == "delay_s":
            ov = {"sampling": {"delay_s": x}}
        else:
            ov = {"friction": {"sigma0_n_per_m": x, "sigma1_n_s_per_m": 2 * math.sqrt(x * mass)}}
        out.append((x, closed_loop.closed_loop(which, overrides={"plant_overrides": ov}, plant=plant)))
    return out


def scan_markdown(knob: str, rows: list[tuple[float, closed_loop.Comparison]]) -> str:
    """One row per value: the relative errors (%) of every signal."""
    lines = [f"| {knob} | " + " | ".join(f"{s} %" for s in closed_loop.SIGNALS) + " |"]
    lines.append("|---|" + "---|" * len(closed_loop.SIGNALS))
    for x, c in rows:
        lines.append(
            f"| {x:g} | " + " | ".join(f"{c.relative_error_pct[s]:.4g}" for s in closed_loop.SIGNALS) + " |"
        )
    return "\n".join(lines)
