"""A self-contained HTML report: images next to ``index.html``, a metrics table, captions.

The page carries a small script that, once loaded, checks that every image decoded and writes the
result into the hidden ``#image-check`` (``"images ok: N/N"``), so a headless browser can verify
the report without the text showing on the page.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path

from dualpixel.io.atomic import atomic_path

__all__ = ["Figure", "Report", "write_html_report"]

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
figure { display: inline-block; margin: 0.5em; vertical-align: top; }
figure img { max-width: 100%; border: 1px solid #ccc; }
figcaption { font-size: 0.9em; color: #555; max-width: 520px; }
table { border-collapse: collapse; margin: 1em 0; }
td, th { border: 1px solid #bbb; padding: 0.3em 0.7em; text-align: right; }
th { background: #f0f0f0; } code { background: #f4f4f4; padding: 0 0.2em; }
"""

_CHECK = """
<script>
window.addEventListener("load", () => {
  const images = Array.from(document.images);
  const ok = images.filter(i => i.complete && i.naturalWidth > 0).length;
  document.getElementById("image-check").textContent = `images ok: ${ok}/${images.length}`;
});
</script>
"""


@dataclass
class Figure:
    """An image file (relative to the report) with a caption."""

    path: str
    caption: str
    width: int | None = None


@dataclass
class Report:
    title: str
    intro: str = ""
    sections: list[tuple[str, list[Figure], str]] = field(default_factory=list)
    tables: list[tuple[str, list[str], list[list[str]]]] = field(default_factory=list)
    footer: str = ""


def _figure(fig: Figure) -> str:
    width = f' width="{fig.width}"' if fig.width else ""
    return (f'<figure><img src="{html.escape(fig.path)}" alt="{html.escape(fig.caption)}"'
            f"{width}><figcaption>{html.escape(fig.caption)}</figcaption></figure>")


def write_html_report(report: Report, output: str | Path) -> Path:
    """Write ``index.html`` into ``output`` (atomically) and return its path."""
    output = Path(output)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>"
             f"{html.escape(report.title)}</title><style>{_STYLE}</style></head><body>",
             f"<h1>{html.escape(report.title)}</h1><p>{report.intro}</p>"]
    for caption, header, rows in report.tables:
        parts.append(f"<h2>{html.escape(caption)}</h2><table><tr>" +
                     "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
        parts += ["<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>"
                  for row in rows]
        parts.append("</table>")
    for heading, figures, text in report.sections:
        parts.append(f"<h2>{html.escape(heading)}</h2>")
        if text:
            parts.append(f"<p>{text}</p>")
        parts += [_figure(f) for f in figures]
    parts.append(f"<p>{report.footer}</p><p id='image-check' hidden>images not checked</p>{_CHECK}")
    parts.append("</body></html>")
    path = output / "index.html"
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(parts), encoding="utf-8")
    return path
