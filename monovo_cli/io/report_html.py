"""Self-contained HTML pages: report.html and batch's index.html.

Everything a page shows is inside the file: images as ``data:image/png;base64,...`` URIs,
styles in one ``<style>`` block, no script, no link to anything but relative paths given by
the caller. The pieces here are text in, text out; :func:`write_page` writes a page
atomically (:mod:`monovo_cli.io.atomic`).
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np

from monovo_cli.errors import OutputError
from monovo_cli.io.atomic import atomic_write_bytes

#: zlib level 1 and every row filtered by its left neighbour (libpng's default tries five
#: filters a row): about level 3's size, in less time (docs/benchmarks.md, "Speed at 20be4d5
#: and 4ce717e")
PNG_COMPRESSION = 1
PNG_FILTER = cv2.IMWRITE_PNG_FILTER_SUB

STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222;
       padding: 0 1em; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc;
       padding-bottom: .2em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: .9em; margin: .5em 0; }
th, td { border: 1px solid #ddd; padding: .2em .6em; text-align: left; vertical-align: top; }
td { overflow-wrap: anywhere; } td.num { overflow-wrap: normal; white-space: nowrap; }
.wide { max-width: 100%; overflow-x: auto; }
th { background: #f3f3f3; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; height: auto; }
.pair { display: flex; flex-wrap: wrap; column-gap: 1.5em; }
.pair section { flex: 1 1 460px; }
figure { display: inline-block; margin: .3em; text-align: center; font-size: .8em; }
tr.failed td { background: #fde8e8; } tr.lost td { background: #fff4e0; }
.note { color: #666; font-size: .9em; }
pre { background: #f7f7f7; padding: .6em; overflow-x: auto; font-size: .85em; }
"""


def esc(text: object) -> str:
    """``text`` as HTML text or an attribute value (quotes escaped)."""
    return html.escape(str(text), quote=True)


def png_bytes(image: np.ndarray) -> bytes:
    """``image`` (H, W[, 3]) uint8 (grey or BGR) as PNG bytes (:data:`PNG_COMPRESSION`,
    :data:`PNG_FILTER`)."""
    ok, buf = cv2.imencode(".png", np.asarray(image), [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION,
                                                     cv2.IMWRITE_PNG_FILTER, PNG_FILTER])
    if not ok:
        raise OutputError(f"cannot encode a {np.asarray(image).shape} image as PNG")
    return buf.tobytes()


def img_tag(image: np.ndarray | bytes, alt: str, *, width: int | None = None) -> str:
    """An ``<img>`` holding ``image`` (an array for :func:`png_bytes`, or PNG bytes) as a
    data URI; ``width`` px the displayed width (None: the image's own)."""
    data = image if isinstance(image, bytes) else png_bytes(image)
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    size = f' width="{int(width)}"' if width else ""
    return f'<img src="{uri}" alt="{esc(alt)}"{size}>'


def column_format(values: Iterable[object]) -> Callable[[float], str]:
    """The one notation of a column of numbers: fixed-point with the decimals that give the
    smallest non-zero magnitude 3 significant digits (none for whole numbers), or
    scientific with 3 decimals for all when that would take more than 9 decimals or a
    magnitude reaches 1e9 -- so ``4.45e-05`` never stands beside ``0.000979``. Not finite:
    "n/a"."""
    mags = [abs(float(v)) for v in values
            if isinstance(v, (int, float, np.number)) and not isinstance(v, (bool, np.bool_))
            and math.isfinite(float(v))]
    nonzero = [m for m in mags if m > 0]
    whole = all(float(m).is_integer() for m in mags)
    decimals = 0 if whole or not nonzero else max(0, 2 - math.floor(math.log10(min(nonzero))))
    scientific = decimals > 9 or (any(m >= 1e9 for m in mags) and not whole)

    def text(x: float) -> str:
        x = float(x)
        if not math.isfinite(x):
            return "n/a"
        return f"{x:.3e}" if scientific else f"{x:.{decimals}f}"

    return text


def cell_text(value: object) -> str:
    """A value as a person reads it: yes / no for booleans, "-" for None, a list as its
    items joined by commas, a mapping as ``key: value`` pairs, a float in the shortest
    ``g`` notation (a column of measures is formatted by :func:`column_format` instead)."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if value is None:
        return "-"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):g}" if math.isfinite(value) else "n/a"
    if isinstance(value, Mapping):
        return "; ".join(f"{k}: {cell_text(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return ", ".join(cell_text(v) for v in value)
    return str(value)


def table(header: Sequence[str], rows: Iterable[Sequence[object]], *,
          numeric: Sequence[bool] | None = None,
          row_classes: Iterable[str] | None = None) -> str:
    """A ``<table>`` of ``rows`` under ``header``, in a box that scrolls sideways rather than
    widen the page past its 1100 px (long words such as paths wrap); cells are escaped
    unless they are :class:`Markup`, values written by :func:`cell_text`; ``numeric``
    flags right-aligned columns, whose numbers are written in one notation each
    (:func:`column_format`; strings in them stay as they are); ``row_classes`` one CSS class
    per row ("" for none)."""
    numeric = list(numeric or [False] * len(header))
    rows = [list(r) for r in rows]
    formats = [column_format(r[i] for r in rows if i < len(r)) if numeric[i] else None
               for i in range(len(header))]
    classes = iter(row_classes) if row_classes is not None else None

    def cell(i: int, c: object) -> str:
        if isinstance(c, Markup):
            return c
        if formats[i] is not None and isinstance(c, (int, float, np.number)) \
                and not isinstance(c, (bool, np.bool_)):
            return esc(formats[i](c))
        return esc(cell_text(c))

    out = ['<div class="wide"><table>',
           "<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for row in rows:
        cls = next(classes) if classes is not None else ""
        cells = "".join(f'<td{" class=num" if numeric[i] else ""}>{cell(i, c)}</td>'
                        for i, c in enumerate(row))
        out.append(f'<tr class="{esc(cls)}">{cells}</tr>' if cls else f"<tr>{cells}</tr>")
    out.append("</table></div>")
    return "\n".join(out)


class Markup(str):
    """HTML already built (a link, an image), put into a table as it is."""


def link(href: str, text: str) -> Markup:
    """``<a>`` to the relative path ``href``."""
    return Markup(f'<a href="{esc(href)}">{esc(text)}</a>')


def page(title: str, body: Sequence[str]) -> str:
    """A whole HTML document: ``title`` and the ``body`` parts in order."""
    return "\n".join(["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
                      f"<title>{esc(title)}</title>", f"<style>{STYLE}</style>", "</head>",
                      "<body>", *body, "</body>", "</html>", ""])


def write_page(path: Path, text: str) -> None:
    """Write the page ``text`` to ``path`` (UTF-8) atomically."""
    atomic_write_bytes(Path(path), text.encode("utf-8"))
