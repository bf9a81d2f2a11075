"""Reports: one self-contained HTML page for a run folder, a single item, or several runs side by side.

The page opens offline in any modern browser: Plotly's JavaScript is written into it, and every figure and every
elite's view is data in it (no server, no network at view time). A run's page holds its settings and timing, its
progress (best objective, and QD score and coverage for quality diversity), its archive as a heatmap, and a panel
that shows one elite: the best on opening, then whichever archive cell is clicked. How an elite is drawn is its
domain's (:meth:`structgen.registry.commands.DomainCommands.report_view`): a structure as a 3D view to turn, its
members coloured by load; a layout, a maze, a game or a world as its picture; a domain that draws nothing shows its
measures and fields. Views are compact data (a structure's points and loads, a picture's cells), drawn by Plotly
when shown: an archive of a thousand structures stays a few megabytes.

Plotly writes the figures; the page's own script only wires them together (a click on a cell shows its elite).
"""

from __future__ import annotations

import html
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from structgen.errors import InputError

__all__ = [
    "ELITES",
    "compare_page",
    "content_security_policy",
    "escaped",
    "hex_rgb",
    "image_figure",
    "item_page",
    "line_set",
    "plain_figure",
    "run_page",
    "write_page",
]

#: Elites of an archive given a view at most (the best by objective); the others show their numbers only.
ELITES = 1000
#: The most cells an archive's heatmap may have (the largest archive of the paper's settings has 10,000).
MAX_HEATMAP_CELLS = 1_000_000
#: Columns of archive.csv that place an elite rather than describe it.
_BOOKKEEPING = ("index", "objective", "threshold")


def image_figure(rgb: np.ndarray, title: str = "", labels: Any = None) -> dict[str, Any]:
    """A Plotly figure (as a dict) of an ``(rows, columns, 3)`` picture of 0-255 colours, one square per cell;
    ``labels`` (rows x columns of text) names each cell on hover."""
    import plotly.graph_objects as go

    hover = None if labels is None else [[escaped(label, quotes=False) for label in row] for row in np.asarray(labels).tolist()]
    shown = {"hoverinfo": "x+y"} if hover is None else {"hovertext": hover, "hoverinfo": "x+y+text"}
    figure = go.Figure(go.Image(z=np.asarray(rgb, dtype=np.uint8), **shown))
    figure.update_layout(title=escaped(title, quotes=False), margin={"l": 10, "r": 10, "t": 40, "b": 10}, height=420)
    figure.update_xaxes(visible=False)
    figure.update_yaxes(visible=False, scaleanchor="x")
    return plain_figure(figure)


def hex_rgb(colour: str) -> tuple[int, int, int]:
    """``"#d95f02"`` as ``(217, 95, 2)``."""
    value = colour.lstrip("#")
    return int(value[0:2], 16), int(value[2:4], 16), int(value[4:6], 16)


def line_set(
    points: np.ndarray, pairs: np.ndarray, values: np.ndarray, *, lines: Any, markers: Any, layout: Any
) -> dict[str, Any]:
    """A 3D view of line segments as compact data, drawn by the page when shown: ``points`` (whole-number
    coordinates), the ``pairs`` of points each segment joins, and each segment's colour value in [0, 1] (NaN: none,
    drawn at the bottom of the scale), kept to a byte. ``lines`` and ``markers`` are Plotly ``Scatter3d`` traces
    without their coordinates (the segments, coloured by value; the points) and ``layout`` the figure's layout: the
    page fills the coordinates in. A structure of a thousand members takes about 10 KB, against 80 KB as a figure."""
    points = np.asarray(points)
    steps = np.where(np.isnan(values), 255, np.round(np.clip(values, 0.0, 1.0) * 254))
    return {
        "lines3d": {
            "points": _typed(points, np.int16 if points.size == 0 or np.abs(points).max() < 2**15 else np.int32),
            "pairs": _typed(np.asarray(pairs), np.int32),
            "values": _typed(steps, np.uint8),
            "style": {"lines": lines.to_plotly_json(), "markers": markers.to_plotly_json(), "layout": plain_layout(layout)},
        }
    }


def _typed(array: np.ndarray, dtype: type) -> dict[str, str]:
    """An array as the page decodes it: its type and its bytes, base64."""
    import base64

    converted = array.astype(dtype)
    if not np.array_equal(converted, array):
        raise ValueError(f"values do not fit {np.dtype(dtype).name}")
    return {"dtype": np.dtype(dtype).str.lstrip("<|"), "bdata": base64.b64encode(converted.tobytes()).decode()}


