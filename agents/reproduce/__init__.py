"""Reproduction of the documents' numbers on the simulator: one module per document (iurian2005: the M220,
kang1998, wallenborg1987, janot2019: the EMPS on its measurements; friction_validation: the friction
structures' elements against Radau; friction_phenomena: Iurian et al. 2005 §1.3's phenomena by structure),
each contributing sections of rows {id, document, simulated, tolerance, pass, note}, figures and findings
computed from the results. `scripts/reproduce.py` walks SECTIONS in order. Published numbers live in
configs/published/<document>.yaml and the plant presets."""

from __future__ import annotations

from . import friction_phenomena, friction_validation, iurian2005, janot2019, kang1998, wallenborg1987
from .report import Section, SectionResult, markdown, run_section

__all__ = ["Section", "SectionResult", "all_rows", "markdown", "run_section", "section_names", "sections"]


def sections() -> list[Section]:
    """Every section, in report order."""
    return [
        iurian2005.PLANT,
        wallenborg1987.PLANT,
        kang1998.PLANT,
        friction_validation.SECTION,
        friction_phenomena.SECTION,
        kang1998.BASELINES,
        wallenborg1987.BASELINES,
        janot2019.IDIM,
        janot2019.SIMULATION,
    ]


def section_names() -> list[str]:
    return [s.name for s in sections()]


def all_rows(names: list[str] | None = None) -> list[dict]:
    """The rows of the named sections (default all), in report order."""
    return [r for s in sections() if names is None or s.name in names for r in run_section(s).rows]
