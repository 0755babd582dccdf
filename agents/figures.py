"""Writing a matplotlib figure as a result file: the one helper every report (leaderboard, sim2real,
training curves, identification, the reproduction report) saves its PNGs with."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from frictiongym.envs.records import atomic_write, pyplot

DPI = 110  # pixels per inch of every PNG the package writes


def smallest_text_px(fig: Any, dpi: int = DPI) -> float:
    """The height (px) of the smallest visible text of a figure as save_figure writes it at `dpi`: what a
    page that shows the PNG at its natural width shows (font size in points x dpi / 72)."""
    from matplotlib.text import Text  # start-up cost: imported where a figure is measured

    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    return min(sizes, default=float("nan")) * dpi / 72


def save_figure(fig: Any, out: Path, fname: str, dpi: int = DPI) -> str:
    """Write a figure as out/fname, PNG (atomically), close it, return its file name."""
    plt = pyplot()

    fig.tight_layout()
    atomic_write(out / fname, lambda p: fig.savefig(p, dpi=dpi, format="png"))
    plt.close(fig)
    return fname
