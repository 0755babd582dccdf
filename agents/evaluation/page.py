"""The leaderboard as one self-contained web page (index.html): the suite's question per plant, the
per-plant aggregates, the verdicts on the learned and plug-in entries and one table per scenario, each
sortable by a click on its header, reference rows marked, the figures embedded (PNG data URIs) and the
run's provenance. No network, no external file: the page opens from a laptop, a CI artefact or a mail.
Rendering only, like report.py: the leaderboard computes, renders, then writes."""

from __future__ import annotations

import base64
import html
import io
import math
from typing import TYPE_CHECKING

from frictiongym.agents.evaluation.report import (
    ANSWER_HEAD,
    G_MEANING,
    RULE,
    answer_rows,
    headline,
)

if TYPE_CHECKING:
    from frictiongym.agents.evaluation.board import Board

STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 1200px; padding: 0 1em;
       color: #222; }
h1 { font-size: 1.6em; } h2 { margin-top: 2em; border-bottom: 1px solid #ccc; } h3 { font-size: 1.1em; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 12.5px; }
th, td { border: 1px solid #ddd; padding: 3px 7px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
table.sortable th { cursor: pointer; background: #f3f3f3; user-select: none; }
table.sortable th[data-dir="asc"]::after { content: " \\25B2"; }
table.sortable th[data-dir="desc"]::after { content: " \\25BC"; }
tr.ref td { color: #777; font-style: italic; background: #fafafa; }
tr.baseline td:first-child { font-weight: bold; }
tr.chatters td:first-child { text-decoration: line-through; }
.provenance, .note { color: #555; font-size: 12.5px; }
small.about { color: #666; }
img { max-width: 100%; border: 1px solid #eee; margin: 0.5em 0; }
nav a { margin-right: 0.8em; }
#answer li { margin: 0.3em 0; }
.win { color: #137333; } .none { color: #5f6368; }
td.yes { background: #e6f4ea; color: #137333; font-weight: bold; } td.no { color: #a50e0e; }
"""

# Sort a table by the clicked column: numbers by the cell's data-v (NaN last), text otherwise.
SCRIPT = """
document.querySelectorAll("table.sortable th").forEach(th => th.addEventListener("click", () => {
  const i = th.cellIndex, body = th.closest("table").tBodies[0];
  const asc = th.dataset.dir !== "asc";
  th.closest("tr").querySelectorAll("th").forEach(h => delete h.dataset.dir);
  th.dataset.dir = asc ? "asc" : "desc";
  const key = td => td.dataset.v === undefined ? td.textContent.trim() : parseFloat(td.dataset.v);
  const rows = Array.from(body.rows);
  rows.sort((a, b) => {
    const x = key(a.cells[i]), y = key(b.cells[i]);
    if (typeof x === "number" && typeof y === "number") {
      if (isNaN(x) || isNaN(y)) return isNaN(x) - isNaN(y);
      return asc ? x - y : y - x;
    }
    return asc ? String(x).localeCompare(String(y)) : String(y).localeCompare(String(x));
  });
  rows.forEach(r => body.appendChild(r));
}));
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _num(x: float) -> str:
    return "nan" if not math.isfinite(x) else repr(float(x))


def _ci(ci: tuple[float, float, float]) -> str:
    """A cell of mean [interval], sorted by the mean."""
    m, lo, hi = ci
    text = "n/a" if not math.isfinite(m) else f"{m:.4g} <small>[{lo:.3g}, {hi:.3g}]</small>"
    return f'<td data-v="{_num(m)}">{text}</td>'


def _table(head: list[str], rows: list[str]) -> str:
    ths = "".join(f"<th>{_e(h)}</th>" for h in head)
    return (
        f'<table class="sortable"><thead><tr>{ths}</tr></thead><tbody>\n'
        + "\n".join(rows)
        + "\n</tbody></table>"
    )


def _aggregates(board: Board) -> list[str]:
    out = ["<h2 id='plants'>Per plant</h2>", "<p>IQM of g over the plant's scored scenarios with its 95 % "
           "stratified-bootstrap interval; each set of scenarios is ranked on its own.</p>"]  # fmt: skip
    for a in board.aggregate:
        rows = [
            f"<tr>{_named(board, r['controller'])}<td data-v='{i + 1}'>{i + 1}</td>{_ci(r['iqm'])}</tr>"
            for i, r in enumerate(a["rows"])
        ]
        rows += [
            f"<tr class='ref'><td>{_e(r['controller'])}</td><td data-v='nan'>reference</td>"
            f"{_ci(r['iqm'])}</tr>"
            for r in a["references"]
        ]
        out += [f"<h3>{_e(a['plant'])}: {_e(', '.join(a['scenarios']))}</h3>",
                _table(["controller", "rank", "IQM of g [95 % CI]"], rows)]  # fmt: skip
    return out


def _verdicts(board: Board) -> list[str]:
    if not board.verdicts:
        return []
    rows = []
    for j in board.verdicts:
        v = j["vs_baseline"]
        verdict = (
            "<td class='yes'>yes</td>"
            if j["beats_baseline"]
            else f"<td class='no'>no: {_e(j['why_not'])}</td>"
        )
        rows.append(
            f"<tr><td>{_e(_with_unit(board, j['scenario']))}</td>{_named(board, j['controller'])}"
            f"<td>{_e(j['baseline'])}</td>{_ci((v['diff'], v['diff_lo'], v['diff_hi']))}"
            f"<td data-v='{_num(j['roughness'])}'>{j['roughness']:.3g} ({j['point'].roughness:.3g})</td>"
            f"<td data-v='{_num(j['saturated'])}'>{j['saturated']:.3g} ({j['point'].saturated:.3g})</td>"
            f"{verdict}</tr>"
        )
    head = ["scenario (main metric, unit)", "entry", "baseline", "difference of the main metric (its unit)",
            "rms change per period (the point's)", "saturated share (the point's)", "beats it"]  # fmt: skip
    return [
        "<h2 id='verdicts'>Learned and plug-in entries against the best classical baseline</h2>",
        "<p>Beats it: the paired 95 % interval of the per-episode difference below 0, and a result: "
        f"{_e(RULE)}</p>",
        _table(head, rows),
    ]


def _scenarios(board: Board) -> list[str]:
    out = ["<h2 id='scenarios'>Scenarios</h2>"]
    for sc, rows in board.table.items():
        s = board.scenarios[sc]
        sec = list(s.secondary_metrics)
        body = []
        for r in rows:
            cls = "ref" if r["reference"] else "baseline" if r["controller"] == r["baseline"] else ""
            cls = "chatters" if r.get("chatters") else cls
            suffix = " (uncompensated)" if r["uncompensated"] else ""
            suffix += f" <small>(not a result: {_e(r['chatters'])})</small>" if r.get("chatters") else ""
            cells = [_ci(r["main"]), _ci(r["g"]), _ci(r["g_tracking"]), *(_ci(r["metrics"][m]) for m in sec)]
            body.append(f"<tr class='{cls}'>{_named(board, r['controller'], suffix)}{''.join(cells)}</tr>")
        head = [
            "controller",
            f"{s.main_metric} [{s.metric_unit(s.main_metric)}] (main)",
            "g [1: friction removed]",
            "g against the tracking limit [1]",
            *(f"{m} [{s.metric_unit(m)}]" for m in sec),
        ]
        out += [f"<h3 id='{_e(sc)}'>{_e(sc)}</h3>", f"<p class='note'>{_e(s.why)}</p>", _table(head, body)]
    return out


def page(
    board: Board,
    figures: dict[str, bytes],
    provenance: dict[str, str],
    text_px: dict[str, float],
) -> str:
    """index.html's text: the board's tables (sortable), the figures (name: PNG bytes) embedded at their
    natural width (each with data-text-px, its smallest text's height in px there: figures.smallest_text_px),
    the provenance (label: value) under the title."""
    prov = "; ".join(f"{_e(k)}: {_e(v)}" for k, v in provenance.items())
    parts = [
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>frictiongym leaderboard: {_e(board.suite)}</title><style>{STYLE}</style></head><body>",
        f"<h1>frictiongym leaderboard, suite <code>{_e(board.suite)}</code></h1>",
        f"<p class='provenance'>{prov}</p>",
        "<nav><a href='#answer'>the answer</a><a href='#question'>per scenario</a><a href='#plants'>per "
        "plant</a><a href='#verdicts'>verdicts</a><a href='#scenarios'>scenarios</a><a href='#figures'>"
        "figures</a></nav>",
        *_headline(board),
        f"<p class='note'>{_e(G_MEANING)} Reference rows (grey, never ranked): Zero, Ideal, TrackingLimit, "
        "Oracle, Optimum. Click a column's header to sort by it.</p>",
        "<h2 id='question'>The question per plant</h2>",
    ]
    for plant, rows in answer_rows(board).items():
        body = []
        for row in rows:
            cells = [
                f"<td>{_e(_with_unit(board, row['name']))}</td>",
                *(_answer_cell(c) for c in row["cells"]),
            ]
            body.append(f"<tr>{''.join(cells)}</tr>")
        parts += [f"<h3>{_e(plant)}</h3>", _table(ANSWER_HEAD, body)]
    parts += _aggregates(board) + _verdicts(board) + _scenarios(board)
    parts.append("<h2 id='figures'>Figures</h2>")
    for name, png in figures.items():
        data = base64.b64encode(compact_png(png)).decode("ascii")
        px = text_px[name]
        parts.append(
            f"<h3>{_e(name)}</h3><img alt='{_e(name)}' data-text-px='{_num(px)}' "
            f"src='data:image/png;base64,{data}'>"
        )
    parts.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(parts) + "\n"


def _named(board: Board, name: str, suffix: str = "") -> str:
    """A row's controller cell: its id (escaped), then what it is where the id alone says little (a saved
    model: design, training scenario, seed)."""
    about = board.about.get(name)
    small = f"<br><small class='about'>{_e(about)}</small>" if about else ""
    return f"<td>{_e(name)}{suffix}{small}</td>"


def _with_unit(board: Board, scenario: str) -> str:
    """'kang_ramp (iae, rad·s)': a scenario with its main metric and that metric's unit."""
    s = board.scenarios[scenario]
    return f"{scenario} ({s.main_metric}, {s.metric_unit(s.main_metric)})"


def _headline(board: Board) -> list[str]:
    """The answer first: per plant, whether a learned or plug-in entry beats the best classical row, and
    where (green where one does)."""
    items = []
    for plant, verdict, wins in headline(board):
        cls = "win" if wins else "none"
        sub = "".join(f"<li>{_e(w)}</li>" for w in wins)
        items.append(
            f"<li class='{cls}'><b>{_e(plant)}</b>: {_e(verdict)}"
            + (f"<ul>{sub}</ul>" if sub else "")
            + "</li>"
        )
    return ["<h2 id='answer'>The answer</h2>", f"<ul>{''.join(items)}</ul>"]


def compact_png(png: bytes) -> bytes:
    """The figure as a 256-colour PNG: a third of the bytes of matplotlib's true-colour file for line
    plots, which keeps the page (it embeds every figure) a few MB."""
    from PIL import Image  # matplotlib's own dependency; only the page needs it

    out = io.BytesIO()
    image = Image.open(io.BytesIO(png)).convert("RGB")
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, format="PNG", optimize=True)
    return out.getvalue()


def _answer_cell(cell: tuple[str, float] | str) -> str:
    """An answer cell: (text, sort value) or plain text."""
    if isinstance(cell, str):
        return f"<td>{_e(cell)}</td>"
    text, value = cell
    return f"<td data-v='{_num(value)}'>{_e(text)}</td>"
