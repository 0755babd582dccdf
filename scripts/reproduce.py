"""Reproduce the documents' numbers on the simulator: writes DIR/report.json, DIR/report.md and figures.

python scripts/reproduce.py --out out/reproduce
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from frictiongym.agents import report as baselines
from frictiongym.envs import checks, report
from frictiongym.envs.identification import m220_step_counts
from frictiongym.envs.plants import plant_config, plant_spec


def figures(out: Path) -> list[str]:
    """PNG figures: M220 step vs measured points, flexible Bode plots, Kang P-ramp bounds."""
    names = []
    idf = plant_config("m220")["identified"]
    t = np.linspace(0.05, 5.0, 100)
    y = m220_step_counts(idf["gain_counts_per_v_s2"], tuple(t), idf["step_input_v"])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, y, label="simulated 0.25 V step (drive encoder)")
    ax.plot(idf["step_points_t_s"], idf["step_points_counts"], "o", label="measured points, seed 000 §2.2")
    a, k, v = idf["document_a_per_s"], idf["document_k_counts_per_v_s2"], idf["step_input_v"]
    ax.plot(t, k * v / a * t - k * v / a**2 * (1 - np.exp(-a * t)), "--", label="document model k/(s(s+a))")
    ax.set(xlabel="t (s)", ylabel="counts", title="M220 open-loop step")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "m220_step.png", dpi=120)
    names.append("m220_step.png")

    f = np.logspace(-1, 1, 60)
    G = np.array(checks.flexible_transfer(plant_spec("flexible_servo"), 2j * np.pi * f)).T
    L = checks.flexible_frf_linearized(f)
    fs = np.array(report.FLEX_FREQS_HZ)
    S = checks.flexible_frf_sine(fs)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    for c, name in enumerate(("G1 (u→y1)", "G2 (u→y2)")):
        a1.loglog(f, abs(G[:, c]), label=f"{name} eq. 3.2/3.3")
        a1.loglog(f, abs(L[:, c]), ":", color="k")
        a1.loglog(fs, abs(S[:, c]), "o")
        a2.semilogx(f, np.degrees(np.unwrap(np.angle(G[:, c]))))
        a2.semilogx(fs, np.degrees(np.unwrap(np.angle(S[:, c]))), "o")
    a1.set(
        ylabel="|G| (V/V)",
        title="Flexible servo: parameters (lines), linearised MuJoCo (dots), sine runs (o)",
    )
    a1.legend()
    a2.set(xlabel="f (Hz)", ylabel="phase (deg)")
    fig.tight_layout()
    fig.savefig(out / "flexible_bode.png", dpi=120)
    names.append("flexible_bode.png")
    plt.close("all")
    return names


def markdown(rows: list[dict], figs: list[str]) -> str:
    npass = sum(r["pass"] for r in rows)
    lines = [
        "# frictiongym reproduction report",
        "",
        f"{npass} of {len(rows)} rows pass. `document` is the document's value, or for friction rows "
        "the stiff-ODE (Radau) / analytic value of the same LuGre equations.",
        "",
        "| id | document | simulated | tolerance | pass | note |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['id']} | {r['document']:.6g} | {r['simulated']:.6g} | {r['tolerance']} | "
        f"{'yes' if r['pass'] else '**NO**'} | {r['note']} |"
        for r in rows
    ]
    lines += ["", *[f"![{f}]({f})" for f in figs]]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/reproduce"), help="output folder")
    ap.add_argument(
        "--sections",
        nargs="*",
        choices=[*report.SECTIONS, "kang_baselines", "wallenborg"],
        help="subset of sections",
    )
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    sections = args.sections or [*report.SECTIONS, "kang_baselines", "wallenborg"]
    for s in tqdm(sections, desc="reproducing", unit="section"):
        if s in report.SECTIONS:
            rows += report.all_rows([s])
    figs = figures(args.out) if set(sections) & set(report.SECTIONS) else []
    if "kang_baselines" in sections:
        runs = baselines.kang_baseline_runs()
        rows += list(baselines.kang_rows(runs))
        figs += baselines.kang_figures(runs, args.out)
        findings = baselines.kang_findings(runs)
    else:
        findings = ""
    if "wallenborg" in sections:
        wruns = baselines.wallenborg_runs()
        rows += list(baselines.wallenborg_rows(wruns))
        figs += baselines.wallenborg_figures(wruns, args.out)
        findings += "\n" + baselines.wallenborg_findings(wruns)
    (args.out / "report.json").write_text(json.dumps(rows, indent=1))
    (args.out / "report.md").write_text(markdown(rows, figs) + "\n" + findings)
    failed = [r["id"] for r in rows if not r["pass"]]
    print(f"{len(rows) - len(failed)}/{len(rows)} rows pass; report in {args.out / 'report.md'}")
    for r in failed:
        print(f"FAIL {r}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
