"""The index page ``reports/index.html`` linking every generated report below it."""

from __future__ import annotations

import time
from pathlib import Path

from brdflab.report import page as html


def write_index(root: Path) -> Path:
    """Write ``root/index.html`` listing every ``*/report.html`` and ``*/index.html`` below ``root``."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    for p in sorted(list(root.glob("*/report.html")) + list(root.glob("*/index.html"))):
        rel = p.relative_to(root).as_posix()
        kind = "variance comparison" if p.name == "report.html" else "validation"
        when = time.strftime("%Y-%m-%d %H:%M", time.localtime(p.stat().st_mtime))
        rows.append([f'<a href="{html.esc(rel)}">{html.esc(p.parent.name)}</a>', kind, when])
    body = html.section("Reports", html.table(["report", "kind", "written"], rows, raw=True) if rows
                        else html.esc_p("No reports yet."))
    path = root / "index.html"
    path.write_text(html.page("brdflab reports", body))
    return path
