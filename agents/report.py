"""Reproduction rows for the classical baselines (extends envs/report.py) and the documents' figures."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from frictiongym.envs.plants import plant_spec
from frictiongym.envs.report import row
from frictiongym.envs.suites import Episode

from .classical import PD, RDFC, Southward
from .evaluate import EpisodeResult, run_episode

KANG = Episode("kang_regulation", 0, False)  # θ(0) = 20 deg, set-point 0, 20 ms, nominal plant


def _save(fig, out: Path, fname: str) -> str:
    """Write a figure as PNG, close it, return its file name."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(out / fname, dpi=110)
    plt.close(fig)
    return fname


def _deg(x: float) -> float:
    return math.degrees(x)


def cycles(result: EpisodeResult) -> float:
    """Oscillation cycles before the rotor settles: half the number of sign changes of the error."""
    e = result.log["output"] - result.log["reference"]
    s = np.sign(e[e != 0])
    return 0.5 * float(np.count_nonzero(s[1:] != s[:-1]))


def kang_baseline_runs() -> dict[str, EpisodeResult]:
    runs = {"pd": run_episode(PD(), KANG, keep_log=True)}
    for ms in (5, 20, 40):
        runs[f"southward_{ms}ms"] = run_episode(Southward(), KANG, keep_log=True, control_period_s=ms / 1000)
    for d in (0.02, 0.04):
        runs[f"rdfc_{d}"] = run_episode(RDFC(d), KANG, keep_log=True)
        runs[f"rdfc_{d}_symmetric"] = run_episode(RDFC(d, "symmetric"), KANG, keep_log=True)
    return runs


def kang_rows(runs: dict[str, EpisodeResult]) -> Iterator[dict]:
    spec = plant_spec("kang_robot")
    lo, hi = spec.info["theta_L_deg"], spec.info["theta_H_deg"]
    e_pd = _deg(runs["pd"].log["output"][-1])
    yield row(
        "kang.pd.final_error_deg",
        0.841,
        e_pd,
        hi - lo,
        relative=False,
        note=f"pass: inside [θ_L, θ_H] = [{lo}, {hi}] deg (eq. 6); the document measured 0.841 deg",
        passed=lo <= e_pd <= hi,
    )
    amps = {ms: _deg(runs[f"southward_{ms}ms"].metrics["limit_cycle_amp"]) for ms in (5, 20, 40)}
    res = math.degrees(spec.sensors[0].resolution)
    for ms in (5, 20, 40):
        ok = amps[ms] > 10 * res and (ms == 5 or amps[ms] > amps[{20: 5, 40: 20}[ms]])
        yield row(
            f"kang.southward.amp_deg.{ms}ms",
            float("nan"),
            amps[ms],
            float("nan"),
            relative=False,
            note="sustained limit cycle (> 10 encoder counts) whose amplitude grows with the sampling "
            "period (§6, Fig. 8; no number printed)",
            passed=ok,
        )
    for d, doc_e, doc_c in ((0.02, 0.007, 6), (0.04, 0.023, 2)):
        r = runs[f"rdfc_{d}"]
        e = _deg(r.log["output"][-1])
        yield row(
            f"kang.rdfc.{d}.final_error_deg",
            doc_e,
            e,
            d,
            relative=False,
            note=f"pass: |e| <= δ = {d} deg (Theorem 2)",
            passed=abs(e) <= d,
        )
        yield row(
            f"kang.rdfc.{d}.cycles",
            doc_c,
            cycles(r),
            float("nan"),
            relative=False,
            note="half the error sign changes before settling; see report text for why it differs",
            passed=cycles(r) <= cycles(runs["rdfc_0.02"]),
        )
        s = runs[f"rdfc_{d}_symmetric"]
        yield row(
            f"kang.rdfc.{d}.symmetric_12b.limit_cycle_amp_deg",
            float("nan"),
            _deg(s.metrics["limit_cycle_amp"]),
            float("nan"),
            relative=False,
            note="ERRATA 001 'symmetric' reading of (12b): sustained chatter (> 10 counts) shows why the "
            "printed reading is followed",
            passed=_deg(s.metrics["limit_cycle_amp"]) > 10 * res,
        )


