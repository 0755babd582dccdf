"""Writing a matplotlib figure as a result file: the one helper every report (leaderboard, sim2real,
training curves, identification, the reproduction report) saves its PNGs with."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from frictiongym.envs.records import atomic_write, pyplot


def save_figure(fig: Any, out: Path, fname: str, dpi: int = 110) -> str:
    """Write a figure as out/fname, PNG (atomically), close it, return its file name."""
    plt = pyplot()

    fig.tight_layout()
    atomic_write(out / fname, lambda p: fig.savefig(p, dpi=dpi, format="png"))
    plt.close(fig)
    return fname
