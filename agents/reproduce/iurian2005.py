"""Seed 000 part 2 (Iurian et al. 2005), the ECP M220: reflected inertia (eq. 22) in four configurations,
the §2.2 open-loop step through its two measured points, the two-point identification on simulated
data, and the plant-gain fit."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from frictiongym.agents.lab.identification import two_point_step_id
from frictiongym.envs.plants import m220, plant_spec

from . import Section, row, save_figure

CONFIGS = {
    "default": {},
    "npd72_npl18_4wl": {"configuration": {"n_pd": 72, "n_pl": 18, "brass_weights_load": 4}},
    "npd18_npl72_2wd_backlash": {
        "configuration": {"n_pd": 18, "n_pl": 72, "brass_weights_drive": 2, "backlash_device": True}
    },
    "npd36_npl36_4wd_4wl": {
        "configuration": {"n_pd": 36, "n_pl": 36, "brass_weights_drive": 4, "brass_weights_load": 4}
    },
}


def rows(_: None) -> Iterator[dict]:
    for name, ov in CONFIGS.items():
        yield row(
            f"m220.reflected_inertia.{name}",
            m220.eq22_of(ov),
            m220.reflected_inertia_sim(ov),
            0.005,
            note="kg·m², eq. (22)",
        )
    doc = plant_spec("m220").document
    t, y = doc.step_points_t_s, doc.step_points_counts
    sim = m220.step_counts(doc.gain_counts_per_v_s2, t, doc.step_input_v)
    for k in range(2):
        yield row(f"m220.step_point.{k + 1}", y[k], sim[k], 0.02, note=f"counts at t = {t[k]} s, §2.2")
    ident = two_point_step_id(t, tuple(sim), doc.step_input_v)
    yield row("m220.step_id.a", doc.document_a_per_s, ident["a"], 0.05, note="1/s, two-point method on sim")
    yield row("m220.step_id.k", doc.document_k_counts_per_v_s2, ident["k"], 0.05, note="counts/(V·s²)")
    yield row(
        "m220.gain_fit.reproducible",
        doc.gain_counts_per_v_s2,
        m220.fit_gain(t, y, doc.step_input_v),
        1e-3,
        note="config value vs a fresh fit",
    )


def figures(_: None, out: Path) -> list[str]:
    """The simulated 0.25 V step against the measured points and the document's model k/(s(s+a))."""
    import matplotlib.pyplot as plt

    doc = plant_spec("m220").document
    t = np.linspace(0.05, 5.0, 100)
    y = m220.step_counts(doc.gain_counts_per_v_s2, tuple(t), doc.step_input_v)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, y, label="simulated 0.25 V step (drive encoder)")
    ax.plot(doc.step_points_t_s, doc.step_points_counts, "o", label="measured points, seed 000 §2.2")
    a, k, v = doc.document_a_per_s, doc.document_k_counts_per_v_s2, doc.step_input_v
    ax.plot(t, k * v / a * t - k * v / a**2 * (1 - np.exp(-a * t)), "--", label="document model k/(s(s+a))")
    ax.set(xlabel="t (s)", ylabel="counts", title="M220 open-loop step")
    ax.legend()
    return [save_figure(fig, out, "m220_step.png")]


PLANT = Section("m220", "iurian2005", lambda: None, rows, figures)
