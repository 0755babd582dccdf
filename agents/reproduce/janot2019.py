"""The EMPS benchmark (Janot, Gautier, Brunot 2019) on its real measurements: the IDIM-LS estimates of §3.4
(symmetric friction), its cross-test on the pulses set, and the asymmetric fit of §4.2, recomputed from
the data by frictiongym.agents.lab.idim; then which friction structure of the suite explains the drive
best (fitted on the estimation set only, cross-tested on the validation set); and the simulated drive
(configs/plants/emps.yaml) in closed loop against both measured logs (§3.5)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from frictiongym.envs.config import Node
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.records import pyplot

from ..figures import save_figure
from ..lab import closed_loop, idim
from ..lab.drive_log import emps_log
from .report import Section, published_node, row

# The published estimates are printed to 4 decimals: 1e-4 absolute is twice their rounding. The relative
# errors and norms are printed to 4-5 significant digits: 1e-4 relative.
PRINTED_ABS = 1e-4
PRINTED_REL = 1e-4
NOTE = "recomputed from the data with MATLAB-compatible filtfilt/decimate (printed to 4 decimals)"


def _by(rows: tuple[idim.ModelRow, ...], structure: str, delay: int) -> idim.ModelRow:
    return next(r for r in rows if r.fit.structure == structure and r.delay_samples == delay)


def _figure_rows(prefix: str, printed: Node, x: idim.Fit | idim.Validation, note: str) -> Iterator[dict]:
    """The relative error, error norm and condition number of a fit or cross-test against the printed."""
    for key, got in (
        ("relative_error_pct", x.relative_error_pct),
        ("error_norm_n", x.error_norm),
        ("condition_number", x.condition_number),
    ):
        yield row(f"{prefix}.{key}", printed.number(key), got, PRINTED_REL, note=note)


def idim_rows(rows: tuple[idim.ModelRow, ...]) -> Iterator[dict]:
    pub = published_node("emps2019").section("idim_ls")
    sym = _by(rows, "coulomb_viscous", 0)
    s = pub.section("symmetric")
    for name in sym.fit.names:
        value, std = s.get(name)
        yield row(f"emps.idim.{name}", value, sym.fit.value(name), PRINTED_ABS, relative=False, note=NOTE)
        i = sym.fit.names.index(name)
        yield row(f"emps.idim.{name}.std", std, sym.fit.std[i], PRINTED_ABS, relative=False, note="§3.4")
    yield from _figure_rows("emps.idim", s, sym.fit, "§3.4, eq. (11)")
    c = pub.section("cross_test")
    yield from _figure_rows("emps.cross_test", c, sym.validation, "§3.4, DATA_EMPS_PULSES")
    asym = _by(rows, "coulomb_viscous_asym", 0)
    a = pub.section("asymmetric")
    for name in asym.fit.names:
        value, std = a.get(name)
        i = asym.fit.names.index(name)
        yield row(f"emps.asym.{name}", value, asym.fit.value(name), PRINTED_ABS, relative=False, note="§4.2")
        yield row(f"emps.asym.{name}.std", std, asym.fit.std[i], PRINTED_ABS, relative=False, note="§4.2")
    yield from _figure_rows("emps.asym", a, asym.fit, "§4.2")


def best(rows: tuple[idim.ModelRow, ...]) -> idim.ModelRow:
    """The identifiable structure with the lowest cross-test error (the table ranks by it; the fits never
    saw the validation set)."""
    return min((r for r in rows if r.fit.identifiable), key=lambda r: r.validation.relative_error_pct)


def figures(rows: tuple[idim.ModelRow, ...], out: Path) -> list[str]:
    """Cross-test force: measured, the published symmetric model, and the best structure of the table."""
    plt = pyplot()

    sym, top = _by(rows, "coulomb_viscous", 0), best(rows)
    fig, ax = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    v = sym.validation
    ax[0].plot(v.t, v.force, "k", lw=1.2, label="measured gτ·ν (validation set)")
    ax[0].plot(v.t, v.predicted, "b--", lw=1, label=f"symmetric (eq. 1): {v.relative_error_pct:.2f} %")
    ax[0].plot(
        top.validation.t,
        top.validation.predicted,
        "r:",
        lw=1,
        label=f"{top.fit.structure}, delay {top.delay_samples}: {top.validation.relative_error_pct:.2f} %",
    )
    ax[0].set_ylabel("force (N)")
    ax[0].legend(fontsize=8)
    ax[1].plot(v.t, v.force - v.predicted, "b", lw=0.8, label="error, symmetric")
    ax[1].plot(
        top.validation.t, top.validation.force - top.validation.predicted, "r", lw=0.8, label="error, best"
    )
    ax[1].set_ylabel("force error (N)")
    ax[1].set_xlabel("time (s)")
    ax[1].legend(fontsize=8)
    ax[0].set_title("EMPS cross-test (§3.4): force rebuilt from the validation set's motion")
    return [save_figure(fig, out, "emps_cross_test.png")]


def findings(rows: tuple[idim.ModelRow, ...], _: list[dict]) -> str:
    """The friction-model table and what it says (markdown)."""
    sym0, asym0 = _by(rows, "coulomb_viscous", 0), _by(rows, "coulomb_viscous_asym", 0)
    top = best(rows)
    beats = top.validation.relative_error_pct < min(
        sym0.validation.relative_error_pct, asym0.validation.relative_error_pct
    )
    stri = _by(rows, "stribeck_asym", top.delay_samples).fit
    drops = (stri.value("stribeck_pos_n"), stri.value("stribeck_neg_n"))
    return "\n".join(
        [
            "## EMPS: which friction structure explains the real drive",
            "",
            "Each structure is fitted on the estimation set (DATA_EMPS) only and cross-tested on the "
            "validation set (DATA_EMPS_PULSES), by the IDIM-LS processing of §3. Delay 1 is the same "
            "processing with the force aligned one sample later (gτ·ν(k-1), the archive's Simulink delay); "
            "the published processing has none. With a zero-order hold the force is half a sample behind the "
            "central-difference acceleration, so the two bracket the truth. The table ranks structures by "
            "the validation set, which none of them was fitted on.",
            "",
            idim.markdown_table(rows),
            "",
            "- Published models, evaluated the same way: symmetric "
            f"{sym0.validation.relative_error_pct:.2f} % "
            f"(§3.4 prints 5.98 %), asymmetric {asym0.validation.relative_error_pct:.2f} % (not printed).",
            f"- Best identifiable structure on the validation set: **{top.fit.structure}** with delay "
            f"{top.delay_samples}, {top.validation.relative_error_pct:.2f} % — "
            + ("better than both published models." if beats else "NOT better than both published models."),
            "- The offset of eq. (1) and the two Coulomb levels of eq. (12) are not identifiable together "
            "(cond(Φ) ~1e9): an asymmetry of the Coulomb levels *is* an offset.",
            f"- The Stribeck term comes out negative (Fs - Fc = {drops[0]:.1f} / {drops[1]:.1f} N at delay "
            f"{top.delay_samples}, Stribeck velocity {stri.extra() * 1e3:.1f} mm/s): the drive's friction "
            "*rises* to its Coulomb level over the first ~10 mm/s instead of dropping from a static peak. "
            "LuGre's static map cannot express that (its Fs >= Fc); LuGre's presliding (bristle) state "
            "captures part of it.",
            "- On the estimation set alone the unshifted processing fits better (the 100 Hz filter and the "
            "decimation blur a 1 ms shift on smooth bang-bang accelerations); on the validation set, whose "
            "pulses are sharp, every structure cross-tests better shifted. The closed loop simulated against "
            "the raw measured force settles it the other way for the plant: no delay beyond the hold "
            "(configs/plants/emps.yaml, `sampling.delay_s`).",
            "",
            "Parameters of the best structure (estimation set):",
            "",
            idim.markdown_parameters(top.fit),
            "",
        ]
    )


IDIM = Section("emps", "emps2019", idim.emps_table, idim_rows, figures, findings)


# ------------------------------------------------------------------------ simulation vs measurement
def simulation_runs() -> dict[str, closed_loop.Comparison]:
    """The nominal EMPS plant in closed loop under the lab PD on both logs, and open loop on ν."""
    out = {f"closed.{w}": closed_loop.closed_loop(w) for w in closed_loop.SCENARIOS}
    out.update({f"open.{w}": closed_loop.open_loop(w) for w in closed_loop.SCENARIOS})
    return out


SIM_NOTE = "pass: at least as close to the measurement as the description's simulation (§3.5)"


def simulation_rows(runs: dict[str, closed_loop.Comparison]) -> Iterator[dict]:
    pub = published_node("emps2019").section("simulation")
    for which in closed_loop.SCENARIOS:
        printed = pub.section(f"{which}_set_relative_error_pct")
        c = runs[f"closed.{which}"]
        for sig in closed_loop.SIGNALS:
            doc, got = printed.number(sig), c.relative_error_pct[sig]
            yield row(f"emps.sim.{which}.{sig}_pct", doc, got, float("nan"), note=SIM_NOTE, passed=got <= doc)
    v = runs["open.validation"]
    yield row(
        "emps.protocol.test_rmse_mm",
        float("nan"),
        v.position_rmse_m * 1e3,
        float("nan"),
        note="open loop on the measured ν, DATA_EMPS_PULSES (benchmark protocol); none printed: reported",
        passed=bool(np.isfinite(v.position_rmse_m)),
    )


def simulation_figures(runs: dict[str, closed_loop.Comparison], out: Path) -> list[str]:
    """Tracking error and force over time, measured against simulated, on both logs."""
    plt = pyplot()

    fig, ax = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for j, which in enumerate(closed_loop.SCENARIOS):
        c = runs[f"closed.{which}"]
        log = emps_log(which)
        keep = slice(len(log.t) - 1 - len(c.t), len(log.t) - 1)
        ref = log.reference[keep]
        ax[0, j].plot(c.t, 1e3 * (ref - log.position[keep]), "k", lw=0.8, label="measured")
        ax[0, j].plot(c.t, 1e3 * (ref - c.simulated["position"]), "r", lw=0.6, label="simulated")
        ax[0, j].set_ylabel("tracking error q_r - q (mm)")
        ax[0, j].set_title(f"{which} set ({closed_loop.SCENARIOS[which]})")
        ax[1, j].plot(c.t, c.measured["force"], "k", lw=0.8, label="measured gτ·ν")
        ax[1, j].plot(
            c.t, c.simulated["force"], "r", lw=0.6, label=f"simulated ({c.relative_error_pct['force']:.1f} %)"
        )
        ax[1, j].set_ylabel("force (N)")
        ax[1, j].set_xlabel("time (s)")
        for a in ax[:, j]:
            a.legend(fontsize=8, loc="upper right")
    return [save_figure(fig, out, "emps_sim_vs_measurement.png")]


def simulation_findings(runs: dict[str, closed_loop.Comparison], rows: list[dict]) -> str:
    """What the comparison says (markdown)."""
    lines = [
        "## EMPS: the simulated drive against its measurement",
        "",
        "The paper suite's scenarios (emps_tracking_full, emps_pulses_full) with the nominal plant under "
        "the lab PD, driven by the measured reference (and pulses); relative errors (%) of EMPS eq. (11) "
        "as §3.5 computes them.",
        "",
        "| log | signal | description's simulation | this simulator |",
        "|---|---|---|---|",
    ]
    for r in rows:
        if r["id"].startswith("emps.sim."):
            _, _, which, sig = r["id"].split(".")
            lines.append(f"| {which} | {sig[:-4]} | {r['document']:.4g} | {r['simulated']:.4g} |")
    op = {w: runs[f"open.{w}"] for w in closed_loop.SCENARIOS}
    cl = {w: runs[f"closed.{w}"] for w in closed_loop.SCENARIOS}
    counts = plant_spec("emps").sensor("encoder").resolution  # m per count
    e = cl["estimation"]
    fast = {"pos": e.simulated["velocity"] > 0.1, "neg": e.simulated["velocity"] < -0.1}
    bias = {k: float(np.mean((e.measured["force"] - e.simulated["force"])[m])) for k, m in fast.items()}
    lines += [
        "",
        f"- Closed loop, position RMSE against the raw measured position: "
        f"{cl['estimation'].position_rmse_m * 1e6:.2f} µm (estimation) and "
        f"{cl['validation'].position_rmse_m * 1e6:.2f} µm (validation): "
        f"{cl['estimation'].position_rmse_m / counts:.0f} and "
        f"{cl['validation'].position_rmse_m / counts:.0f} encoder counts.",
        f"- The measurement's force at steady speed is off the simulator's by {bias['pos']:+.1f} N (moving "
        f"positive) and {bias['neg']:+.1f} N (negative), above 0.1 m/s on the estimation set: the two "
        "viscous slopes of the asymmetric fit (§4.2, 166.7 / 240.4 N·s/m), which the simulator's one "
        "slope (MuJoCo's LuGre element is symmetric) cannot follow. It is reported, not tuned away.",
        f"- Open loop on the measured ν (the common protocol: train on DATA_EMPS, test on DATA_EMPS_PULSES): "
        f"position RMSE {op['estimation'].position_rmse_m * 1e3:.2f} mm (estimation), "
        f"**{op['validation'].position_rmse_m * 1e3:.2f} mm (test)**; the pure integrator accumulates every "
        "force error, which the closed loop rejects.",
        "- The acceleration error is the largest on the validation set, as §3.5 also finds (a flexibility "
        "excited by the pulses, which a rigid model lacks).",
        "",
    ]
    return "\n".join(lines)


SIMULATION = Section(
    "emps_sim", "emps2019", simulation_runs, simulation_rows, simulation_figures, simulation_findings
)
