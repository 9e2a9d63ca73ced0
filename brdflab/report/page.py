"""Self-contained HTML pages for brdflab reports (inline CSS/JS, images embedded as data URIs).

Every report opens from the file system without a server. Rendered images placed with
:func:`image_row` (class ``render``) share a **synchronised zoom**: clicking a point of any of them
magnifies all of them 4× around the same relative point; clicking again resets. Opening a report with
the fragment ``#selftest`` makes the page click its first image itself and record what happened in
``<body data-selftest="…">`` (used by the browser test).
"""

from __future__ import annotations

import base64
import html as _html
from pathlib import Path

STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;background:#f6f7f9;color:#222}
header{background:#20252c;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header .sub{color:#aab;font-size:13px;margin-top:4px}
main{padding:8px 24px 40px;max-width:1500px}
section{background:#fff;border:1px solid #e1e4e8;border-radius:8px;margin:16px 0;padding:12px 18px}
h2{font-size:16px;margin:4px 0 10px}
.row{display:flex;flex-wrap:wrap;gap:12px}
figure{margin:0;flex:1 1 260px;max-width:520px}
figure.plot{max-width:640px;flex-basis:360px}
figcaption{font-size:12px;color:#555;margin-top:4px}
.zoom{overflow:hidden;border:1px solid #ccc;line-height:0;cursor:zoom-in}
.zoom img{width:100%;transition:transform .15s ease-out;image-rendering:pixelated}
.zoom img.zoomed{cursor:zoom-out}
img.fig{width:100%}
table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ddd;padding:3px 8px;text-align:right}
th{background:#f0f2f5}td:first-child,th:first-child{text-align:left}
.pass{color:#1a7f37;font-weight:600}.fail{color:#cf222e;font-weight:600}
"""

SCRIPT = """
(function(){
  const imgs = () => Array.from(document.querySelectorAll('img.render'));
  function zoomAll(x, y, on){
    imgs().forEach(o => {
      o.style.transformOrigin = (100*x) + '% ' + (100*y) + '%';
      o.style.transform = on ? 'scale(4)' : '';
      o.classList.toggle('zoomed', on);
    });
  }
  document.addEventListener('click', e => {
    const img = e.target.closest('img.render');
    if (!img) return;
    const r = img.getBoundingClientRect();
    const x = (e.clientX - r.left) / r.width, y = (e.clientY - r.top) / r.height;
    zoomAll(x, y, !img.classList.contains('zoomed'));
  });
  window.addEventListener('load', () => {
    if (location.hash !== '#selftest') return;
    const all = imgs();
    const first = all[0];
    if (first) {
      const r = first.getBoundingClientRect();
      first.dispatchEvent(new MouseEvent('click', {bubbles: true, clientX: r.left + r.width * 0.25,
                                                   clientY: r.top + r.height * 0.25}));
    }
    const loaded = Array.from(document.images).filter(i => i.complete && i.naturalWidth > 0).length;
    document.body.dataset.selftest = JSON.stringify({
      images: document.images.length, loaded: loaded, renders: all.length,
      zoomed: all.filter(o => o.classList.contains('zoomed') && o.style.transform.includes('scale(4)')).length,
      plots: document.querySelectorAll('figure.plot img').length});
  });
})();
"""


def esc(text: object) -> str:
    """HTML-escape ``text``."""
    return _html.escape(str(text))


def esc_p(text: object) -> str:
    """An escaped paragraph."""
    return f"<p>{esc(text)}</p>"


def data_uri(path: Path) -> str:
    """Embed an image file as a data URI (PNG or SVG)."""
    path = Path(path)
    mime = "image/svg+xml" if path.suffix.lower() == ".svg" else "image/png"
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def image_row(items: list[tuple[Path, str]], cls: str = "render") -> str:
    """A row of captioned images; ``cls='render'`` images take part in the synchronised zoom."""
    figs = []
    for path, caption in items:
        if cls == "render":
            img = f'<div class="zoom"><img class="render" src="{data_uri(path)}" alt="{esc(caption)}"></div>'
            figs.append(f"<figure>{img}<figcaption>{esc(caption)}</figcaption></figure>")
        else:
            figs.append(f'<figure class="plot"><img class="fig" src="{data_uri(path)}" alt="{esc(caption)}">'
                        f"<figcaption>{esc(caption)}</figcaption></figure>")
    return '<div class="row">' + "".join(figs) + "</div>"


def table(headers: list[str], rows: list[list[object]], raw: bool = False) -> str:
    """An HTML table; cells are escaped unless ``raw``."""
    cell = (lambda v: str(v)) if raw else esc
    head = "".join(f"<th>{esc(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def section(title: str, body: str) -> str:
    """A titled section (``body`` is HTML)."""
    return f"<section><h2>{esc(title)}</h2>{body}</section>"


def page(title: str, body: str, subtitle: str = "generated by brdflab") -> str:
    """A complete self-contained HTML document."""
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{esc(title)}</title>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><style>{STYLE}</style></head>"
            f"<body><header><h1>{esc(title)}</h1><div class='sub'>{esc(subtitle)}</div></header>"
            f"<main>{body}</main><script>{SCRIPT}</script></body></html>")
