"""The reproduction report's building blocks: a row {id, document, simulated, tolerance, pass, note}, the
published numbers (configs/published/<document>.yaml), a Section (run once, then rows, figures and
findings), running one, saving its figures and the markdown report."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.envs.config import Node, configs_dir, load_yaml


def row(
    id_: str,
    document: float,
    simulated: float,
    tolerance: float,
    relative: bool = True,
    note: str = "",
    passed: bool | None = None,
) -> dict:
    """One report row; tolerance is relative (fraction) unless relative=False (absolute). `passed`
    overrides the distance test for rows whose criterion is stated in the note (nan: no printed number)."""
    if passed is None:
        err = abs(simulated - document) / abs(document) if relative else abs(simulated - document)
        passed = bool(np.isfinite(simulated) and err <= tolerance)
    return {
        "id": id_,
        "document": float(document),
        "simulated": float(simulated),
        "tolerance": f"{tolerance:g}{' rel' if relative else ' abs'}"
        if np.isfinite(tolerance)
        else "see note",
        "pass": bool(passed),
        "note": note,
    }


@cache
def published(document: str) -> dict[str, Any]:
    """configs/published/<document>.yaml as a plain mapping."""
    return load_yaml(configs_dir() / "published" / f"{document}.yaml")


def published_node(document: str) -> Node:
    """The same, as a checked view (missing keys name the file)."""
    return Node(published(document), f"published/{document}.yaml")


@dataclass(frozen=True)
class Section:
    """A part of a document's reproduction: run() once, then rows, figures and findings from its result."""

    name: str
    document: str
    run: Callable[[], Any]
    rows: Callable[[Any], Iterator[dict]]
    figures: Callable[[Any, Path], list[str]] | None = None
    findings: Callable[[Any, list[dict]], str] | None = None


@dataclass
class SectionResult:
    section: Section
    rows: list[dict]
    figures: list[str]
    findings: str


def run_section(section: Section, out: Path | None = None) -> SectionResult:
    """Run one section; figures are written only with out."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # scipy's numerical Jacobian on stiff LuGre
        data = section.run()
        rows = list(section.rows(data))
    figs = section.figures(data, out) if (out is not None and section.figures) else []
    text = section.findings(data, rows) if section.findings else ""
    return SectionResult(section, rows, figs, text)


def markdown(results: list[SectionResult]) -> str:
    rows = [r for s in results for r in s.rows]
    figs = [f for s in results for f in s.figures]
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
    lines += ["", *[f"![{f}]({f})" for f in figs], ""]
    lines += [s.findings for s in results if s.findings]
    return "\n".join(lines) + "\n"
