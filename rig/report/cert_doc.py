"""A small document model (headings, paragraphs, tables, figures) written as Markdown or HTML.

Text from the record is always escaped on output: `html_escape` for HTML, `md_escape` for
Markdown (so that a raw '<' cannot become markup when the Markdown is converted later).
"""

from __future__ import annotations

import base64
import html
import os
import re
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Heading:
    """A section heading (level 1-3); `new_page`: printed at the top of a new page."""

    text: str
    level: int = 2
    new_page: bool = False


@dataclass(frozen=True)
class Para:
    """A paragraph of plain text; `strong` for emphasis."""

    text: str
    strong: bool = False


@dataclass(frozen=True)
class Table:
    """A table with a header row."""

    headers: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class Figure:
    """A figure with its caption: a PNG file on disk (Markdown links it) and/or SVG text (HTML
    embeds it; vector, so it scales for print)."""

    path: Path | None
    caption: str
    svg: str | None = None


@dataclass(frozen=True)
class Code:
    """A command to type, shown verbatim."""

    text: str


@dataclass(frozen=True)
class Banner:
    """The verdict, shown prominently; tone is 'pass', 'fail' or 'none'; `mark` (a simulated run's
    SIMULATED - NOT A CERTIFICATION) above its title."""

    title: str
    lines: tuple[str, ...]
    tone: str
    mark: str = ""


@dataclass(frozen=True)
class Logo:
    """An image given as data (the lab's logo, PNG or JPEG, from the record): HTML embeds it,
    Markdown leaves it out."""

    media_type: str
    data_b64: str
    alt: str


@dataclass(frozen=True)
class PageMarks:
    """What every printed page of the HTML carries in its margins (CSS paged media): the report id
    and the lab at the top, a simulated run's mark, and "page x of y" at the foot."""

    report_id: str
    lab: str = ""
    mark: str = ""
    status: str = ""  # e.g. DRAFT - NOT ISSUED


Block = Heading | Para | Table | Figure | Code | Banner | Logo


def kv(pairs: list[tuple[str, str]]) -> Table:
    """A two-column table of labelled values."""
    return Table(("item", "value"), tuple(pairs))


_ENTITY = re.compile(r"&(?=#?\w+;)")  # what a Markdown converter would read as an entity
_RAW_HTML = re.compile(r"<(?=[A-Za-z/!?])")  # ... or as the start of a tag, comment or declaration


def html_escape(text: object) -> str:
    """Text safe inside HTML elements and attribute values."""
    return html.escape(str(text), quote=True)


def md_escape(text: object, cell: bool = False) -> str:
    """Text safe in Markdown: no raw HTML; in a table cell, no column breaks or newlines."""
    out = _RAW_HTML.sub("&lt;", _ENTITY.sub("&amp;", str(text)))  # '<=' stays readable
    if cell:
        out = out.replace("\\", "\\\\").replace("|", "\\|").replace("\r", " ").replace("\n", " ")
    return out


def to_markdown(blocks: list[Block], link_base: Path | None) -> str:
    """Markdown with pipe tables; figures linked relative to `link_base` (the document's folder),
    or by absolute path when the document's place is unknown."""
    parts: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            parts.append("#" * b.level + " " + md_escape(b.text))
        elif isinstance(b, Para):
            parts.append(f"**{md_escape(b.text)}**" if b.strong else md_escape(b.text))
        elif isinstance(b, Table):
            lines = ["| " + " | ".join(md_escape(h, cell=True) for h in b.headers) + " |"]
            lines.append("|" + "|".join("---" for _ in b.headers) + "|")
            lines += ["| " + " | ".join(md_escape(c, cell=True) for c in row) + " |" for row in b.rows]
            parts.append("\n".join(lines))
        elif isinstance(b, Figure):
            if b.path is None:  # drawn only in memory, for HTML
                continue
            where = os.path.abspath(b.path)
            rel = where if link_base is None else os.path.relpath(where, os.path.abspath(link_base))
            link = Path(rel).as_posix()
            target = f"<{link}>" if " " in link else link
            parts.append(f"![{md_escape(b.caption)}]({target})\n\n*Figure: {md_escape(b.caption)}*")
        elif isinstance(b, Code):
            parts.append(f"```\n{b.text}\n```")
        elif isinstance(b, Logo):
            continue  # an image as data is for HTML; Markdown names the lab in text
        else:
            marked = [f"> **{md_escape(b.mark)}**"] if b.mark else []
            body = marked + [f"> **{md_escape(b.title)}**"] + [f"> {md_escape(line)}" for line in b.lines]
            parts.append("\n>\n".join(body))
    return "\n\n".join(parts) + "\n"


_CSS = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 2rem auto; padding: 0 1rem;
       color: #1b1b1b; line-height: 1.4; }