def kang_figures(runs: dict[str, EpisodeResult], out: Path) -> list[str]:
    """Kang Fig. 7-10 analogues: rotor angle (deg) vs time."""
    import matplotlib.pyplot as plt

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
            a1.plot(g["t"], np.degrees(g["output"]), label=k)
            a2.plot(g["t"], np.degrees(g["output"]), label=k)
        a1.set(ylabel="θ (deg)", title=title)
        a1.legend()
        a2.set(ylabel="θ (deg), zoom", xlabel="t (s)", ylim=(-0.06, 0.06))
        names.append(_save(fig, out, fname))
    return names


def kang_findings(runs: dict[str, EpisodeResult]) -> str:
    """Where the simulation and Kang's experiments differ, and what we know about why (markdown)."""
    pd = _deg(runs["pd"].log["output"][-1])
    lc = {ms: _deg(runs[f"southward_{ms}ms"].metrics["limit_cycle_amp"]) for ms in (5, 20, 40)}
    e02, e04 = (_deg(runs[f"rdfc_{d}"].log["output"][-1]) for d in (0.02, 0.04))
    c02, c04 = cycles(runs["rdfc_0.02"]), cycles(runs["rdfc_0.04"])
    sym = _deg(runs["rdfc_0.02_symmetric"].metrics["limit_cycle_amp"])
    return f"""## Kang baselines: findings

- **PD** stops at {pd:.3f} deg, inside [θ_L, θ_H] as eq. (6) requires; Kang measured 0.841 deg. The stopping
  point is where the decaying PD torque drops below the static level while the rotor sticks, which depends
  on the slip friction's shape (Stribeck curve, LuGre dynamics) and on K_d; K_d here gives ζ = 0.83 with
  viscous friction (the printed ζ = 0.79-0.87); the printed K_d/K_p ratio would give ζ ≈ 0.89 (ERRATA 001).
- **Southward** at 20 ms keeps a sustained limit cycle ({lc[20]:.4f} deg), growing with the sampling period
  ({lc[5]:.4f} deg at 5 ms, {lc[40]:.4f} deg at 40 ms), as §3.1 and §6 state. The amplitude is of the order of
  one hold period's travel under the net torque: (T̃_s - T_C)·T²/(2J) ≈ 0.007 deg at 20 ms.
- **RDFC** converges into the dead band: e_ss = {e02:.4f} deg for δ = 0.02 deg (Kang: 0.007) and {e04:.4f} deg
  for δ = 0.04 deg (Kang: 0.023), both within ±δ. It takes {c02:g} and {c04:g} cycles, where Kang saw 6 and 2.
  Candidates, not yet separated: K_d (see PD), the friction (Kang's is position dependent, §6; here LuGre
  with constant levels) and the analog loop (ideal here). The number of cycles is reported, not fitted.
- **Eq. (12b)**: the printed third line (θ̃_L ≤ θ ≤ δ_L) is followed. ERRATA 001's "symmetric" reading
  (θ̃_L ≤ θ < 0) makes the rotor bounce across zero every sample with full ±T̃_s pushes (chatter amplitude
  {sym:.4f} deg), which contradicts Kang's convergence; the printed line leaves θ ∈ (δ_L, 0) with ω < 0 to
  the negligible K_p θ term, so friction stops the rotor.
"""


# --------------------------------------------------------------------------------------------------------
# Wallenborg (seed 002)

WALLENBORG_DESIGNS = {  # id -> (w_cl, sensor, h)
    "cont_wcl12_y1": (12.0, "y1", 0.0),
    "cont_wcl8_y1": (8.0, "y1", 0.0),
    "cont_wcl12_y2": (12.0, "y2", 0.0),
    "digital_wcl12_y1": (12.0, "y1", 0.04),
}
WALLENBORG_CASES = {  # id -> (controller kwargs, scenario)
    "wcl12_y1": ({}, "flexible_speed_step_fast"),
    "wcl8_y1": ({"w_cl": 8.0}, "flexible_speed_step_fast"),
    "wcl12_y2": ({"sensor": "y2"}, "flexible_speed_step_fast"),
    "wcl12_y1_relay": ({"compensation": "relay"}, "flexible_speed_step_fast"),
    "wcl12_y1_highgain": ({"compensation": "highgain"}, "flexible_speed_step_fast"),
    "digital_wcl12_y1": ({}, "flexible_speed_step"),
    "digital_wcl12_y1_highgain": ({"compensation": "highgain"}, "flexible_speed_step"),
}


def wallenborg_published() -> dict:
    from frictiongym.envs.config import configs_dir, load_yaml

    return load_yaml(configs_dir() / "published" / "wallenborg.yaml")


def wallenborg_runs() -> dict[str, EpisodeResult]:
    from .wallenborg import StateFeedback

    return {
        case: run_episode(StateFeedback(**kw), Episode(sc, 0, False), keep_log=True)
        for case, (kw, sc) in WALLENBORG_CASES.items()
    }


def window_cycle(r: EpisodeResult) -> dict[str, float]:
    """Limit cycle of y1 over t ∈ [6, 10] s (the issue's window), after the reference returned to 0."""
    from frictiongym.envs import metrics

    g = r.log
    sel = g["t"] >= 6.0
    return metrics.limit_cycle(g["t"][sel], g["output"][sel], window=1.0, min_amp=1e-3)


def wallenborg_rows(runs: dict[str, EpisodeResult]) -> Iterator[dict]:
    from .design import describing_function_cycle, regulator_stability_boundary, state_feedback_design

    pub = wallenborg_published()
    spec = plant_spec("flexible_servo")
    for key, (w, sensor, h) in WALLENBORG_DESIGNS.items():
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
    for case in WALLENBORG_CASES:
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


def wallenborg_figures(runs: dict[str, EpisodeResult], out: Path) -> list[str]:
    """Analogues of Wallenborg Fig. 4.2-4.4, 6.2, 6.7-6.9: y1 step responses of the cases."""
    import matplotlib.pyplot as plt

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
        names.append(_save(fig, out, fname))
    return names


def wallenborg_findings(runs: dict[str, EpisodeResult]) -> str:
    """Where the simulated flexible servo and the thesis differ, and the choices made (markdown)."""
    base, dig = window_cycle(runs["wcl12_y1"]), window_cycle(runs["digital_wcl12_y1"])
    hg = window_cycle(runs["wcl12_y1_highgain"])
    f0, a0 = base["limit_cycle_freq_hz"], base["limit_cycle_amp"]
    f1, a1 = dig["limit_cycle_freq_hz"], dig["limit_cycle_amp"]
    return f"""## Wallenborg: findings

- The gains designed here from the §3.1 parameters with python-control match Appendix B within 0.05 %.
- With ω_cl = 12 and the colocated sensor, the MuJoCo plant with LuGre friction limit-cycles at {f0:.2f} Hz
  with {a0:.3f} V amplitude (thesis: ≈ 2.5 Hz, 0.3 V simulated with Coulomb friction, 0.2 V measured); the
  describing function of the same loop predicts 15.85 rad/s and 0.32 V. The amplitude is proportional to
  the friction level (§7.2), which randomised episodes vary by ±30 %.
- The digital design (h = 40 ms) limit-cycles like the continuous one ({f1:.2f} Hz, {a1:.3f} V), as §4.3 and
  Fig. 4.3 state; the issue listed this case among those expected to be free of limit cycles, which the
  thesis does not say.
- Friction compensation follows the SIMNON code (CSFNL/DSFNL), not the text: it acts on the estimated output
  ŷ in volts with ε = 0.001 V (ERRATA 002), the observer is fed the linear part u0, and u0 is clipped at
  ±8 V. High gain with saturation reduces the cycle to {hg["limit_cycle_amp"]:.4f} V.
"""
