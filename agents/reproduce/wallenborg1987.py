"""Seed 002 (Wallenborg 1987), the flexible servo: G1/G2 of eq. (3.2)/(3.3) against the linearised
MuJoCo model and simulated sine runs; the state-feedback designs of Appendix B; the regulator's stability
limits (§6.1-6.2); the Nyquist crossing and describing-function limit cycle (§5.1); and the simulated
limit cycles with and without friction compensation (§4.3, §6.3; Fig. 4.2-4.4, 6.2, 6.7-6.9)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from frictiongym.agents.evaluation.evaluate import EpisodeResult, run_episode
from frictiongym.envs import metrics
from frictiongym.envs.plants import flexible_servo, plant_spec
from frictiongym.envs.plants.flexible_servo import tacho_gains
from frictiongym.envs.plants.sim import PlantSim, linearize
from frictiongym.envs.records import pyplot
from frictiongym.envs.suites import Episode
from frictiongym.envs.units import rad_to_deg

from ..classical.state_feedback import (
    StateFeedback,
    describing_function_cycle,
    regulator_stability_boundary,
    state_feedback_design,
)
from ..figures import save_figure
from .report import Section, published, row

FREQS_HZ = (0.1, 0.3, 1.0, 1.78, 3.0, 10.0)
DESIGNS = {  # id -> (w_cl, sensor, h)
    "cont_wcl12_y1": (12.0, "y1", 0.0),
    "cont_wcl8_y1": (8.0, "y1", 0.0),
    "cont_wcl12_y2": (12.0, "y2", 0.0),
    "digital_wcl12_y1": (12.0, "y1", 0.04),
}
CASES = {  # id -> (controller kwargs, scenario)
    "wcl12_y1": ({}, "flexible_speed_step_fast"),
    "wcl8_y1": ({"w_cl": 8.0}, "flexible_speed_step_fast"),
    "wcl12_y2": ({"sensor": "y2"}, "flexible_speed_step_fast"),
    "wcl12_y1_relay": ({"compensation": "relay"}, "flexible_speed_step_fast"),
    "wcl12_y1_highgain": ({"compensation": "highgain"}, "flexible_speed_step_fast"),
    "digital_wcl12_y1": ({}, "flexible_speed_step"),
    "digital_wcl12_y1_highgain": ({"compensation": "highgain"}, "flexible_speed_step"),
}


def plant_rows(_: None) -> Iterator[dict]:
    spec = plant_spec("flexible_servo")
    f = np.array(FREQS_HZ)
    G = np.array(flexible_servo.transfer(spec, 2j * np.pi * f)).T
    for label, resp in (("lin", frf_linearized(f)), ("sine", frf_sine(f))):
        for c, name in enumerate(("G1", "G2")):
            for i, fi in enumerate(f):
                yield row(
                    f"flexible.{name}.{fi:g}Hz.{label}.mag",
                    abs(G[i, c]),
                    abs(resp[i, c]),
                    0.01,
                    note="|G|, V/V",
                )
                yield row(
                    f"flexible.{name}.{fi:g}Hz.{label}.phase_deg",
                    0.0,
                    rad_to_deg(float(np.angle(resp[i, c] / G[i, c]))),
                    1.0,
                    relative=False,
                    note="phase error vs G(jω), deg",
                )


def plant_figures(_: None, out: Path) -> list[str]:
    """Bode plots: G1/G2 from the parameters (lines), linearised MuJoCo (dots), sine runs (o)."""
    plt = pyplot()

    f = np.logspace(-1, 1, 60)
    G = np.array(flexible_servo.transfer(plant_spec("flexible_servo"), 2j * np.pi * f)).T
    L = frf_linearized(f)
    fs = np.array(FREQS_HZ)
    S = frf_sine(fs)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    for c, name in enumerate(("G1 (u→y1)", "G2 (u→y2)")):
        a1.loglog(f, abs(G[:, c]), label=f"{name} eq. 3.2/3.3")
        a1.loglog(f, abs(L[:, c]), ":", color="k")
        a1.loglog(fs, abs(S[:, c]), "o")
        a2.semilogx(f, rad_to_deg(np.unwrap(np.angle(G[:, c]))))
        a2.semilogx(fs, rad_to_deg(np.unwrap(np.angle(S[:, c]))), "o")
    a1.set(
        ylabel="|G| (V/V)",
        title="Flexible servo: parameters (lines), linearised MuJoCo (dots), sine runs (o)",
    )
    a1.legend()
    a2.set(xlabel="f (Hz)", ylabel="phase (deg)")
    return [save_figure(fig, out, "flexible_bode.png", dpi=120)]


PLANT = Section("flexible", "wallenborg1987", lambda: None, plant_rows, plant_figures)


def baseline_runs() -> dict[str, EpisodeResult]:
    return {
        case: run_episode(StateFeedback(**kw), Episode(sc, 0, False), keep_log=True)
        for case, (kw, sc) in CASES.items()
    }


def window_cycle(r: EpisodeResult) -> dict[str, float]:
    """Limit cycle of y1 over t ∈ [6, 10] s, after the reference returned to 0."""
    g = r.log
    sel = g["t"] >= 6.0
    return metrics.limit_cycle(g["t"][sel], g["output"][sel], window=1.0, min_amp=1e-3)


def baseline_rows(runs: dict[str, EpisodeResult]) -> Iterator[dict]:
    pub = published("wallenborg1987")
    spec = plant_spec("flexible_servo")
    for key, (w, sensor, h) in DESIGNS.items():
        d = state_feedback_design(spec, w, sensor=sensor, h=h)
        ref = pub["gains"][key]
        got = np.concatenate([d.L.ravel(), d.K.ravel(), [d.lr]])
        want = np.array([*ref["L"], *ref["K"], ref["lr"]])
        err = float(np.max(np.abs(got / want - 1)))
        yield row(
            f"wallenborg.gains.{key}",
            0.0,
            err,
            0.01,
            relative=False,
            note="largest relative deviation of L, K, l_r from Appendix B (designed from §3.1 parameters)",
        )
    yield row(
        "wallenborg.regulator_stability_limit",
        pub["regulator_stability_limit_rad_s"],
        regulator_stability_boundary(spec, 8.0, 12.0),
        0.01,
        note="rad/s, eig(A - BL - KC), complete model",
    )
    yield row(
        "wallenborg.noncolocated_lower_limit",
        pub["noncolocated_lower_limit_rad_s"],
        regulator_stability_boundary(spec, 1.0, 12.0, sensor="y2"),
        0.05,
        note="rad/s; the document's 5.5 comes from the simplified model (§6.2)",
    )
    F = spec.joints[0].friction.levels()["static_pos"]
    df = describing_function_cycle(spec, 12.0, F)
    yield row(
        "wallenborg.nyquist_crossing",
        pub["nyquist_crossing"],
        df["G"],
        0.05,
        note=f"G(jω) at -180° (V per N·m), ω = {df['omega']:.2f} rad/s; eq. (5.3)",
    )
    yield row(
        "wallenborg.nyquist_crossing_rad_s", pub["nyquist_crossing_rad_s"], df["omega"], 0.02, note="rad/s"
    )
    yield row("wallenborg.df_amplitude", pub["df_amplitude_v"], df["amplitude_v"], 0.1, note="V, C = -4F·G/π")
    base = window_cycle(runs["wcl12_y1"])
    yield row(
        "wallenborg.limit_cycle.wcl12_y1.freq_hz",
        pub["limit_cycle_freq_hz"],
        base["limit_cycle_freq_hz"],
        0.1,
        note="y1, t in [6, 10] s, MuJoCo plant with LuGre friction, fast (1 ms) continuous design",
    )
    yield row(
        "wallenborg.limit_cycle.wcl12_y1.amp_v",
        pub["limit_cycle_amp_v"],
        base["limit_cycle_amp"],
        0.3,
        note="V; the document simulated 0.3 and measured 0.2 V (its friction value is uncertain, §7.2)",
    )
    for case in CASES:
        if case == "wcl12_y1":
            continue
        lc = window_cycle(runs[case])
        if case == "digital_wcl12_y1":
            # §4.3, Fig. 4.3: "approximately the same amplitude and frequency" as the continuous design
            ok = (
                abs(lc["limit_cycle_freq_hz"] / pub["limit_cycle_freq_hz"] - 1) <= 0.1
                and abs(lc["limit_cycle_amp"] / pub["limit_cycle_amp_v"] - 1) <= 0.3
            )
            note = "digital nominal design: the same limit cycle as the continuous one (§4.3, Fig. 4.3)"
        else:
            ok = lc["limit_cycle_amp"] <= base["limit_cycle_amp"] / 4
            note = "no sustained limit cycle, or amplitude reduced >= 4x vs wcl12_y1"
        for metric, key in (("amp_v", "limit_cycle_amp"), ("freq_hz", "limit_cycle_freq_hz")):
            # both rows of a case are judged by the case's criterion (frequency 0 below 1 mV amplitude)
            yield row(
                f"wallenborg.limit_cycle.{case}.{metric}",
                float("nan"),
                lc[key],
                float("nan"),
                relative=False,
                passed=ok,
                note=note,
            )


def figures(runs: dict[str, EpisodeResult], out: Path) -> list[str]:
    """Analogues of Wallenborg Fig. 4.2-4.4, 6.2, 6.7-6.9: y1 step responses of the cases."""
    plt = pyplot()

    figs = [
        ("wallenborg_fig4_2.png", ["wcl12_y1"], "Fig. 4.2: ω_cl = 12, y1 measured"),
        ("wallenborg_fig4_4.png", ["wcl8_y1"], "Fig. 4.4: ω_cl = 8 (reduced bandwidth)"),
        ("wallenborg_fig6_2.png", ["wcl12_y2"], "Fig. 6.2: ω_cl = 12, y2 measured (non-colocated)"),
        ("wallenborg_fig6_7.png", ["wcl12_y1", "wcl12_y1_highgain"], "Fig. 6.7: high gain with saturation"),
        ("wallenborg_fig6_8.png", ["wcl12_y1", "wcl12_y1_relay"], "Fig. 6.8: relay with dead zone"),
        (
            "wallenborg_fig6_9.png",
            ["digital_wcl12_y1", "digital_wcl12_y1_highgain"],
            "Fig. 6.9: digital (h = 40 ms), high gain with saturation",
        ),
    ]
    names = []
    for fname, keys, title in figs:
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for k in keys:
            g = runs[k].log
            ax.plot(g["t"], g["output"], label=f"y1, {k}")
        ax.plot(g["t"], g["reference"], "k:", label="y_r")
        ax.set(xlabel="t (s)", ylabel="V", title=title)
        ax.legend(fontsize=8)
        names.append(save_figure(fig, out, fname))
    return names


def findings(runs: dict[str, EpisodeResult], rows: list[dict]) -> str:
    """Where the simulated flexible servo and the thesis agree or differ (markdown), from runs and rows."""
    pub = published("wallenborg1987")
    by_id = {r["id"]: r for r in rows}
    gain_err = max(by_id[f"wallenborg.gains.{k}"]["simulated"] for k in DESIGNS)
    spec = plant_spec("flexible_servo")
    df = describing_function_cycle(spec, 12.0, spec.joints[0].friction.levels()["static_pos"])
    base, dig = window_cycle(runs["wcl12_y1"]), window_cycle(runs["digital_wcl12_y1"])
    hg = window_cycle(runs["wcl12_y1_highgain"])
    dig_ok = by_id["wallenborg.limit_cycle.digital_wcl12_y1.amp_v"]["pass"]
    f0, a0 = base["limit_cycle_freq_hz"], base["limit_cycle_amp"]
    digital = "limit-cycles like" if dig_ok else "does NOT limit-cycle like"
    return f"""## Wallenborg: findings

- The gains designed here from the §3.1 parameters with python-control match Appendix B within
  {100 * gain_err:.2g} % (largest relative deviation of L, K, l_r over the four designs).
- With ω_cl = 12 and the colocated sensor, the MuJoCo plant with LuGre friction limit-cycles at
  {f0:.2f} Hz with {a0:.3f} V amplitude (thesis: ≈ {pub["limit_cycle_freq_hz"]} Hz,
  {pub["limit_cycle_amp_v"]} V simulated with Coulomb friction, 0.2 V measured); the describing function
  of the same loop predicts {df["omega"]:.2f} rad/s and {df["amplitude_v"]:.2f} V (thesis:
  {pub["nyquist_crossing_rad_s"]} rad/s, {pub["df_amplitude_v"]} V). The amplitude is proportional to the
  friction level (§7.2), which randomised episodes vary.
- The digital design (h = 40 ms) {digital} the continuous one
  ({dig["limit_cycle_freq_hz"]:.2f} Hz, {dig["limit_cycle_amp"]:.3f} V); §4.3 and Fig. 4.3 say it does.
- Friction compensation follows the SIMNON code (CSFNL/DSFNL), not the text: it acts on the estimated output
  ŷ in volts with ε = 0.001 V (ERRATA 002), the observer is fed the linear part u0, and u0 is clipped.
  High gain with saturation reduces the cycle to {hg["limit_cycle_amp"]:.4f} V
  ({a0 / max(hg["limit_cycle_amp"], 1e-12):.0f}x smaller).
