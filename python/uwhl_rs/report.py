"""``uwhl report OUTDIR``: one page for a whole batch (docs/REPORT.md).

Reads the sidecars under OUTDIR (a local folder or an object-storage URL,
``uwhl_rs.storage``), writes small thumbnails once
(``OUTDIR/report/thumbs/``) and ``OUTDIR/report/index.html``: the photos
that need a look first (their flags), a histogram of the water types, the
water type, A and the choice's score over the sequence (and the blue
attenuation fitted from a distance, where there is one), and a grid of
before/after thumbnails, paginated in the page, that open the full-size
photo and its transmission map. The page needs nothing but the files
beside it: no network, no script library.
"""

from __future__ import annotations

import errno
import hashlib
import html
import io as _io
import json
import os
import posixpath
import re
import stat
import tempfile
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import uwhl_rs

from . import _core, report_video
from .errors import UwhlError
from .images import IMAGE_EXTENSIONS, RAW_EXTENSIONS, read_image, to_srgb
from .outdir import FILE_NAME, REPORT_DIR, Digests, Photo, collect_sidecars, failed_inputs
from .report_series import series_axis, series_svg, used_water
from .sidecars import display, printable
from .storage import Folder, is_url, on_storage, open_regular, scheme, spool

__all__ = ["write_report", "collect_sidecars", "REPORT_DIR", "THUMB_SIDE", "PAGE_SIZE", "MAX_INPUT_BYTES", "thumb_names",
           "script_json", "series_axis"]

#: the longer side of a thumbnail, in pixels
THUMB_SIDE = 256
#: A file decoded whole for its thumbnail (16-bit or float TIFF) may have at most this many pixels:
#: its float copy is 12 bytes a pixel, and thumbnails are made several at a time.
THUMB_MAX_PIXELS = 64_000_000
#: what Pillow may decode a thumbnail from (the formats of IMAGE_EXTENSIONS)
THUMB_FORMATS = ("JPEG", "PNG", "TIFF")
#: thumbnails per page of the grid
PAGE_SIZE = 120

_TYPE_COLORS = {"I": "#08306b", "IA": "#08519c", "IB": "#2171b5", "II": "#4292c6", "III": "#6baed6",
                "1C": "#41ab5d", "3C": "#238b45", "5C": "#006d2c", "7C": "#8c6d31", "9C": "#5b4a1f"}


# ---------------------------------------------------------------- thumbnails
# A sidecar is not trusted (uwhl_rs.sidecars): its ``input`` names a file
# the report opens only when it is a regular file whose SHA-256 is the one
# the batch recorded (metadata.input_sha256), so a planted sidecar cannot
# have the report fetch a URL, read a device or FIFO, or show another file;
# the outputs it names are bare file names beside it, inside the folder.

#: the largest input file hashed and thumbnailed (raw files and TIFFs included), and output
#: photo thumbnailed; one on object storage is copied to a temporary file a chunk at a time
MAX_INPUT_BYTES = 4 << 30


def thumb_names(sidecar: str) -> tuple[str, str]:
    """The thumbnails of the photo of ``sidecar`` (relative to OUTDIR):
    input and restored, in ``report/thumbs``. The name keeps the photo's
    for a reader, and a digest of its whole path so that no two photos
    share one (``a/b`` and ``a__b``); ``.jpeg`` is an extension no output
    of a batch has, so a thumbnail never replaces an output."""
    stem = sidecar[:-5] if sidecar.endswith(".json") else sidecar
    slug = re.sub(r"[^A-Za-z0-9._-]", "_", posixpath.basename(stem))[:60]
    digest = hashlib.sha256(stem.encode("utf-8", "surrogatepass")).hexdigest()[:16]
    tdir = REPORT_DIR + "/thumbs"
    return f"{tdir}/{slug}-{digest}_in.jpeg", f"{tdir}/{slug}-{digest}_out.jpeg"


def _candidates(src: str, folder) -> list[str]:
    """Where a relative ``input`` may be: the batch's working folder is not
    recorded, so the folders above the output folder (nearest first), then
    the current one; the recorded hash says which, if any, is the input."""
    if os.path.isabs(src):
        return [src]
    bases = []
    if not folder.is_url:
        d = os.path.abspath(folder.root)
        while True:
            bases.append(d)
            up = os.path.dirname(d)
            if up == d:
                break
            d = up
    bases.append(os.getcwd())
    out = []
    for b in bases:
        c = os.path.normpath(os.path.join(b, src))
        if c not in out:
            out.append(c)
    return out


