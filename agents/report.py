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
        fig.tight_layout()
        fig.savefig(out / fname, dpi=110)
        plt.close(fig)
        names.append(fname)
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