def plain_layout(layout: Any) -> dict[str, Any]:
    """A Plotly layout as plain data, without the template Plotly would repeat in every figure."""
    data = layout.to_plotly_json()
    data.pop("template", None)
    return data


def plain_figure(figure: Any) -> dict[str, Any]:
    """A Plotly figure as plain data (:func:`plain_layout`)."""
    return {"data": [trace.to_plotly_json() for trace in figure.data], "layout": plain_layout(figure.layout)}


# -- pages ----------------------------------------------------------------------------------------------------------------
def run_page(run_dir: str | Path, *, elites: int = ELITES, progress: bool = False) -> str:
    """The report of the run in ``run_dir``, as HTML. ``elites`` caps the archive elites given a view (the best
    first); ``progress`` shows a bar on stderr as they are drawn."""
    from tqdm import tqdm

    from evolution import RunFolder
    from structgen.runs import open_run, summary_of

    folder, experiment = open_run(run_dir)
    rows = folder.metrics()
    summary = summary_of(folder, experiment, rows)
    hooks = experiment.spec.command_hooks()
    problem = experiment.make_problem()
    try:
        views = []
        if (folder / RunFolder.BEST / "best.json").is_file():
            best = summary.get("best") or {}
            views.append(_view(hooks, problem, folder.best_genome(problem), "best", best.get("objective"), best))
        heatmap = None
        if (folder / RunFolder.ARCHIVE).is_file():
            archive = folder.load_archive(problem)
            order = np.argsort(-archive.objective, kind="stable")[: max(0, elites)]
            shown = np.full(len(archive), -1)
            for row in tqdm(order, desc="elites drawn", unit="elite", disable=not progress, leave=False):
                numbers = {
                    name: float(values[row])
                    for name, values in archive.columns.items()
                    if name not in _BOOKKEEPING and not name.startswith("cell_")
                }
                name = f"cell {int(archive.columns['index'][row])}"
                genome = archive.genomes[row]
                shown[row] = len(views)
                views.append(_view(hooks, problem, genome, name, float(archive.objective[row]), {"measures": numbers}))
            cells = getattr(experiment.optimizer_settings, "cells", None)
            heatmap = _heatmap(archive, shown, cells, folder / RunFolder.ARCHIVE)
    finally:
        problem.close()
    title = f"{folder.path.name}: {experiment.domain}, {experiment.optimizer_name}"
    sections = [_settings_section(summary, folder), _figure_section("progress", "Progress", _progress_figure({title: rows}))]
    if heatmap is not None:
        sections.append(_figure_section("archive", "Archive (click a cell to see its elite)", heatmap))
    sections.append(_elite_section())
    return _page(title, sections, views)


def item_page(path: str | Path, spec: Any) -> str:
    """The report of a single file of the domain ``spec`` describes (a structure, or a structure's check result), as
    HTML."""
    source = Path(path)
    hooks = spec.command_hooks()
    view = hooks.report_file(source) if hooks is not None else None
    if view is None:
        raise InputError(f"{source}: not a file the {spec.id} domain reports on (--domain names another)")
    view.setdefault("name", source.name)
    return _page(f"{source.name}: {spec.id}", [_elite_section()], [view])


def compare_page(runs: Mapping[str, Sequence[Mapping[str, Any]]], table: Sequence[Mapping[str, Any]]) -> str:
    """Several runs' progress on one page: ``runs`` maps a label to its metrics rows; ``table`` is compare's table."""
    columns = list(table[0]) if table else []
    rows = "".join("<tr>" + "".join(f"<td>{escaped(row[c])}</td>" for c in columns) + "</tr>" for row in table)
    head = "".join(f"<th>{escaped(c.replace('_', ' '))}</th>" for c in columns)
    sections = [
        f'<section><h2>Runs</h2><table class="numbers"><tr>{head}</tr>{rows}</table></section>',
        _figure_section("progress", "Progress", _progress_figure(runs)),
    ]
    return _page(f"{len(runs)} runs compared", sections, [])