h1 { font-size: 1.6rem; border-bottom: 2px solid #333; padding-bottom: .3rem; }
h2 { font-size: 1.2rem; margin-top: 2rem; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; margin: .6rem 0; font-size: .9rem; }
th, td { border: 1px solid #bbb; padding: .2rem .5rem; text-align: left; vertical-align: top; }
th { background: #eee; }
.banner { border: 3px solid; border-radius: 6px; padding: .8rem 1.2rem; margin: 1rem 0; }
.banner .title { font-size: 1.5rem; font-weight: bold; }
.pass { border-color: #1a7f37; background: #e8f5ec; }
.fail { border-color: #c0262d; background: #fbeaea; }
.none { border-color: #9a6700; background: #fff8e1; }
pre { background: #f4f4f4; padding: .6rem; overflow-x: auto; }
figure { margin: 1rem 0; } figure img { width: 100%; max-width: 40rem; height: auto; }
figcaption { font-size: .85rem; color: #555; }
.banner .mark { font-size: 1.4rem; font-weight: bold; color: #6f2da8; letter-spacing: .05em; }
.logo { max-height: 18mm; max-width: 60mm; }
@page { size: A4; margin: 18mm 14mm 16mm; }
@media print {
  h1.new-page, h2.new-page { break-before: page; page-break-before: always; }
  body { max-width: none; margin: 0; padding: 0; font-size: 10pt; }
  h1, h2, h3 { break-after: avoid; page-break-after: avoid; }
  table, tr, figure, pre, .banner { break-inside: avoid; page-break-inside: avoid; }
  figure img { max-width: 100%; }
  pre { white-space: pre-wrap; overflow: visible; }
  .banner, th { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
}
"""


def css_string(text: str) -> str:
    """`text` as a CSS string literal: every character but letters, digits and spaces escaped (so a
    record's text can neither end the string nor the style element)."""
    out = "".join(c if c.isascii() and (c.isalnum() or c == " ") else f"\\{ord(c):06x}" for c in text)
    return f'"{out}"'


def page_css(marks: PageMarks) -> str:
    """The @page margin boxes that put the marks on every printed page (Chromium 131 and later)."""
    boxes = {
        "top-left": (css_string(marks.lab), ""),
        "top-center": (css_string(marks.mark), "color: #6f2da8; font-weight: bold; font-size: 11pt;"),
        "top-right": (css_string(f"Report {marks.report_id}"), ""),
        "bottom-left": (css_string(marks.status), "color: #c0262d; font-weight: bold;"),
        "bottom-right": ('"page " counter(page) " of " counter(pages)', ""),
    }
    inner = "".join(
        f"  @{box} {{ content: {content}; font-family: system-ui, sans-serif; font-size: 8.5pt; {style}}}\n"
        for box, (content, style) in boxes.items()
        if content != '""'
    )
    return f"@page {{\n{inner}}}\n"


def to_html(blocks: list[Block], title: str, marks: PageMarks | None = None) -> str:
    """A standalone HTML page: inline CSS (screen and print; `marks` in every printed page's
    margins), figures embedded as data: URIs (SVG where drawn as such), all text escaped."""
    e = html_escape
    body: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            cls = ' class="new-page"' if b.new_page else ""
            body.append(f"<h{b.level}{cls}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            body.append(f"<p><strong>{e(b.text)}</strong></p>" if b.strong else f"<p>{e(b.text)}</p>")
        elif isinstance(b, Table):
            head = "".join(f"<th>{e(h)}</th>" for h in b.headers)
            rows = "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in b.rows)
            body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
        elif isinstance(b, Figure):
            if b.svg is not None:
                data, kind = base64.b64encode(b.svg.encode("utf-8")).decode("ascii"), "svg+xml"
            elif b.path is not None:
                data, kind = base64.b64encode(b.path.read_bytes()).decode("ascii"), "png"
            else:
                continue
            body.append(
                f'<figure><img src="data:image/{kind};base64,{data}" alt="{e(b.caption)}">'
                f"<figcaption>{e(b.caption)}</figcaption></figure>"
            )
        elif isinstance(b, Code):
            body.append(f"<pre><code>{e(b.text)}</code></pre>")
        elif isinstance(b, Logo):
            if b.media_type in ("image/png", "image/jpeg") and re.fullmatch(r"[A-Za-z0-9+/=]*", b.data_b64):
                body.append(
                    f'<img class="logo" src="data:{b.media_type};base64,{b.data_b64}" alt="{e(b.alt)}">'
                )
        else:
            mark = f'<div class="mark">{e(b.mark)}</div>' if b.mark else ""
            lines = "".join(f"<p>{e(line)}</p>" for line in b.lines)
            body.append(
                f'<div class="banner {e(b.tone)}">{mark}<div class="title">{e(b.title)}</div>{lines}</div>'
            )
    css = _CSS + (page_css(marks) if marks is not None else "")
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{e(title)}</title>\n<style>{css}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )
