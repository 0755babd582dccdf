"""The EMPS benchmark (Janot, Gautier, Brunot 2019) on its real measurements: the IDIM-LS estimates of §3.4
(symmetric friction), its cross-test on the pulses set, and the asymmetric fit of §4.2, recomputed from
the data by frictiongym.agents.lab.idim; then which friction structure of the suite explains the drive
best (fitted on the estimation set only, cross-tested on the validation set)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from ..lab import idim
from . import Section, published_node, row, save_figure

# The published estimates are printed to 4 decimals: 1e-4 absolute is twice their rounding. The relative
# errors and norms are printed to 4-5 significant digits: 1e-4 relative.
PRINTED_ABS = 1e-4
PRINTED_REL = 1e-4
NOTE = "recomputed from the data with MATLAB-compatible filtfilt/decimate (printed to 4 decimals)"


def _by(rows: tuple[idim.ModelRow, ...], structure: str, delay: int) -> idim.ModelRow:
    return next(r for r in rows if r.fit.structure == structure and r.delay_samples == delay)


def idim_rows(rows: tuple[idim.ModelRow, ...]) -> Iterator[dict]:
    pub = published_node("emps2019").section("idim_ls")
    sym = _by(rows, "coulomb_viscous", 0)
    s = pub.section("symmetric")
    for name in sym.fit.names:
        value, std = s.get(name)
        yield row(f"emps.idim.{name}", value, sym.fit.value(name), PRINTED_ABS, relative=False, note=NOTE)
        i = sym.fit.names.index(name)
        yield row(f"emps.idim.{name}.std", std, sym.fit.std[i], PRINTED_ABS, relative=False, note="§3.4")
    for key, got in (
        ("relative_error_pct", sym.fit.relative_error_pct),
        ("error_norm_n", sym.fit.error_norm),
        ("condition_number", sym.fit.condition_number),
    ):
        yield row(f"emps.idim.{key}", s.number(key), got, PRINTED_REL, note="§3.4, eq. (11)")
    c = pub.section("cross_test")
    for key, got in (
        ("relative_error_pct", sym.validation.relative_error_pct),
        ("error_norm_n", sym.validation.error_norm),
        ("condition_number", sym.validation.condition_number),
    ):
        yield row(f"emps.cross_test.{key}", c.number(key), got, PRINTED_REL, note="§3.4, DATA_EMPS_PULSES")
    asym = _by(rows, "coulomb_viscous_asym", 0)
    a = pub.section("asymmetric")
    for name in asym.fit.names:
        value, std = a.get(name)
        i = asym.fit.names.index(name)
        yield row(f"emps.asym.{name}", value, asym.fit.value(name), PRINTED_ABS, relative=False, note="§4.2")
        yield row(f"emps.asym.{name}.std", std, asym.fit.std[i], PRINTED_ABS, relative=False, note="§4.2")
    for key, got in (
        ("relative_error_pct", asym.fit.relative_error_pct),
        ("error_norm_n", asym.fit.error_norm),
        ("condition_number", asym.fit.condition_number),
    ):
        yield row(f"emps.asym.{key}", a.number(key), got, PRINTED_REL, note="§4.2")


def best(rows: tuple[idim.ModelRow, ...]) -> idim.ModelRow:
    """The identifiable structure with the lowest cross-test error (the table ranks by it; the fits never
    saw the validation set)."""
    return min((r for r in rows if r.fit.identifiable), key=lambda r: r.validation.relative_error_pct)


def figures(rows: tuple[idim.ModelRow, ...], out: Path) -> list[str]:
    """Cross-test force: measured, the published symmetric model, and the best structure of the table."""
    import matplotlib.pyplot as plt

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
