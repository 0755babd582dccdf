"""Seed 001 (Kang 1998): the robot's P-ramp equilibrium bounds (eq. 6, §6), its implied Coulomb levels,
and the baselines of §6 on the nominal plant: PD (Fig. 7), Southward at 5/20/40 ms (Fig. 8) and RDFC
with δ = 0.02 / 0.04 deg (Fig. 9-10), including ERRATA 001's alternative reading of eq. (12b)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from frictiongym.agents.evaluation.evaluate import EpisodeResult, run_episode
from frictiongym.envs import units
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.records import pyplot
from frictiongym.envs.suites import Episode
from frictiongym.envs.units import rad_to_deg

from ..classical import PD, RDFC, Southward
from ..figures import save_figure
from .report import Section, published_node, row

EPISODE = Episode("kang_regulation_20deg", 0, False)  # θ(0) = 20 deg, set-point 0, 20 ms, nominal plant
SOUTHWARD_PERIODS_MS = (5, 20, 40)
DELTAS_DEG = (0.02, 0.04)


# the plant's simulated check: §6's equilibrium-region bounds from slow P-control ramps


def pd_bounds(rate_deg_s: float = 0.05) -> dict[str, float]:
    """Equilibrium-region bounds (deg) from simulated P control of slow reference ramps (the §6 method):
    the largest error held before the rotor breaks away, ramping up (θ_L) and down (θ_H). The default
    0.05 deg/s is the document's ramp: faster ramps overshoot the bound while the rotor crosses the
    Stribeck region (1.4 % at 0.5 deg/s)."""
    spec = plant_spec("kang_robot")
    period = spec.document.identification_period_s
    spec = replace(spec, control_period=period)
    kp = spec.document.kp_nm_per_rad
    out = {}
    for key, direction in (("theta_L_deg", 1.0), ("theta_H_deg", -1.0)):
        sim = PlantSim(spec)
        sim.reset()
        rate = direction * units.deg_to_rad(rate_deg_s)
        errors = []
        for k in range(round(12.0 / rate_deg_s / period)):
            r = rate * k * period
            e = sim.data.qpos[sim.dofs[0]] - r
            res = sim.step(-kp * e)
            errors.append(e)
            if abs(res.qvel[0]) > 20 * abs(rate):  # slipping: the bound was the error held just before
                break
        out[key] = units.rad_to_deg(max(errors, key=abs))
    return out


def plant_rows(bounds: dict[str, float]) -> Iterator[dict]:
    spec = plant_spec("kang_robot")
    doc = spec.document
    # printed to 0.01 deg; K_p is the mean of the two printed bounds' implied values -> 0.05 deg
    yield row(
        "kang.theta_H_deg",
        doc.theta_H_deg,
        bounds["theta_H_deg"],
        0.05,
        relative=False,
        note="simulated P-control ramp at 0.05 deg/s, §6",
    )
    yield row("kang.theta_L_deg", doc.theta_L_deg, bounds["theta_L_deg"], 0.05, relative=False, note="")
    wn = math.sqrt(doc.kp_nm_per_rad / spec.joints[0].inertia) / (2 * math.pi)
    yield row("kang.natural_frequency_hz", doc.natural_frequency_hz, wn, 0.01, note="sqrt(K_p/J)")
    lv = spec.joints[0].friction.levels()
    for key, (lo, hi) in (
        ("coulomb_pos", doc.coulomb_pos_range_nm),
        ("coulomb_neg", doc.coulomb_neg_range_nm),
    ):
        yield row(
            f"kang.{key}_nm",
            0.5 * (lo + hi),
            lv[key],
            0.5 * (hi - lo),
            relative=False,
            note="implied by the symmetric-LuGre + bias construction; document range",
        )


PLANT = Section("kang", "kang1998", pd_bounds, plant_rows)


def cycles(result: EpisodeResult) -> float:
    """Oscillation cycles before the rotor settles: half the number of sign changes of the error."""
    e = result.log["output"] - result.log["reference"]
    s = np.sign(e[e != 0])
    return 0.5 * float(np.count_nonzero(s[1:] != s[:-1]))


def baseline_runs() -> dict[str, EpisodeResult]:
    """The baselines on the LuGre plant, and again (keys ending _kang) on the paper's own friction model
    (friction_model kang: eq. 1-4, static level within a stick band, Coulomb level outside)."""
    runs = {}
    for suffix, model in (("", "lugre"), ("_kang", "kang")):
        kw = {"keep_log": True, "overrides": {"friction_model": model}}
        runs[f"pd{suffix}"] = run_episode(PD(), EPISODE, **kw)
        for ms in SOUTHWARD_PERIODS_MS:
            runs[f"southward_{ms}ms{suffix}"] = run_episode(
                Southward(), EPISODE, control_period_s=ms / 1000, **kw
            )
        for d in DELTAS_DEG:
            runs[f"rdfc_{d}{suffix}"] = run_episode(RDFC(d), EPISODE, **kw)
    for d in DELTAS_DEG:
        runs[f"rdfc_{d}_symmetric"] = run_episode(RDFC(d, "symmetric"), EPISODE, keep_log=True)
    return runs


def _published_rdfc(d: float) -> tuple[float, float]:
    p = published_node("kang1998").section("rdfc").section(f"delta_{d}_deg")
    return p.number("final_error_deg"), p.number("cycles")


def baseline_rows(runs: dict[str, EpisodeResult]) -> Iterator[dict]:
    yield from _rows(runs, "", "kang")
    yield from _rows(runs, "_kang", "kang.paper_model")
    amp = {k: rad_to_deg(runs[f"southward_20ms{k}"].metrics["limit_cycle_amp"]) for k in ("", "_kang")}
    yield row(
        "kang.paper_model.southward_20ms_over_lugre",
        float("nan"),
        amp["_kang"] / amp[""],
        float("nan"),
        note=f"Southward's 20 ms limit cycle, paper's model / LuGre ({amp['_kang']:.4f} / {amp['']:.4f} "
        "deg): > 2, the drop at once from T_s to T_0 against LuGre's over v_s = 1 deg/s",
        passed=amp["_kang"] > 2 * amp[""],
    )
    for d in DELTAS_DEG:
        s = runs[f"rdfc_{d}_symmetric"]
        res = rad_to_deg(plant_spec("kang_robot").sensors[0].resolution)
        yield row(
            f"kang.rdfc.{d}.symmetric_12b.limit_cycle_amp_deg",
            float("nan"),
            rad_to_deg(s.metrics["limit_cycle_amp"]),
            float("nan"),
            relative=False,
            note="ERRATA 001 'symmetric' reading of (12b): sustained chatter (> 10 counts) shows why the "
            "printed reading is followed",
            passed=rad_to_deg(s.metrics["limit_cycle_amp"]) > 10 * res,
        )


def _rows(runs: dict[str, EpisodeResult], k: str, prefix: str) -> Iterator[dict]:
    """PD, Southward and RDFC rows of one friction model (run keys ending k, row ids under prefix)."""
    spec = plant_spec("kang_robot")
    lo, hi = spec.document.theta_L_deg, spec.document.theta_H_deg
    e_pd = rad_to_deg(runs[f"pd{k}"].log["output"][-1])
    pd_doc = published_node("kang1998").number("pd_final_error_deg")
    yield row(
        f"{prefix}.pd.final_error_deg",
        pd_doc,
        e_pd,
        hi - lo,
        relative=False,
        note=f"pass: inside [θ_L, θ_H] = [{lo}, {hi}] deg (eq. 6); the document measured {pd_doc} deg",
        passed=lo <= e_pd <= hi,
    )
    amps = {
        ms: rad_to_deg(runs[f"southward_{ms}ms{k}"].metrics["limit_cycle_amp"]) for ms in SOUTHWARD_PERIODS_MS
    }
    res = rad_to_deg(spec.sensors[0].resolution)
    for ms in SOUTHWARD_PERIODS_MS:
        ok = amps[ms] > 10 * res and (ms == 5 or amps[ms] > amps[{20: 5, 40: 20}[ms]])
        yield row(
            f"{prefix}.southward.amp_deg.{ms}ms",
            float("nan"),
            amps[ms],
            float("nan"),
            relative=False,
            note="sustained limit cycle (> 10 encoder counts) whose amplitude grows with the sampling "
            "period (§6, Fig. 8; no number printed)",
            passed=ok,
        )
    for d in DELTAS_DEG:
        doc_e, doc_c = _published_rdfc(d)
        r = runs[f"rdfc_{d}{k}"]
        e = rad_to_deg(r.log["output"][-1])
        yield row(
            f"{prefix}.rdfc.{d}.final_error_deg",
            doc_e,
            e,
            d,
            relative=False,
            note=f"pass: |e| <= δ = {d} deg (Theorem 2)",
            passed=abs(e) <= d,
        )
        yield row(
            f"{prefix}.rdfc.{d}.cycles",
            doc_c,
            cycles(r),
            float("nan"),
            relative=False,
            note="half the error sign changes before settling; see report text for why it differs",
            passed=cycles(r) <= cycles(runs[f"rdfc_0.02{k}"]),
        )


def figures(runs: dict[str, EpisodeResult], out: Path) -> list[str]:
    """Kang Fig. 7-10 analogues: rotor angle (deg) vs time."""
    plt = pyplot()

    figs = [
        ("kang_fig7_pd.png", ["pd"], "PD control (Fig. 7)"),
        (
            "kang_fig8_southward.png",
            ["southward_5ms", "southward_20ms", "southward_40ms"],
            "Southward's compensator, 5/20/40 ms sampling (Fig. 8)",
        ),
        ("kang_fig9_rdfc_002.png", ["rdfc_0.02", "rdfc_0.02_symmetric"], "RDFC δ = 0.02 deg (Fig. 9)"),
        ("kang_fig10_rdfc_004.png", ["rdfc_0.04", "rdfc_0.04_symmetric"], "RDFC δ = 0.04 deg (Fig. 10)"),
    ]
    names = []
    for fname, keys, title in figs:
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        for k in keys:
            g = runs[k].log
            a1.plot(g["t"], rad_to_deg(g["output"]), label=k)
            a2.plot(g["t"], rad_to_deg(g["output"]), label=k)
        a1.set(ylabel="θ (deg)", title=title)
        a1.legend()
        a2.set(ylabel="θ (deg), zoom", xlabel="t (s)", ylim=(-0.06, 0.06))
        names.append(save_figure(fig, out, fname))
    return names


def findings(runs: dict[str, EpisodeResult], rows: list[dict]) -> str:
    """Where the simulation and Kang's experiments agree or differ (markdown), from the runs and rows."""
    ok = {r["id"]: r["pass"] for r in rows}
    spec = plant_spec("kang_robot")
    lo, hi = spec.document.theta_L_deg, spec.document.theta_H_deg
    pub = published_node("kang1998")
    pd_doc = pub.number("pd_final_error_deg")
    z_lo, z_hi = pub.interval("pd_zeta_printed")
    pd = rad_to_deg(runs["pd"].log["output"][-1])
    lc = {ms: rad_to_deg(runs[f"southward_{ms}ms"].metrics["limit_cycle_amp"]) for ms in SOUTHWARD_PERIODS_MS}
    grows = all(ok[f"kang.southward.amp_deg.{ms}ms"] for ms in SOUTHWARD_PERIODS_MS)
    sym = rad_to_deg(runs["rdfc_0.02_symmetric"].metrics["limit_cycle_amp"])
    lines = [
        "## Kang baselines: findings",
        "",
        f"- **PD** stops at {pd:.3f} deg, {'inside' if lo <= pd <= hi else 'OUTSIDE'} "
        f"[θ_L, θ_H] = [{lo}, {hi}] deg as eq. (6) requires; Kang measured {pd_doc} deg. "
        "The stopping point is where the decaying PD torque drops below the static level while the "
        "rotor sticks, which depends on the slip friction's "
        f"shape (Stribeck curve, LuGre dynamics) and on K_d (ζ printed in [{z_lo}, {z_hi}]).",
        f"- **Southward** keeps a limit cycle of {lc[5]:.4f} / {lc[20]:.4f} / {lc[40]:.4f} deg "
        "at 5 / 20 / 40 ms: "
        + (
            "sustained and growing with the sampling period, as §3.1 and §6 state."
            if grows
            else "NOT the sustained cycle growing with the sampling period that §3.1 and §6 describe."
        ),
    ]
    for d in DELTAS_DEG:
        doc_e, doc_c = _published_rdfc(d)
        e, c = rad_to_deg(runs[f"rdfc_{d}"].log["output"][-1]), cycles(runs[f"rdfc_{d}"])
        lines.append(
            f"- **RDFC δ = {d} deg** ends at e_ss = {e:.4f} deg (Kang: {doc_e}), "
            f"{'within' if abs(e) <= d else 'OUTSIDE'} ±δ, after {c:g} cycles (Kang: {doc_c:g})."
        )
    if any(cycles(runs[f"rdfc_{d}"]) != _published_rdfc(d)[1] for d in DELTAS_DEG):
        lines.append(
            "  The cycle counts differ from Kang's. Candidates, not yet separated: K_d (see PD), the "
            "friction (Kang's is position dependent, §6; here LuGre with constant levels) and the analog "
            "loop (ideal here)."
        )
    lines.append(
        f"- **Eq. (12b)**: with ERRATA 001's 'symmetric' third line the rotor keeps chattering across zero "
        f"({sym:.4f} deg), "
        + (
            "which contradicts Kang's convergence, so the printed line is followed."
            if ok["kang.rdfc.0.02.symmetric_12b.limit_cycle_amp_deg"]
            else "no more than with the printed line."
        )
    )
    lines += _model_comparison(runs)
    return "\n".join(lines) + "\n"