"""


BASELINES = Section("wallenborg", "wallenborg1987", baseline_runs, baseline_rows, figures, findings)


# ----------------------------------------------------------------------------------------------------
# the plant's simulated frequency responses (linearised MuJoCo model and sine inputs) for §3's Bode plot


def frf_linearized(freqs_hz: np.ndarray) -> np.ndarray:
    """(len(freqs), 2) complex u->y1, u->y2 responses of the linearised friction-free MuJoCo model."""
    sim = PlantSim("flexible_servo", friction_model="none")
    A, B = linearize(sim)
    C = np.zeros((2, A.shape[0]))
    C[0, sim.model.nv + sim.dofs[0]] = tacho_gains(sim.spec)[0]
    C[1, sim.model.nv + sim.dofs[1]] = tacho_gains(sim.spec)[1]
    return np.array([C @ np.linalg.solve(2j * np.pi * f * np.eye(len(A)) - A, B) for f in freqs_hz])


def frf_sine(
    freqs_hz: np.ndarray, amplitude_v: float = 0.1, settle_s: float = 80.0, periods: int = 4
) -> np.ndarray:
    """Same responses from simulated sine inputs (mujoco.rollout, command updated every physics step
    with the mid-step value, so the per-step hold adds no phase lag), fitted over whole periods."""
    sim = PlantSim("flexible_servo", friction_model="none")
    m, h = sim.model, sim.spec.timestep
    out = []
    state0 = np.zeros((1, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    mujoco.mj_resetData(m, sim.data)
    mujoco.mj_getState(m, sim.data, state0[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for f in freqs_hz:
        w = 2 * np.pi * f
        n_fit = round(periods / f / h)
        n = round(settle_s / h) + n_fit
        t_mid = (np.arange(n) + 0.5) * h
        ctrl = np.zeros((1, n, m.nu))
        ctrl[0, :, sim.idx.drive_ctrl] = amplitude_v * np.sin(w * t_mid)
        state, _ = rollout.rollout(m, sim.data, state0, ctrl)
        qvel0 = 1 + m.nq  # FULLPHYSICS: time, qpos, qvel, ...
        t_end = (np.arange(n) + 1) * h
        basis = np.stack([np.sin(w * t_end[-n_fit:]), np.cos(w * t_end[-n_fit:]), np.ones(n_fit)], axis=1)
        resp = []
        for dof, gain in ((sim.dofs[0], tacho_gains(sim.spec)[0]), (sim.dofs[1], tacho_gains(sim.spec)[1])):
            y = gain * state[0, -n_fit:, qvel0 + dof]
            a, b, _ = np.linalg.lstsq(basis, y, rcond=None)[0]
            resp.append((a + 1j * b) / amplitude_v)  # y = Im{G e^{jwt}}·A = A(|G|cos φ sin + |G| sin φ cos)
        out.append(resp)
    return np.array(out)
