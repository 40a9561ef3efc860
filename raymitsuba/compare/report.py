"""A batch's results as one HTML page and as CSV.

The HTML page is self-contained: its pictures are PNG data URIs, so the one file can be
mailed, uploaded to a course site or archived and still shows every picture. It holds a
table (scene, score, left-out pixels, PSNR, pass/fail; missing images and errors listed
as such) and, per scene, the submission, the reference and the heat map (see
``picture.py``), scaled up without smoothing so that single pixels stay visible. Both
files are written atomically.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import math

from raymitsuba.atomic import atomic_path

#: The CSV columns (and their order).
COLUMNS = ("scene", "image", "status", "match", "left_out", "psnr", "within_2", "within_8",
           "mean_abs", "worst", "message")
DISPLAY_WIDTH = 320  # CSS pixels of each picture on the page (at least)

STYLE = """
body { font-family: sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; }
th, td { border: 1px solid #bbb; padding: 0.3em 0.7em; text-align: right; white-space: nowrap; }
th:first-child, td:first-child, th:last-child, td:last-child { text-align: left; }
.pass { background: #d8f5d8; } .fail { background: #f8d4d4; }
.missing, .error, .failed { background: #f3e6c4; }
.pictures { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; } figcaption { font-weight: bold; }
.path { font-size: 0.8em; color: #555; word-break: break-all; }
img { image-rendering: pixelated; min-width: %dpx; border: 1px solid #888; }
""" % DISPLAY_WIDTH


def _data_uri(pixels) -> str:
    from raymitsuba.compare.picture import png_bytes

    return "data:image/png;base64," + base64.b64encode(png_bytes(pixels)).decode("ascii")


def _fields(result) -> dict:
    s = result.score
    row = {"scene": result.reference_name, "image": result.image_name,
           "status": result.status, "message": result.message}
    if s is not None:
        row.update(match=f"{s.match:.3f}", left_out=s.left_out, within_2=f"{s.within_2:.3f}",
                   within_8=f"{s.within_8:.3f}", mean_abs=f"{s.mean_abs:.6f}",
                   psnr="inf" if math.isinf(s.psnr) else f"{s.psnr:.2f}",
                   worst="" if s.worst is None else "x %d..%d y %d..%d" % (
                       s.worst[0], s.worst[2] - 1, s.worst[1], s.worst[3] - 1))
    return row


def csv_text(results) -> str:
    out = io.StringIO()
    writer = csv.DictWriter(out, COLUMNS, restval="", lineterminator="\n")
    writer.writeheader()
    for result in results:
        writer.writerow(_fields(result))
    return out.getvalue()


def write_csv(results, path: str) -> None:
    text = csv_text(results)
    with atomic_path(path, ".csv") as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)


def html_text(results, settings, title: str = "raymitsuba compare") -> str:
    from raymitsuba.compare.picture import HEAT_RANGE, heat_map, view
    from raymitsuba.compare.score import difference
    from raymitsuba.compare.stable import CAMERA_SHIFT, OFFSET_FACTOR

    esc = html.escape
    passed = sum(r.status == "pass" for r in results)
    tol = f"{settings.tolerance * 255:g}/255"
    parts = [f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{esc(title)}</title>",
             f"<style>{STYLE}</style></head><body>",
             f"<h1>{esc(title)}</h1>",
             f"<p>{passed} of {len(results)} passed: at least {settings.min_match:g} % of the "
             f"scored pixels within {tol} (largest channel difference). Pixels whose reference "
             f"is not stable (they change when the camera moves by {CAMERA_SHIFT:g} of the "
             f"scene or the secondary rays' offset grows {OFFSET_FACTOR:g}&times;) are left out "
             "of the score.</p>",
             "<table><tr><th>scene</th><th>score</th><th>left-out pixels</th><th>PSNR</th>"
             "<th>result</th></tr>"]
    for r in results:
        f = _fields(r)
        score = f"{f['match']} %" if r.score else "&ndash;"
        parts.append(
            f"<tr class='{r.status}'><td><a href='#{esc(r.name)}'>{esc(r.name)}</a></td>"
            f"<td>{score}</td><td>{f.get('left_out', '&ndash;')}</td>"
            f"<td>{f.get('psnr', '&ndash;')}</td><td>{esc(r.status)}</td></tr>")
    parts.append("</table>")
    for r in results:
        parts.append(f"<h2 id='{esc(r.name)}'>{esc(r.name)}: {esc(r.status)}</h2>")
        if r.score is None:
            parts.append(f"<p>{esc(r.message)}</p>")
            continue
        parts.append("<p>" + "<br>".join(esc(line) for line in r.score.lines()) + "</p>")
        pictures = (("submission", r.image_name, view(r.image, settings.srgb)),
                    ("reference", r.reference_name, view(r.reference, settings.srgb)),
                    ("difference", f"black: equal; yellow: {HEAT_RANGE * 255:g}/255 or more; "
                                   "blue-gray: left out",
                     heat_map(difference(r.image, r.reference), r.unstable)))
        parts.append("<div class='pictures'>")
        for caption, detail, pixels in pictures:
            width = max(DISPLAY_WIDTH, pixels.shape[1])
            parts.append(f"<figure style='width: {width}px'><img src='{_data_uri(pixels)}' "
                         f"width='{width}' alt='{esc(caption)}'><figcaption>{esc(caption)}"
                         f"</figcaption><div class='path'>{esc(detail)}</div></figure>")
        parts.append("</div>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


def write_html(results, settings, path: str) -> None:
    text = html_text(results, settings)
    with atomic_path(path, ".html") as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