def _model_comparison(runs: dict[str, EpisodeResult]) -> list[str]:
    """The same baselines on LuGre and on the paper's own friction model, beside Kang's numbers."""
    pub = published_node("kang1998")

    def err(key: str) -> float:
        return rad_to_deg(runs[key].log["output"][-1])

    def amp(key: str) -> float:
        return rad_to_deg(runs[key].metrics["limit_cycle_amp"])

    lines = [
        "",
        "### Kang's rows on the paper's own friction model (`friction_model: kang`) and on LuGre",
        "",
        "| quantity | LuGre (v_s = 1 deg/s) | paper's model (stick band 0.01 deg/s) | Kang §6 |",
        "|---|---|---|---|",
        f"| PD resting error (deg) | {err('pd'):.3f} | {err('pd_kang'):.3f} | "
        f"{pub.number('pd_final_error_deg')} |",
    ]
    lines += [
        f"| Southward limit cycle at {ms} ms (deg) | {amp(f'southward_{ms}ms'):.4f} | "
        f"{amp(f'southward_{ms}ms_kang'):.4f} | sustained, grows with the period (Fig. 8) |"
        for ms in SOUTHWARD_PERIODS_MS
    ]
    for d in DELTAS_DEG:
        doc_e, doc_c = _published_rdfc(d)
        lugre, paper = runs[f"rdfc_{d}"], runs[f"rdfc_{d}_kang"]
        lines.append(
            f"| RDFC δ = {d} deg: e_ss (deg), cycles | {err(f'rdfc_{d}'):.4f}, {cycles(lugre):g} | "
            f"{err(f'rdfc_{d}_kang'):.4f}, {cycles(paper):g} | {doc_e}, {doc_c:g} |"
        )
    ratio = amp("southward_20ms_kang") / amp("southward_20ms")
    lines += [
        "",
        "With the paper's model the friction falls from T_s to T_0 as soon as the rotor moves, and "
        f"Southward's sampled compensator keeps a {ratio:.1f} times larger limit cycle at 20 ms than on the "
        "LuGre plant, "
        "whose friction falls over v_s = 1 deg/s: the discontinuity the paper's analysis (§3.1) rests on is "
        "what LuGre smooths. Neither model brings PD near Kang's 0.841 deg: the resting point is set by "
        "K_d (ERRATA 001) far more than by the friction structure.",
    ]
    for d in DELTAS_DEG:
        doc_c = _published_rdfc(d)[1]
        off = {
            m: abs(cycles(runs[f"rdfc_{d}{k}"]) - doc_c)
            for m, k in (("LuGre", ""), ("the paper's model", "_kang"))
        }
        closer = "both equally" if off["LuGre"] == off["the paper's model"] else min(off, key=off.get)
        lines.append(f"RDFC δ = {d} deg: closer to Kang's {doc_c:g} cycles: {closer}.")
    return lines


BASELINES = Section("kang_baselines", "kang1998", baseline_runs, baseline_rows, figures, findings)