def _input_file(p: Photo, folder, digests: Digests):
    """The batch's input of ``p`` opened (a binary file object), or None
    and why it is not shown. Each file is hashed once a run (``digests``)."""
    src = p.doc["input"]
    want = (p.doc.get("metadata") or {}).get("input_sha256")
    shown = display(src)
    # the network is the folder's own storage only: never http(s), never elsewhere
    if is_url(src) and (not folder.is_url or scheme(src) != scheme(folder.display)
                        or scheme(src) in ("http", "https")):
        return None, f"{shown}: not on the output folder's storage; not fetched"
    # refused before anything is opened, fetched or hashed: a planted sidecar naming /etc/shadow,
    # a database or a key (another bucket's too) with its true hash would have it read and shown;
    # an input given by name with another extension (x.dat) loses its thumbnail, not its row
    if os.path.splitext(src)[1].lower() not in IMAGE_EXTENSIONS | RAW_EXTENSIONS:
        return None, f"{shown}: not an image file name (a JPEG, PNG, TIFF or raw extension); not opened"
    if is_url(src):
        if not want:
            return None, f"{shown}: the sidecar records no input hash; not fetched"
        if digests.of_url(src) not in (None, want):
            return None, f"{shown}: not there as it was restored (gone, or another SHA-256)"
        h = hashlib.sha256()
        try:
            f = spool(src, folder.storage_options, limit=MAX_INPUT_BYTES, digest=h)
        except FileNotFoundError:
            f = None
        except OSError as e:
            if e.errno != errno.EFBIG:
                raise
            return None, f"{shown}: larger than {MAX_INPUT_BYTES} bytes; not shown"
        if f is not None:
            digests.fetched(src, h.hexdigest())
        if f is None or h.hexdigest() != want:
            if f is not None:
                f.close()
            # one message for both: the page (written where the sidecars are) does not tell
            # whoever planted one which keys exist
            return None, f"{shown}: not there as it was restored (gone, or another SHA-256)"
        return f, None
    if not want:
        return None, f"{shown}: the sidecar records no input hash (metadata.input_sha256); not shown"
    why = "not found"
    for c in _candidates(src, folder):
        try:
            f = open_regular(c)
        except FileNotFoundError:
            continue
        except OSError as e:
            why = f"{e.strerror or e}; not opened"
            continue
        try:
            if os.fstat(f.fileno()).st_size <= MAX_INPUT_BYTES and digests.of_file(f) == want:
                f.seek(0)
                return f, None
        except OSError:
            pass
        f.close()
        why = "no file there has the SHA-256 the batch recorded"
    return None, f"{shown}: {why}"


def _open_small(f, ext: str, side: int):
    """An 8-bit RGB Pillow image of the open file ``f`` (its name's
    extension ``ext``) at most ``side`` pixels a side, decoded as cheaply
    as the format allows (JPEG: DCT scaling; raw: the embedded preview)."""
    from PIL import Image, ImageOps, UnidentifiedImageError

    if ext in RAW_EXTENSIONS:
        import rawpy

        with rawpy.imread(f) as raw:
            try:
                th = raw.extract_thumb()
            except (rawpy.LibRawNoThumbnailError, rawpy.LibRawUnsupportedThumbnailError):
                th = None
            if th is not None and th.format == rawpy.ThumbFormat.JPEG:
                im = Image.open(_io.BytesIO(th.data))
            else:
                im = Image.fromarray(raw.postprocess(half_size=True, use_camera_wb=True))
        im = ImageOps.exif_transpose(im)
    else:
        try:
            # the formats of an image's name only: a planted PostScript named .jpg would run Ghostscript
            im = Image.open(f, formats=THUMB_FORMATS)
        except UnidentifiedImageError:
            if ext not in (".tif", ".tiff"):
                raise
            # a float RGB TIFF (the renders of benches/truth.py, a linear export): Pillow cannot open it at all
            im = _from_array(f, ext)
            im.thumbnail((side, side))
            return im
        # the header's size before any pixel: a 13000 x 13000 PNG of 657 KB took 2.7 GB (JPEG decodes
        # at 1/8 a side)
        if im.width * im.height > THUMB_MAX_PIXELS * (64 if im.format == "JPEG" else 1):
            raise ValueError(f"{im.width}x{im.height} pixels: over the {THUMB_MAX_PIXELS} a thumbnail is made of")
        if im.format == "JPEG":
            im.draft("RGB", (side, side))
        im = ImageOps.exif_transpose(im)
        if im.mode not in ("RGB", "L"):
            if im.mode in ("I;16", "I;16B", "I") or im.format == "TIFF":
                im = _from_array(f, ext)
            else:
                im = im.convert("RGB")
    im.thumbnail((side, side))
    return im.convert("RGB")


def _from_array(f, ext: str):
    """16-bit or float files Pillow cannot make RGB of: through our reader
    (which takes a path: a private copy of the bytes already opened)."""
    from PIL import Image

    f.seek(0)
    with tempfile.TemporaryDirectory(prefix="uwhl-thumb-") as d:
        local = os.path.join(d, "source" + ext)
        with open(local, "xb") as out:
            for block in iter(lambda: f.read(1 << 20), b""):
                out.write(block)
        try:
            img, meta = read_image(local, max_pixels=THUMB_MAX_PIXELS)
        except Exception as e:
            # the message names the private copy, gone when this returns: the caller names the input
            msg = str(e).replace(local + ": ", "").replace(local, "the file")
            try:
                err = type(e)(msg)
            except Exception:
                err = RuntimeError(msg)
            raise err from None
    s = max(1, -(-max(img.shape[:2]) // (THUMB_SIDE * 2)))
    small = img[::s, ::s]
    return Image.fromarray((np.clip(to_srgb(small, meta), 0, 1) * 255 + 0.5).astype(np.uint8))


def _thumb(job, folder, side: int, dst_time: float | None, digests: Digests) -> str:
    """Writes one thumbnail (``job``: the photo, "in" or "out", where, when
    the photo's output was written, whether it is missing) unless one is
    there written after the output (every restore of an input rewrites it,
    so neither source is asked again for a thumbnail that is current, which
    on object storage would be a request per photo). Returns "written",
    "kept", or why not."""
    p, which, dst, made, missing = job
    if dst_time is not None and made is not None and dst_time >= made and not missing:
        return "kept"
    earlier = "; its earlier thumbnail is shown" if dst_time is not None else ""
    rel = p.output("image")
    if which == "out" and missing:
        return f"{display(folder.path(rel))}: not found{earlier}"
    try:
        if which == "in":
            f, why = _input_file(p, folder, digests)
            if f is None:
                return why + earlier
            name = p.doc["input"]
        else:
            f, name = folder.open(rel, MAX_INPUT_BYTES), rel
        with f:
            im = _open_small(f, os.path.splitext(name)[1].lower(), side)
        buf = _io.BytesIO()
        im.save(buf, "JPEG", quality=82)
    except Exception as e:  # one unreadable file leaves its cell empty (or its earlier thumbnail), never the page
        src = display(p.doc["input"] if which == "in" else folder.path(rel))
        if isinstance(e, FileNotFoundError):
            why = "not found"
        elif isinstance(e, OSError) and e.errno == errno.EFBIG:
            why = f"no thumbnail ({e.strerror})"
        else:
            why = f"no thumbnail ({type(e).__name__}: {e})"
        return f"{src}: {display(why)}{earlier}"
    folder.write(dst, buf.getvalue())
    return "written"


# ---------------------------------------------------------------- charts


def _histogram_svg(counts: dict) -> str:
    names = list(counts)
    top = max(counts.values()) if counts else 1
    bw, gap, H, top_pad = 34, 10, 150, 18
    out = [f'<svg class="hist" width="{40 + len(names) * (bw + gap)}" height="{H + top_pad + 30}" role="img" '
           'aria-label="water types">']
    for k, n in enumerate(names):
        h = H * counts[n] / top
        x = 30 + k * (bw + gap)
        out.append(f'<rect x="{x}" y="{H - h + top_pad:.1f}" width="{bw}" height="{h:.1f}" '
                   f'fill="{_TYPE_COLORS.get(n, "#777")}"><title>{_text(n)}: {counts[n]}</title></rect>')
        out.append(f'<text x="{x + bw / 2}" y="{H + top_pad + 16}" text-anchor="middle">{_text(n)}</text>')
        out.append(f'<text x="{x + bw / 2}" y="{H - h + top_pad - 4:.1f}" text-anchor="middle" class="n">'
                   f'{counts[n]}</text>')
    out.append("</svg>")
    return "".join(out)


# ---------------------------------------------------------------- the page

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:16px;background:#fafafa;color:#222}
h1{font-size:20px;margin:0 0 4px} h2{font-size:16px;margin:22px 0 8px}
.meta{color:#555} svg text{font-size:11px;fill:#333} svg .lab{font-weight:600} svg .tick{fill:#666}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(270px,1fr));gap:10px}
.cell{background:#fff;border:1px solid #ddd;border-radius:4px;padding:6px}
.cell.flagged{border:2px solid #d95f02}
.pair{display:flex;gap:3px;cursor:pointer} .pair img{width:50%;height:auto;min-height:60px;background:#ccc}
.cap{font-size:12px;margin-top:4px;word-break:break-all} .flags{color:#d95f02;font-weight:600}
.why{color:#555}
.sw{display:inline-block;width:10px;height:10px;border:1px solid #999;vertical-align:middle;margin-right:2px}
.failed td{padding:2px 8px;border-bottom:1px solid #ddd;color:#a00}
.pager button{margin:0 2px} #view{position:fixed;inset:0;background:rgba(0,0,0,.85);display:none;
padding:20px;overflow:auto;color:#eee} #view img{max-width:48%;margin:0 1%} #view a{color:#9cf}
"""

_JS = """
const D = JSON.parse(document.getElementById('data').textContent);
function cell(p){
  const flagged = p.flags.length ? ' flagged' : '';
  const A = p.A ? p.A.map(v=>Number(v).toFixed(3)).join(', ') : '';
  const sw = p.A ? p.A.map(v=>Math.round(255*Math.max(0,Math.min(1,Math.pow(Number(v),1/2.2))))||0) : [0,0,0];
  return `<div class="cell${flagged}" data-k="${Number(p.k)}"><div class="pair" onclick="show(${Number(p.k)})">`+
    `<img loading="lazy" alt="input" src="${esc(p.ti||'')}"><img loading="lazy" alt="restored" src="${esc(p.to||'')}"></div>`+
    `<div class="cap">${Number(p.k)+1}. ${esc(p.name)}<br>type <b>${esc(p.wt)}</b>, A `+
    `<span class="sw" style="background:rgb(${sw.join(',')})"></span>(${esc(A)})`+
    (p.flags.length ? `<br><span class="flags">${p.flags.map(esc).join(', ')}</span>` : '')+
    (p.why ? `<br><span class="why">distance not used: ${esc(p.why)}</span>` : '')+
    (p.plausible ? `<br>water from the distance; plausible types ${plausible(p)}` : '')+
    (balanced(p) ? `<br>colours: ${balanced(p)}` : '')+`</div></div>`;
}
// how much of the shown colour is the input's own balance (fallback_share, METHOD §12.5)
function balanced(p){
  const s = p.balance;
  if (typeof s !== 'number' || !(s >= 0.05 && s <= 1)) return '';
  return s >= D.balanced ? "the input's balance (the restoration gives the brightness)" : `${Math.round(100*s)}% the input's balance`;
}
// every type of the table plausible: the photo's content hides its water (METHOD §13.2 step 6)
function plausible(p){return p.plausible.length >= D.types ? 'any (the content hides the water)' : p.plausible.map(esc).join(', ');}
// every value of a sidecar is text to the page: escaped for HTML text and quoted attributes
function esc(s){return String(s).replace(/[&<>"']/g,c=>({'&':'&amp;','<':'&lt;','>':'&gt;','"':'&quot;',"'":'&#39;'}[c]));}
function pager(id, items){
  const el = document.getElementById(id), pages = Math.max(1, Math.ceil(items.length / D.page));
  let cur = 0;
  function draw(){
    const nav = pages > 1 ? `<div class="pager">page ${cur+1} of ${pages} `+
      `<button onclick="this.closest('section').go(${cur-1})" ${cur?'':'disabled'}>previous</button>`+
      `<button onclick="this.closest('section').go(${cur+1})" ${cur<pages-1?'':'disabled'}>next</button></div>` : '';
    el.innerHTML = nav + '<div class="grid">' +
      items.slice(cur*D.page, (cur+1)*D.page).map(k=>cell(D.photos[k])).join('') + '</div>';
  }
  el.closest('section').go = k => { cur = Math.max(0, Math.min(pages-1, k)); draw(); };
  draw();
}
function show(k){
  const p = D.photos[k], v = document.getElementById('view');
  v.innerHTML = `<p><a href="#" onclick="hide();return false">close</a> &middot; ${esc(p.name)}: `+
    `type ${esc(p.wt)}, flags ${p.flags.map(esc).join(', ')||'none'}`+
    (p.why ? ` (distance not used: ${esc(p.why)})` : '')+
    (p.plausible ? ` (water from the distance; plausible types ${plausible(p)})` : '')+
    (balanced(p) ? ` (colours: ${balanced(p)})` : '')+` &middot; `+
    (p.full ? `<a href="${esc(p.full)}">full size</a> &middot; ` : '')+
    (p.t ? `<a href="${esc(p.t)}">t map</a> &middot; ` : '')+
    `<a href="${esc(p.side)}">sidecar</a></p>`+
    (p.full ? `<img alt="restored" src="${esc(p.full)}">` : '')+
    (p.t ? `<img alt="transmission" src="${esc(p.t)}">` : '');
  v.style.display = 'block';
}
function hide(){ document.getElementById('view').style.display = 'none'; }
pager('flagged-grid', D.photos.filter(p=>p.flags.length).map(p=>p.k));
pager('all-grid', D.photos.map(p=>p.k));
"""


#: The longest reason a page shows for a distance map not used (a sidecar's text, bounded).
WHY_MAX = 300


def _plausible_types(doc) -> list[str] | None:
    """The types a photo's distance fit found plausible (the sidecar's
    ``distance.water.plausible_types``, METHOD §13.2 step 6), when its
    distance was used: the table's names only, in the table's order; None
    otherwise or when the record is not what OUTPUTS.md says."""
    w = used_water(doc)
    got = w.get("plausible_types") if w is not None else None
    if not isinstance(got, list):
        return None
    names = {t for t in got if isinstance(t, str)}
    return [t for t in uwhl_rs.WATER_TYPES if t in names] or None


def _distance_why(doc) -> str | None:
    """Why the photo's distance map was not used (the sidecar's
    ``distance.rejected``), as text of at most WHY_MAX characters; None when
    it was used, there was none, or the record is not what OUTPUTS.md says."""
    d = doc.get("distance") if isinstance(doc, dict) else None
    why = d.get("rejected") if isinstance(d, dict) else None
    if not isinstance(why, str) or not why:
        return None
    return why if len(why) <= WHY_MAX else why[:WHY_MAX - 1] + "\u2026"


def _linkable(folder, rel: str, listed: dict) -> bool:
    """Whether the page may link ``rel``: a file of the folder's listing
    and, locally, a regular file not reached through a symbolic link (a
    pipe would block the browser that opens it; a link would show a file
    from elsewhere as this folder's output)."""
    if rel not in listed:
        return False
    if folder.is_url:
        return True
    try:
        return stat.S_ISREG(os.lstat(folder.path(rel)).st_mode)
    except OSError:
        return False


def _rel_url(rel: str | None) -> str | None:
    """A relative URL from the report's folder to ``rel`` (a path relative
    to OUTDIR), so the page works wherever OUTDIR is served or copied."""
    if rel is None:
        return None
    from urllib.parse import quote

    # a relative path, every character but / percent-encoded (no scheme such as javascript: survives);
    # undecodable bytes of a name as the bytes themselves
    return quote(posixpath.relpath(rel, REPORT_DIR), safe="/", errors="surrogateescape")


def _shown(note: str | None) -> bool:
    """Whether a thumbnail is there after :func:`_thumb` said ``note``."""
    return note is not None and (note in ("written", "kept") or note.endswith("its earlier thumbnail is shown"))


class NotAnOutputFolder(UwhlError, ValueError):
    """The folder holds nothing ``uwhl restore`` writes: no page is made."""

    kind = "unreadable_input"


def write_report(out_dir, *, storage_options: dict | None = None, workers: int | None = None,
                 side: int = THUMB_SIDE, page_size: int = PAGE_SIZE) -> dict:
    """Writes ``out_dir/report/index.html`` and its thumbnails from the
    sidecars under ``out_dir`` (a local folder, or an object-storage URL
    read and written with ``storage_options``); returns what it did
    (``photos``, ``flagged``, ``thumbnails_written``, ``problems``,
    ``seconds``, ``path``). Thumbnails newer than their source are kept, so
    a rerun after more inputs only makes the new ones; the page is written
    last, in one step. Storage that cannot be reached raises
    ``BatchError``; a missing local folder, FileNotFoundError; a folder
    without a sidecar or summary.csv, :class:`NotAnOutputFolder`."""
    out_dir = os.fspath(out_dir)
    return on_storage(out_dir, lambda: _write_report(Folder(out_dir, storage_options), workers, side, page_size),
                      keep=(FileNotFoundError,))


def _write_report(folder, workers, side: int, page_size: int) -> dict:
    t0 = time.perf_counter()
    if not folder.exists():
        raise FileNotFoundError(2, "no such folder", folder.display)
    listed = folder.files()
    written_at = dict(listed)
    photos, problems = collect_sidecars(folder, listed=listed)
    if not photos and not problems and FILE_NAME not in written_at:
        # an input folder given by mistake: no page is written into it
        raise NotAnOutputFolder(f"holds no sidecar and no {FILE_NAME} of 'uwhl restore': not an output folder; "
                                "nothing written")
    videos = [p for p in photos if report_video.is_video(p)]
    photos = [p for p in photos if not report_video.is_video(p)]
    thumbs_at = dict(folder.files(under=REPORT_DIR + "/thumbs"))
    jobs, cells = [], []
    for p in photos:
        ti, to = thumb_names(p.sidecar)
        img = p.output("image")
        made = written_at.get(img, p.modified) if img else p.modified
        missing = bool(img) and img not in written_at
        # a frame of a video or a pipe has no input file of its own to show
        frame = str((p.doc.get("source") or {}).get("format") or "").startswith(("video frame", "raw "))
        jobs += [None if frame else (p, "in", ti, made, False), (p, "out", to, made, missing) if img else None]
        cells.append((p, ti, to))
    # Pillow warns on stderr about what it skips in a damaged file (corrupt EXIF, a short read); a
    # thumbnail it cannot make is a note on the page already. The filter is set once around the pool.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module=r"PIL(\.|$)")
        # the size is refused by _open_small itself, with a note on the page
        warnings.filterwarnings("ignore", message="Image size .* could be decompression bomb")
        with ThreadPoolExecutor(max_workers=workers or min(8, os.cpu_count() or 1)) as pool:
            digests = Digests()
            notes = list(pool.map(lambda j: None if j is None else _thumb(j, folder, side, thumbs_at.get(j[2]), digests),
                                  jobs))
    problems += [n for n in notes if n not in (None, "written", "kept")]
    refused: list[str] = []

    def link(rel: str | None) -> str | None:
        """The page's link to an output, when it is one the page may open."""
        if not rel:
            return None
        if _linkable(folder, rel, written_at):
            return _rel_url(rel)
        if rel in written_at:
            refused.append(f"{display(folder.path(rel))}: not a regular file (a link, a pipe or a device); not linked")
        return None
    problems = [printable(x) for x in problems]  # they quote names and sidecars' values, and go to a terminal
    written = notes.count("written")
    data = []
    counts = {t: 0 for t in uwhl_rs.WATER_TYPES}
    for k, (p, ti, to) in enumerate(cells):
        wt = p.doc["water_type"]
        counts[wt] = counts.get(wt, 0) + 1
        data.append({
            "k": k, "name": p.sidecar[:-5], "wt": wt,
            "A": p.doc.get("veiling_light"), "flags": p.flags, "why": _distance_why(p.doc),
            "plausible": _plausible_types(p.doc),
            "balance": p.doc.get("fallback_share"),
            "ti": _rel_url(ti) if _shown(notes[2 * k]) else None,
            "to": _rel_url(to) if _shown(notes[2 * k + 1]) else None,
            "full": link(p.output("image")),
            "t": link(p.output("transmission_color")),
            "side": _rel_url(p.sidecar),
        })
    for p in videos:
        counts[p.doc["water_type"]] = counts.get(p.doc["water_type"], 0) + 1
    counts = {t: n for t, n in counts.items() if n}
    flagged = sum(1 for d in data if d["flags"])
    # photos whose colour is the input's balance throughout (METHOD §12.5), as the cells say
    balanced = sum(1 for d in data if isinstance(d["balance"], (int, float))
                   and _core.BALANCED_SHARE <= d["balance"] <= 1)
    flagged_videos = [p for p in videos if report_video.needs_a_look(p)]
    failed, n_failed, summary_why = failed_inputs(folder)
    if summary_why:
        problems.append(printable(summary_why))
    more = n_failed - len(failed)
    failed_html = "" if not failed else (
        f'<section id="failed"><h2>Failed: {n_failed} (from summary.csv)</h2><table class="failed">'
        + "".join(f"<tr><td>{_text(r.get('input', ''))}</td><td>{_text(r.get('error_kind', ''))}</td>"
                  f"<td>{_text(r.get('error', ''))}</td></tr>" for r in failed)
        + "</table>" + (f'<p class="meta">and {more} more: see summary.csv</p>' if more else "") + "</section>")
    types = [t for t in uwhl_rs.WATER_TYPES] + sorted(t for t in counts if t not in uwhl_rs.WATER_TYPES)
    videos_part = report_video.videos_html(videos, types, link)
    problems += [printable(x) for x in refused]
    axis = series_axis(photos)
    page = f"""<!doctype html><html lang="en"><head><meta charset="utf-8">
<title>uwhl report: {_text(folder.name)}</title><style>{_CSS}</style></head><body>
<h1>{_text(folder.display)}</h1>
<p class="meta" id="summary">{_count(len(photos), "photo")}{f" and {_count(len(videos), 'video')}" if videos else ""} restored, {flagged + len(flagged_videos)} flagged, {n_failed} failed{f", {balanced} with the input's balance for colours" if balanced else ""}; water types:
{', '.join(f'{_text(t)} {n}' for t, n in counts.items()) or 'none'}. uwhl_rs {html.escape(uwhl_rs.__version__)},
{html.escape(time.strftime('%Y-%m-%d %H:%M'))}.</p>
{failed_html}
<section id="flagged"><h2>Needs a look: {flagged + len(flagged_videos)} flagged (fallbacks, clamps; docs/OUTPUTS.md "Flags")</h2>
{''.join(f'<p class="flags">video {_text(p.sidecar[:-5])}: {_text(", ".join(p.flags))}</p>' for p in flagged_videos)}
<div id="flagged-grid"></div></section>
<h2>Water types</h2>{_histogram_svg(counts)}
<h2>Over the sequence ({'EXIF time' if axis.by_time else 'frame index, in name order'})</h2>{series_svg(axis, types) if photos else ''}
{videos_part}
<section id="all"><h2>All photos (input | restored; click for full size and the t map)</h2><div id="all-grid"></div></section>
{''.join(f'<p class="meta">{html.escape(x)}</p>' for x in problems[:50])}
<div id="view" onclick="if(event.target===this)hide()"></div>
<script id="data" type="application/json">{script_json({"page": int(page_size), "types": len(uwhl_rs.WATER_TYPES), "balanced": _core.BALANCED_SHARE, "photos": data})}</script>
<script>{_JS}</script></body></html>
"""
    # lone surrogates (undecodable names) cannot be UTF-8: shown as U+FFFD
    path = folder.write(REPORT_DIR + "/index.html", display(page).encode("utf-8"))
    return {"path": path, "photos": len(photos), "videos": len(videos), "flagged": flagged + len(flagged_videos),
            "failed": n_failed, "thumbnails_written": written,
            "problems": problems, "seconds": time.perf_counter() - t0}


def _count(n: int, noun: str) -> str:
    """``n`` and ``noun``, plural unless one."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _text(s: str) -> str:
    """A value as the page's HTML text, as the console shows it (:func:`printable`)."""
    return html.escape(printable(s))


def _shown_text(value):
    """``value`` with each string (keys too) as the page shows it, as the
    console does (:func:`printable`): the bytes of a name that are not
    UTF-8 (lone surrogates here, which JSON would carry to the page as
    ``\\udcXX``) as U+FFFD, control and bidirectional characters as
    visible escapes, so that a name cannot reorder the text around it."""
    if isinstance(value, str):
        return printable(value)
    if isinstance(value, dict):
        return {(printable(k) if isinstance(k, str) else k): _shown_text(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_shown_text(v) for v in value]
    return value


def script_json(value) -> str:
    """``value`` as JSON that is inert inside a ``<script>`` element: no
    ``<``, ``>`` or ``&`` (so no ``</script>`` or ``<!--`` can end or
    swallow the element) and no U+2028/U+2029, each written as its
    ``\\u`` escape, which JSON.parse reads back as the same text."""
    text = json.dumps(_shown_text(value), ensure_ascii=True, allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
