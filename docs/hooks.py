"""MkDocs hooks (mkdocs.yml): the site shows some of the repository's own Markdown files as pages.

README.md is the landing page (``index.md``), CONTRIBUTING.md is ``contributing.md``, and ``benchmarks/*.md`` are
``benchmarks/*.md`` (their README the section's ``index.md``, the anchors' README
``benchmarks/anchors.md``). Each file keeps one home, the repository; the site
reads it at build time. Their relative links, written for reading the repository, are turned into the site's, and so
are the docs pages' links to those files: ``docs/layouts.md`` from the README is ``layouts.md`` on the site.

The picture of the layers (``layers.svg``, in docs/architecture.md) is drawn at build time from the import graph that
tests/test_layering.py checks (tests/layering.py), so it cannot fall behind the code.
"""

from __future__ import annotations

import posixpath
import re
import sys
from collections import Counter
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
#: Repository files shown as pages, and where they are on the site.
BROUGHT_IN = {
    "README.md": "index.md",
    "CONTRIBUTING.md": "contributing.md",
    "benchmarks/README.md": "benchmarks/index.md",
    "benchmarks/anchors/README.md": "benchmarks/anchors.md",
    **{f"benchmarks/{p.name}": f"benchmarks/{p.name}" for p in sorted((ROOT / "benchmarks").glob("*.md")) if p.stem != "README"},
}
_SITE_TO_REPO = {site: repo for repo, site in BROUGHT_IN.items()}
_LINK = re.compile(r"(\]\()([^)\s#]*)(#[^)\s]*)?(\))")


def on_files(files: Files, config: Any) -> Files:
    for repo_path, site_path in BROUGHT_IN.items():
        files.append(File.generated(config, site_path, content=(ROOT / repo_path).read_text()))
    files.append(File.generated(config, "layers.svg", content=layers_svg()))
    return files


def _group(name: str) -> str:
    """Where a module is drawn: its library, structgen's core files, a layer's folder, or a domain."""
    parts = name.split(".")
    if parts[0] != "structgen":
        return f"{parts[0]}/"
    if name == "structgen.__main__":
        return "cli/"
    if len(parts) > 2 and parts[1] == "domains":
        return f"domains/{parts[2]}/"
    if len(parts) > 1 and (ROOT / "structgen" / parts[1]).is_dir():
        return f"{parts[1]}/"
    return "structgen/*.py"


_LAYER_NAMES = {
    1: "libraries",
    2: "core",
    3: "how domains are described",
    4: "runs, for any domain",
    5: "domains",
    6: "command line",
}


def layers_figure() -> Any:
    """One band per layer (highest on top), a box per folder with its module count, and an arrow for each pair of
    folders one imports from the other, labelled with the count of module imports (an arrow up would be red)."""
    sys.path.insert(0, str(ROOT))
    try:
        from evolution.plots import new_figure
        from tests.layering import GRAPH, layer
    finally:
        sys.path.remove(str(ROOT))
    modules = Counter(_group(name) for name in GRAPH)
    layer_of = {_group(name): layer(name) for name in GRAPH}
    edges = Counter((_group(a), _group(b)) for a in GRAPH for b in GRAPH[a] if _group(a) != _group(b))
    layers = sorted(set(layer_of.values()))
    figure = new_figure(figsize=(11, 1.15 * len(layers)), layout="constrained")
    ax = figure.subplots()
    place: dict[str, tuple[float, float]] = {}
    half_width: dict[str, float] = {}
    box_h = 0.36
    for number in layers:
        y = number
        ax.axhspan(y - 0.48, y + 0.48, color="#eaf0f8" if number % 2 else "#f6f8fb", zorder=0)
        ax.text(-0.02, y, f"layer {number}\n{_LAYER_NAMES.get(number, '')}", ha="right", va="center", fontsize=9)
        groups = sorted(group for group, at in layer_of.items() if at == number)
        for column, group in enumerate(groups):
            x = (column + 0.5) / len(groups)
            width = min(0.92 / len(groups), 0.3)
            place[group], half_width[group] = (x, y), width / 2
            ax.add_patch(
                __import__("matplotlib.patches", fromlist=["FancyBboxPatch"]).FancyBboxPatch(
                    (x - width / 2, y - box_h / 2), width, box_h, boxstyle="round,pad=0.01", fc="white", ec="#345", zorder=3
                )
            )
            label = group.removeprefix("domains/") or "domains/__init__"  # the band names the domains already
            ax.text(x, y, f"{label} ({modules[group]})", ha="center", va="center", fontsize=9, zorder=4)
    for (source, target), count in sorted(edges.items()):
        (x1, y1), (x2, y2) = place[source], place[target]
        colour = "#c00" if layer_of[target] > layer_of[source] else "#556"
        # Ends spread along the boxes' edges, towards each other, so that arrows into one box stay apart.
        x1 += 0.8 * half_width[source] * max(-1.0, min(1.0, (x2 - x1) / 0.5))
        x2 += 0.8 * half_width[target] * max(-1.0, min(1.0, (place[source][0] - x2) / 0.5))
        start, end = (x1, y1 - box_h / 2), (x2, y2 + box_h / 2)
        if y1 == y2:  # within a layer: under the boxes
            start, end = (x1, y1 - box_h / 2), (x2, y2 - box_h / 2)
        ax.annotate(
            "",
            xy=end,
            xytext=start,
            arrowprops={"arrowstyle": "-|>", "color": colour, "alpha": 0.4, "lw": 0.8, "shrinkA": 0, "shrinkB": 0},
            zorder=2,
        )
        ax.text(  # near the arrow's start, where arrows from one box are still apart
            start[0] + 0.25 * (end[0] - start[0]),
            start[1] + 0.25 * (end[1] - start[1]),
            str(count),
            fontsize=7,
            color=colour,
            ha="center",
            zorder=5,
            bbox={"fc": "white", "ec": "none", "pad": 0.5, "alpha": 0.8},
        )
    ax.set_xlim(-0.01, 1.01)
    ax.set_ylim(layers[0] - 0.5, layers[-1] + 0.5)
    ax.axis("off")
    return figure


def layers_svg() -> str:
    """:func:`layers_figure` as SVG, its words kept as text (searchable, and a tenth of the size as paths)."""
    import io

    import matplotlib

    out = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        layers_figure().savefig(out, format="svg")
    return out.getvalue()


def _repo_path(site_path: str) -> str:
    return _SITE_TO_REPO.get(site_path, f"docs/{site_path}")


def _site_path(repo_path: str) -> str | None:
    if repo_path in BROUGHT_IN:
        return BROUGHT_IN[repo_path]
    if repo_path.startswith("docs/"):
        return repo_path[len("docs/") :]
    return None


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    here_site = page.file.src_uri
    here_repo = _repo_path(here_site)

    def rewrite(match: re.Match) -> str:
        opening, target, anchor, closing = match.groups()
        if not target or re.match(r"^[a-z]+:", target) or target.startswith("/"):
            return match.group(0)
        repo_target = posixpath.normpath(posixpath.join(posixpath.dirname(here_repo), target))
        site_target = _site_path(repo_target)
        if site_target is None:  # a file the site does not hold: left as written, for the link check to report
            return match.group(0)
        relative = posixpath.relpath(site_target, posixpath.dirname(here_site) or ".")
        return f"{opening}{relative}{anchor or ''}{closing}"

    return _LINK.sub(rewrite, markdown)
