"""MkDocs hooks (mkdocs.yml): the site shows some of the repository's own Markdown files as pages.

README.md is the landing page (``index.md``), CONTRIBUTING.md is ``contributing.md``, and ``benchmarks/*.md`` are
``benchmarks/*.md`` (their README the section's ``index.md``). Each file keeps one home, the repository; the site
reads it at build time. Their relative links, written for reading the repository, are turned into the site's, and so
are the docs pages' links to those files: ``docs/layouts.md`` from the README is ``layouts.md`` on the site.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
#: Repository files shown as pages, and where they are on the site.
BROUGHT_IN = {
    "README.md": "index.md",
    "CONTRIBUTING.md": "contributing.md",
    "benchmarks/README.md": "benchmarks/index.md",
    **{f"benchmarks/{p.name}": f"benchmarks/{p.name}" for p in sorted((ROOT / "benchmarks").glob("*.md")) if p.stem != "README"},
}
_SITE_TO_REPO = {site: repo for repo, site in BROUGHT_IN.items()}
_LINK = re.compile(r"(\]\()([^)\s#]*)(#[^)\s]*)?(\))")


def on_files(files: Files, config: Any) -> Files:
    for repo_path, site_path in BROUGHT_IN.items():
        files.append(File.generated(config, site_path, content=(ROOT / repo_path).read_text()))
    return files


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
