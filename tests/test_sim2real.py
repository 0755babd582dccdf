"""The sim-to-real study (agents/sim2real/, scripts/sim2real.py): shifted plants one axis at a time, joint
in- and out-of-distribution sets, friction structures, model error, its report and resume."""

import csv

import pytest

from frictiongym.agents import sim2real
from frictiongym.scripts.sim2real import main


@pytest.mark.slow
def test_sim2real_on_a_tiny_grid(tmp_path):
    """scripts/sim2real.py: one-axis shifts (inadmissible pins left out), joint in/out-of-distribution sets,
    the CSV, the plot and the summary; a rerun resumes from episodes.csv."""
    args = [
        "--scenario",
        "kang_regulation",
        "--models",
        "--controllers",
        "PD",
        "--seeds",
        "1",
        "--points",
        "2",
    ]
    args += ["--joint", "1", "--model-error", "1", "--workers", "1", "--out", str(tmp_path)]
    assert main(args) == 0
    rows = list(csv.DictReader((tmp_path / "sim2real.csv").read_text().splitlines()))
    axes = {r["axis"] for r in rows}
    assert {"friction_scale", "delay_s", "joint_in_distribution", "joint_out_of_distribution"} <= axes
    assert {r["controller"] for r in rows} == {"Zero", "PD"}
    # inertia x0.5 with Kang's σ0 breaks the LuGre numerics check (h·sqrt(σ0/J) > 0.2): left out
    assert sorted(
        float(r["shift"]) for r in rows if r["axis"] == "inertia_scale" and r["controller"] == "PD"
    ) == [1.5]
    pd = {(r["axis"], r["shift"]): float(r["mean"]) for r in rows if r["controller"] == "PD"}
    # more friction, larger final error of PD (its stick band [θ_L, θ_H] widens, Kang 1998 eq. 6)
    assert pd[("friction_scale", "1.5")] > pd[("friction_scale", "0.5")]
    # the structural axis: every structure on the same episodes; Coulomb + viscous (static level F_c < F_s)
    # narrows PD's stick band
    assert {s for a, s in pd if a == "friction_model"} == set(sim2real.STRUCTURES)
    assert pd[("friction_model", "coulomb")] < pd[("friction_model", "lugre")]
    assert (tmp_path / "sim2real.png").stat().st_size > 0
    md = (tmp_path / "sim2real.md").read_text()
    assert "Where each controller keeps its lead" in md and "performance lost to model error" in md
    assert "## Friction structures (designed and trained on lugre)" in md
    assert (tmp_path / "sim2real_structures.png").stat().st_size > 0
    assert "1 randomised true plants" in md
    designs = [r["design"] for r in csv.DictReader((tmp_path / "model_error.csv").read_text().splitlines())]
    assert sorted(designs) == ["identified", "nominal", "true"]  # PD, on one true plant
    n = len((tmp_path / "episodes.csv").read_text().splitlines())
    episodes, _ = sim2real.plan("kang_regulation", 1, 2, 1)
    assert n == 1 + 2 * len(episodes)
    assert main(args) == 0 and len((tmp_path / "episodes.csv").read_text().splitlines()) == n


def test_a_structure_the_scenario_cannot_be_built_with_is_left_out_and_reported():
    """Drifting friction levels drift through bristle elements; Coulomb + viscous has none, so a drift
    scenario's structural axis runs without it and sim2real.md says why (the study used to stop there)."""
    from frictiongym.agents.sim2real import report
    from frictiongym.agents.sim2real.study import runnable_structures

    ok, why = runnable_structures("kang_drift", sim2real.STRUCTURES)
    assert ok == ("lugre", "dahl", "maxwell_slip", "kang") and set(why) == {"coulomb"}
    assert "friction_drift" in why["coulomb"]
    assert runnable_structures("kang_random", sim2real.STRUCTURES) == (sim2real.STRUCTURES, {})
    study = report.Study("kang_drift", "iae", "lugre", [], [], 1, 1, {}, [], why)
    assert f"Structure coulomb left out: {why['coulomb']}." in report.markdown(study)


def test_the_best_controller_of_a_shift_is_never_a_reference_row():
    """Ideal and Oracle are limits, not entries: the per-axis leader is the best controller beside them, as
    in the structural section (on the M220 the friction-free Ideal row is lowest at every shift)."""
    from frictiongym.agents.sim2real.report import findings

    def row(c, shift, mean):
        return {"axis": "friction_scale", "controller": c, "shift": shift, "mean": mean}

    table = [
        row("Ideal", 1.0, 0.019),
        row("Oracle", 1.0, 0.020),
        row("PID", 1.0, 0.042),
        row("LuGreObserver", 1.0, 0.026),
    ]
    (line,) = findings(table, ["Ideal", "Oracle", "PID", "LuGreObserver"])
    assert "best by mean (the reference rows Ideal, Oracle aside) 1: LuGreObserver." in line