def write_page(page: str, output: str | Path) -> Path:
    """Write ``page`` to ``output`` whole or not at all (a file that was there is kept until the new one is
    complete)."""
    from evolution.files import atomic_write

    path = Path(output)
    if path.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"{path}: a report is an HTML page; give a name ending in .html")
    atomic_write(path, page)
    return path


# -- pieces ---------------------------------------------------------------------------------------------------------------
def _view(hooks: Any, problem: Any, genome: Any, name: str, objective: Any, numbers: Mapping[str, Any]) -> dict[str, Any]:
    view = (hooks.report_view(problem, genome) if hooks is not None else None) or {}
    fields = {"objective": objective, **(numbers.get("measures") or {}), **(numbers.get("fields") or {})}
    return {"name": name, **view, "fields": {**fields, **view.get("fields", {})}}


def _progress_figure(runs: Mapping[str, Sequence[Mapping[str, Any]]]) -> dict[str, Any]:
    """Best objective, and QD score and coverage where runs have them, over generations: one trace per run."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    panels = [("best_objective", "best objective")]
    panels += [(key, label) for key, label in (("qd_score", "QD score"), ("coverage", "coverage")) if _any(runs, key)]
    figure = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.06)
    palette = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")
    for number, (label, rows) in enumerate(runs.items()):
        colour = palette[number % len(palette)]
        generations = [row.get("generation") for row in rows]
        for panel, (key, title) in enumerate(panels, start=1):
            values = [row.get(key) for row in rows]
            figure.add_trace(
                go.Scatter(
                    x=generations,
                    y=values,
                    name=escaped(label, quotes=False),
                    legendgroup=label,
                    showlegend=panel == 1,
                    line={"color": colour},
                ),
                row=panel,
                col=1,
            )
            figure.update_yaxes(title_text=title, row=panel, col=1)
    figure.update_xaxes(title_text="generation", row=len(panels), col=1)
    figure.update_layout(height=260 * len(panels) + 60, margin={"l": 60, "r": 20, "t": 20, "b": 40})
    return plain_figure(figure)


def _any(runs: Mapping[str, Sequence[Mapping[str, Any]]], key: str) -> bool:
    return any(key in row for rows in runs.values() for row in rows)


def _heatmap(archive: Any, shown: np.ndarray, shape: Sequence[int] | None, source: Any = "archive.csv") -> dict[str, Any]:
    """The archive's objective over its first two measures' cells (``shape``, the archive's cells per measure); a
    cell's custom data is its elite's view (-1: none). One measure is drawn as a single row."""
    import plotly.graph_objects as go

    cells = archive.cells
    # Measure names stand in the hover template too, where a % would start a field.
    names = [escaped(name, quotes=False).replace("%", "&#37;") for name in archive.measure_names]
    if cells.shape[1] == 1:
        cells, names = np.concatenate([cells, np.zeros_like(cells)], axis=1), [names[0], ""]
    size = cells[:, :2].max(axis=0) + 1 if len(cells) else np.array([1, 1])
    if shape is not None:
        configured = np.array([*list(shape)[:2], 1][:2])
        if (size > configured).any():
            raise InputError(f"{source}: an elite's cell {cells[:, :2].max(axis=0).tolist()} lies outside the archive's "
                             f"{configured.tolist()} cells (the run's settings)")  # fmt: skip
        size = configured
    if int(size[0]) * int(size[1]) > MAX_HEATMAP_CELLS:
        raise InputError(f"{source}: a heatmap of {int(size[0]):,} x {int(size[1]):,} cells is more than the "
                         f"{MAX_HEATMAP_CELLS:,} a report draws")  # fmt: skip
    z = np.full((int(size[1]), int(size[0])), np.nan)
    custom = np.full(z.shape, -1, dtype=np.int64)
    z[cells[:, 1], cells[:, 0]] = archive.objective
    custom[cells[:, 1], cells[:, 0]] = shown
    figure = go.Figure(
        go.Heatmap(
            z=z,
            customdata=custom,
            colorscale="Viridis",
            colorbar={"title": "objective"},
            hovertemplate=f"{names[0]} cell %{{x}}<br>{names[1]} cell %{{y}}<br>objective %{{z:.4g}}<extra></extra>",
        )
    )
    figure.update_layout(
        xaxis_title=f"{names[0]} (cell)", yaxis_title=f"{names[1]} (cell)", height=480, margin={"l": 60, "r": 20, "t": 20}
    )
    return plain_figure(figure)


def _settings_section(summary: Mapping[str, Any], folder: Any) -> str:
    seconds = summary.get("wall_s")
    rows = [
        ("domain", summary["domain"]),
        ("optimizer", summary["optimizer"]),
        ("seed", summary["seed"]),
        ("generations", f"{summary['generations']:,} of {summary['generations_configured']:,}"),
        ("evaluations", f"{summary['evaluations']:,}"),
        ("time", f"{seconds:,.1f} s" if isinstance(seconds, (int, float)) else "-"),
        ("started", summary.get("created") or "-"),
        ("structgen", summary.get("structgen") or "-"),
    ]
    archive = summary.get("archive")
    if archive:
        rows += [("elites", f"{archive['elites']:,}"), ("coverage", f"{archive['coverage']:.1%}")]
        rows.append(("QD score", archive["qd_score"]))
    cells = "".join(f"<tr><th>{escaped(k)}</th><td>{escaped(v)}</td></tr>" for k, v in rows)
    config = (folder / "config.toml").read_text() if (folder / "config.toml").is_file() else ""
    return (
        f'<section><h2>The run</h2><table class="numbers">{cells}</table>'
        f"<details><summary>Settings (config.toml)</summary><pre>{escaped(config)}</pre></details></section>"
    )


def _figure_section(key: str, title: str, figure: Mapping[str, Any]) -> str:
    return f'<section><h2>{escaped(title)}</h2><div id="{key}" class="figure" data-figure="{key}"></div></section>' + (
        f'<script type="application/json" id="{key}-data">{_json(figure)}</script>'
    )


def _elite_section() -> str:
    return (
        '<section id="elite"><h2 id="elite-title">Elite</h2><p id="elite-verdict"></p>'
        '<div class="elite"><div id="elite-view" class="figure"></div><table id="elite-fields" class="numbers"></table></div>'
        "</section>"
    )


def escaped(value: Any, *, quotes: bool = True) -> str:
    """``value`` as text that may stand anywhere in the page, or (``quotes=False``) in a figure's text: titles, hover
    labels, axis and trace names, which Plotly reads as markup too (its ``<a>`` even takes a script). ``<``, ``>``
    and ``&`` become entities, and in the page both quotes as well. Everything a page holds that came from a file
    (names of measures and fields, their values, folder names, settings) goes through here; the page's own script
    sets text, never markup."""
    return html.escape(_shown(value), quote=quotes)


def _shown(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else "-"
    return str(value)


def _json(value: Any) -> str:
    """JSON safe inside a script element (``</`` cannot close it); NaN and infinities as null."""
    from plotly.io.json import to_json_plotly

    return to_json_plotly(value).replace("</", "<\\/")


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px; padding: 0 1em; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.4em; }
table.numbers { border-collapse: collapse; } table.numbers th, table.numbers td { padding: 2px 10px; text-align: left;
  border-bottom: 1px solid #eee; font-variant-numeric: tabular-nums; }
.elite { display: flex; gap: 1.5em; align-items: flex-start; flex-wrap: wrap; }
#elite-view { flex: 1 1 640px; min-height: 200px; }
pre { background: #f6f8fa; padding: 0.8em; overflow-x: auto; } footer { margin-top: 2em; color: #777; font-size: 0.85em; }
"""

# The page's own script: it draws the figures the page holds and shows an elite's view when its cell is clicked.
_SCRIPT = """
const VIEWS = JSON.parse(document.getElementById("views-data").textContent);
const STYLES = JSON.parse(document.getElementById("styles-data").textContent);
const CONFIG = {responsive: true, displaylogo: false};
const TYPES = {i1: Int8Array, u1: Uint8Array, i2: Int16Array, i4: Int32Array, f4: Float32Array};
function decode(array) {
  const bytes = Uint8Array.from(atob(array.bdata), (c) => c.charCodeAt(0));
  return new TYPES[array.dtype](bytes.buffer);
}
// A compact line set (report.line_set) as a figure: its style's traces with the coordinates filled in.
function lineSetFigure(set) {
  const style = STYLES[set.style], points = decode(set.points), pairs = decode(set.pairs), values = decode(set.values);
  const lines = structuredClone(style.lines), markers = structuredClone(style.markers);
  const x = [], y = [], z = [], colour = [];
  for (let k = 0; k < values.length; k++) {
    const a = 3 * pairs[2 * k], b = 3 * pairs[2 * k + 1], value = values[k] === 255 ? -1 : values[k] / 254;
    x.push(points[a], points[b], null); y.push(points[a + 1], points[b + 1], null); z.push(points[a + 2], points[b + 2], null);
    colour.push(value, value, value);
  }
  Object.assign(lines, {x, y, z, customdata: colour});
  lines.line = {...lines.line, color: colour};
  Object.assign(markers, {x: [], y: [], z: []});
  for (let i = 0; i < points.length; i += 3) {
    markers.x.push(points[i]); markers.y.push(points[i + 1]); markers.z.push(points[i + 2]);
  }
  return {data: [lines, markers], layout: style.layout};
}
function showElite(index) {
  const view = VIEWS[index];
  if (!view) return;
  document.getElementById("elite-title").textContent = "Elite: " + view.name;
  document.getElementById("elite-verdict").textContent = view.verdict || "";
  // Names and values come from files: they are set as text, never parsed as markup.
  const rows = Object.entries(view.fields || {}).map(([name, value]) => {
    const row = document.createElement("tr"), head = document.createElement("th"), cell = document.createElement("td");
    head.textContent = name;
    cell.textContent = typeof value === "number" ? String(Number(value.toPrecision(6)))
      : typeof value === "string" ? value : value === null || value === undefined ? "-" : JSON.stringify(value);
    row.append(head, cell);
    return row;
  });
  document.getElementById("elite-fields").replaceChildren(...rows);
  const target = document.getElementById("elite-view");
  const figure = view.lines3d ? lineSetFigure(view.lines3d) : view.figure;
  if (figure) Plotly.react(target, figure.data, figure.layout, CONFIG);
  else { Plotly.purge(target); target.textContent = "This domain draws no picture of its elites."; }
}
for (const div of document.querySelectorAll("div[data-figure]")) {
  const figure = JSON.parse(document.getElementById(div.dataset.figure + "-data").textContent);
  Plotly.newPlot(div, figure.data, figure.layout, CONFIG).then((plot) => {
    if (div.id === "archive") plot.on("plotly_click", (event) => {
      const index = event.points[0].customdata;
      if (index >= 0) showElite(index);
    });
  });
}
if (VIEWS.length) showElite(0);
"""


def content_security_policy(*scripts: str) -> str:
    """The page's Content-Security-Policy: only the given scripts run (named by their SHA-256, so no script written
    into the page from a file, and no inline event handler, can), nothing is fetched from anywhere (pictures only as
    data the page holds), no form is sent and no base address set. Plotly needs inline styles (it styles what it
    draws), which let no markup from a file run."""
    import base64
    import hashlib

    hashes = " ".join(f"'sha256-{base64.b64encode(hashlib.sha256(s.encode()).digest()).decode()}'" for s in scripts)
    return (
        f"default-src 'none'; script-src {hashes}; style-src 'unsafe-inline'; img-src data: blob:; "
        "font-src data:; worker-src blob:; connect-src 'none'; base-uri 'none'; form-action 'none'"
    )


def _page(title: str, sections: Sequence[str], views: Sequence[Mapping[str, Any]]) -> str:
    from plotly.offline import get_plotlyjs

    from structgen import __version__

    # A run's views share one style: it is written once and named by its number.
    styles: list[Any] = []
    compact = []
    for view in views:
        if "lines3d" in view:
            lines = dict(view["lines3d"])
            style = lines.pop("style")
            if style not in styles:
                styles.append(style)
            view = {**view, "lines3d": {**lines, "style": styles.index(style)}}
        compact.append(view)
    views = compact

    stamp = time.strftime("%Y-%m-%d %H:%M")
    plotly_js = get_plotlyjs()
    return (
        f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta http-equiv="Content-Security-Policy" content="{content_security_policy(plotly_js, _SCRIPT)}">'
        f"<title>{escaped(title)}</title>"
        f"<style>{_STYLE}</style><script>{plotly_js}</script></head>\n<body><h1>{escaped(title)}</h1>\n"
        + "\n".join(sections)
        + f'\n<script type="application/json" id="views-data">{_json(list(views))}</script>'
        + f'\n<script type="application/json" id="styles-data">{_json(styles)}</script>'
        + f"\n<script>{_SCRIPT}</script>\n<footer>structgen {__version__}, {stamp}</footer></body></html>\n"
    )
