"""``uwhl report`` and ``uwhl ifdo`` over an output folder someone else
could have written (issue 30, "The report and the iFDO trust their
sidecars" and "Writes that go through links"): markup in any field is text
on the page, a sidecar cannot make either command fetch a URL, open a FIFO
or device or show a file the batch did not restore, ~40 malformed sidecars
are one line each and the rest is written, the iFDO refuses what its
schema refuses, YAML headers cannot expand, thumbnails never share names
or replace outputs, and links planted at the temporaries are not written
through.

Every hostile file is made here. The subprocess timeouts are guards
against a hang (the old code hung on a FIFO), not measurements."""

from __future__ import annotations

import hashlib
import html.parser
import http.server
import json
import os
import shutil
import subprocess
import sys
import threading

import numpy as np
import pytest
import yaml
from PIL import Image

from test_ifdo import HEADER, POSITION, validator
from test_metadata import _gps_exif, _scene

GUARD = 120  # seconds: only so that a hang fails the test instead of holding the suite


def uwhl(*args, cwd=None, timeout=GUARD):
    # stdin stays an open pipe nobody writes: a command that read /dev/stdin would wait on it
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, stdin=subprocess.PIPE, env=dict(os.environ))


def _sha(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def _make_inputs(d, names_seeds):
    for name, seed in names_seeds:
        p = d / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith(".jpg"):
            Image.fromarray(_scene(60, 80, seed=seed)).save(p, quality=90, exif=_gps_exif())
        else:
            Image.fromarray(_scene(60, 80, seed=seed)).save(p)


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """A restored batch with relative inputs (run from its folder): every
    photo has GPS (the iFDO needs it) and a recorded input hash."""
    d = tmp_path_factory.mktemp("batch")
    _make_inputs(d / "in", [("f000.jpg", 1), ("f001.jpg", 2), ("f002.jpg", 3)])
    r = uwhl("restore", "in", "-o", "out", "-q", cwd=d, timeout=600)
    assert r.returncode == 0, r.stderr
    return d


def _copy(batch, tmp_path):
    """The batch's folder (inputs and outputs) copied, so each test may spoil its own."""
    shutil.copytree(batch / "in", tmp_path / "in")
    shutil.copytree(batch / "out", tmp_path / "out")
    return tmp_path / "out"


def _header(tmp_path, fields=None, name="header.yaml"):
    p = tmp_path / name
    fields = {**HEADER, **POSITION} if fields is None else fields
    p.write_text(json.dumps(fields) if name.endswith(".json") else yaml.safe_dump(fields))
    return p


def _page_data(page: str) -> dict:
    start = page.index('<script id="data" type="application/json">') + len('<script id="data" type="application/json">')
    return json.loads(page[start:page.index("</script>", start)])


class _Elements(html.parser.HTMLParser):
    """Every element of a page: (tag, attributes), and the text of each script."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.elements, self.scripts, self._in_script = [], [], False

    def handle_starttag(self, tag, attrs):
        self.elements.append((tag, dict(attrs)))
        if tag == "script":
            self._in_script = True
            self.scripts.append("")

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts[-1] += data


def _elements(page: str) -> _Elements:
    p = _Elements()
    p.feed(page)
    p.close()
    return p


# ------------------------------------------------------------------ 1. markup is text

MARKUP = "<img src=x onerror=alert(1)>"


def test_markup_in_sidecars_names_and_custom_types_stays_text(tmp_path):
    _make_inputs(tmp_path / "in", [("<!--<script>.png", 4), ("plain.png", 5)])
    out = tmp_path / "out"
    # a custom water type named as markup, given on the command line
    r = uwhl("restore", tmp_path / "in", "-o", out, "-q", "--water-type", f"{MARKUP}:0.7:1.1", timeout=600)
    assert r.returncode == 0, r.stderr
    side = out / "plain.json"
    doc = json.loads(side.read_text())
    assert doc["water_type"] == MARKUP
    # markup in the flags, and the characters that end or swallow a script element, or a JS line
    flags = ["</script><script>document.title='pwned'</script>", "<b onmouseover=alert(2)>x</b>",
             "a\u2028b\u2029c & <!-- -->", "\"' onfocus=alert(3) x='"]
    doc["flags"] = flags
    # the reason a distance map was not used is shown: markup in it stays text, and a long one is cut
    why = "</script><img src=x onerror=alert(4)> " + "w" * 400
    doc["distance"] = {"used": False, "rejected": why}
    side.write_text(json.dumps(doc))
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    page = (out / "report" / "index.html").read_text(encoding="utf-8")
    found = _elements(page)
    tags = {t for t, _ in found.elements}
    # the page is made of the template's elements only: nothing from a sidecar became one
    assert tags <= {"html", "head", "meta", "title", "style", "body", "h1", "p", "section", "h2", "div", "svg",
                    "rect", "text", "polyline", "script", "table", "tr", "td"}, tags
    handlers = [(t, a) for t, a in found.elements for k in a if k.startswith("on")]
    assert handlers == [("div", {"id": "view", "onclick": "if(event.target===this)hide()"})], handlers
    assert len(found.scripts) == 2, "the data and the code are two whole script elements"
    data_text = found.scripts[0]
    for c in "<>&\u2028\u2029":
        assert c not in data_text, f"{c!r} inside the embedded JSON"
    data = json.loads(data_text)
    by_name = {p["name"]: p for p in data["photos"]}
    # the JSON reads back as the sidecars' strings as the console shows them (markup kept as text; the
    # line and paragraph separators as visible escapes, which also keep a name from reordering its line)
    assert set(by_name) == {"<!--<script>", "plain"}
    shown = [f.replace("\u2028", "\\u2028").replace("\u2029", "\\u2029") for f in flags]
    assert by_name["plain"]["wt"] == MARKUP and by_name["plain"]["flags"] == shown
    assert by_name["plain"]["why"] == why[:299] + "\u2026"
    assert by_name["<!--<script>"]["why"] is None
    assert by_name["<!--<script>"]["wt"] == MARKUP
    # the histogram names the custom type as text
    assert "&lt;img src=x onerror=alert(1)&gt;" in page

    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        return  # the static checks above are the test; the browser one is a bonus where there is one
    from test_report_browser import _run

    dom = _run(browser, "--dump-dom", (out / "report" / "index.html").resolve().as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    rendered = _elements(dom.stdout)
    imgs = [a for t, a in rendered.elements if t == "img"]
    # both photos drawn in the grid of all and the flagged one in the first grid too (the name did not
    # swallow the script), each image with the template's attributes only
    assert len(imgs) == 2 * (2 + 1) and all(set(a) <= {"loading", "alt", "src"} for a in imgs), imgs
    assert not [t for t, a in rendered.elements if t in ("b", "script") and a.get("onmouseover")]
    title = dom.stdout[dom.stdout.index("<title>") + 7:dom.stdout.index("</title>")]
    assert title == "uwhl report: out"


# ------------------------------------------------------------------ 2. no request, no read not asked for


class _Recorder(http.server.BaseHTTPRequestHandler):
    hits: list = []

    def do_GET(self):  # noqa: N802 (the http.server name)
        type(self).hits.append(self.path)
        self.send_response(404)
        self.end_headers()

    def log_message(self, *a):
        pass


@pytest.fixture
def http_server():
    _Recorder.hits = []
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Recorder)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    yield srv
    srv.shutdown()
    srv.server_close()


def test_a_fits_plausible_types_are_shown_as_the_tables_names_only(tmp_path):
    """METHOD §13.2 step 6: the page lists the types a used distance fit
    found plausible; a sidecar's other strings, markup and numbers there are
    dropped, and a photo whose distance was not used lists none."""
    _make_inputs(tmp_path / "in", [("a.png", 4), ("b.png", 5)])
    out = tmp_path / "out"
    r = uwhl("restore", tmp_path / "in", "-o", out, "-q", timeout=600)
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "a.json").read_text())
    doc["distance"] = {"used": True, "water": {"plausible_types": ["3C", MARKUP, "II", 5, "3C", None]}}
    (out / "a.json").write_text(json.dumps(doc))
    doc = json.loads((out / "b.json").read_text())
    doc["distance"] = {"used": False, "rejected": "no", "water": {"plausible_types": ["II"]}}
    (out / "b.json").write_text(json.dumps(doc))
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    page = (out / "report" / "index.html").read_text(encoding="utf-8")
    data = json.loads(_elements(page).scripts[0])
    by_name = {p["name"]: p for p in data["photos"]}
    assert by_name["a"]["plausible"] == ["II", "3C"]
    assert by_name["b"]["plausible"] is None


def test_a_url_in_a_sidecar_is_never_fetched(batch, tmp_path, http_server):
    out = _copy(batch, tmp_path)
    port = http_server.server_address[1]
    for name in ("f000", "f001"):
        doc = json.loads((out / f"{name}.json").read_text())
        doc["input"] = f"http://127.0.0.1:{port}/{name}.jpg"  # an internal address is asked the same way
        (out / f"{name}.json").write_text(json.dumps(doc))
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert _Recorder.hits == [], "the report asked a server the user did not name"
    assert sum("not fetched" in line for line in r.stdout.splitlines()) == 2, r.stdout


def test_sidecars_cannot_make_the_report_fetch_open_fifos_or_show_other_files(batch, tmp_path, http_server):
    out = _copy(batch, tmp_path)
    fifo = tmp_path / "pipe.jpg"
    os.mkfifo(fifo)
    secret = tmp_path / "secret.png"
    Image.fromarray(_scene(60, 80, seed=9)).save(secret)
    base = json.loads((out / "f000.json").read_text())
    port = http_server.server_address[1]
    planted = {
        "f000": f"http://127.0.0.1:{port}/f000.jpg",
        "f001": str(fifo),
        "f002": "/dev/stdin",
        "g003": "/dev/zero",
        "g004": str(secret),  # a real image outside the batch, not the one the batch restored
    }
    for name, src in planted.items():
        doc = dict(base, input=src, outputs={k: v.replace("f000", name) for k, v in base["outputs"].items()})
        if name.startswith("g"):
            doc["outputs"] = {"image": f"{name}.jpg" if name == "g004" else "f000.jpg"}
        (out / f"{name}.json").write_text(json.dumps(doc))
    # g003 names f000.jpg, another sidecar's output: left out whole, not shown as a photo
    del planted["g003"]
    os.mkfifo(out / "g004.jpg")  # an output that is a FIFO
    os.symlink(secret, out / "g005.jpg")  # an output that is a link to a file outside
    os.mkfifo(out / "g005_t_color.png")
    doc = dict(base, outputs={"image": "g005.jpg", "transmission_color": "g005_t_color.png"})
    (out / "g005.json").write_text(json.dumps(doc))
    planted["g005"] = base["input"]
    os.mkfifo(out / "zz.json")  # a sidecar that is a FIFO
    os.remove(out / "summary.csv")
    os.mkfifo(out / "summary.csv")
    os.mkfifo(out / "ifdo.yaml")  # an earlier iFDO that is a FIFO
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert _Recorder.hits == [], "the report asked a server the user did not name"
    data = _page_data((out / "report" / "index.html").read_text())
    ti = {p["name"]: p["ti"] for p in data["photos"]}
    assert set(ti) == set(planted), ti
    assert all(v is None for k, v in ti.items() if k != "g005"), ti  # none of these is the batch's input
    # the page links no output the report would not open itself: a click on a FIFO would block the
    # browser, a link would show a file from outside as the batch's
    links = {p["name"]: (p["full"], p["t"]) for p in data["photos"]}
    assert links["g004"][0] is None and links["g005"] == (None, None), links
    assert links["f001"][0] == "../f000.jpg" or links["f001"][0].endswith("f001.jpg"), links
    attrs = [v for _, a in _elements((out / "report" / "index.html").read_text()).elements for v in a.values()]
    assert not any(v and ("g004.jpg" in v or "g005" in v) for v in attrs), attrs
    assert "g005.jpg: not a regular file" in r.stdout and "g004.jpg: not a regular file" in r.stdout, r.stdout
    assert "g003.json: not a usable sidecar: outputs.image is 'f000.jpg', not an output of its own name" \
        in r.stdout, r.stdout
    assert any("zz.json" in line for line in r.stdout.splitlines())
    # the iFDO over the same folder: no hang on the FIFO sidecar, summary or earlier file
    r = uwhl("ifdo", out, "--header", _header(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    assert _Recorder.hits == []
    assert (out / "ifdo.yaml").is_file()
    validator().validate(yaml.safe_load((out / "ifdo.yaml").read_text()))


# ------------------------------------------------------------------ 3. malformed sidecars


def _shapes() -> dict:
    """name -> a function of the valid sidecar's text giving the bytes of a malformed one."""

    def edit(**fields):
        def f(text):
            d = json.loads(text)
            for k, v in fields.items():
                if "." in k:
                    top, sub = k.split(".", 1)
                    inner = d[top]
                    for part in sub.split(".")[:-1]:
                        inner = inner[part]
                    inner[sub.split(".")[-1]] = v
                else:
                    d[k] = v
            return json.dumps(d).encode()
        return f

    def drop(key):
        def f(text):
            d = json.loads(text)
            del d[key]
            return json.dumps(d).encode()
        return f

    def raw(fn):
        return fn

    def number_text(key, value, text):
        # a number no JSON writer of ours emits, put in as text: 0.123456789 marks where
        def f(t):
            return json.dumps(dict(json.loads(t), **{key: value})).replace("0.123456789", text, 1).encode()
        return f

    return {
        "A_strings": edit(veiling_light=["0.1", "0.2", "0.3"]),
        "A_length_2": edit(veiling_light=[0.1, 0.2]),
        "A_null": edit(veiling_light=None),
        "A_nan": number_text("veiling_light", [0.123456789, 0.2, 0.3], "NaN"),
        "A_1e400": number_text("veiling_light", [0.123456789, 0.2, 0.3], "1e400"),
        "water_type_list": edit(water_type=["II"]),
        "water_type_null": edit(water_type=None),
        "water_type_number": edit(water_type=3),
        "water_type_empty": edit(water_type=""),
        "scores_string": edit(scores="low"),
        "scores_value_text": edit(scores={"II": "x"}),
        "flags_string": edit(flags="veiling_fallback"),
        "flags_numbers": edit(flags=[1, 2]),
        "taken_at_number": edit(**{"metadata.taken_at": 20261130}),
        "taken_at_words": edit(**{"metadata.taken_at": "yesterday"}),
        "seconds_1e400": number_text("seconds", {"total": 0.123456789}, "1e400"),
        "seconds_text": edit(seconds="fast"),
        "seconds_infinity": raw(lambda t: json.dumps(dict(json.loads(t), seconds={"total": float("inf")})).encode()),
        "nested_100000": raw(lambda t: (t.rstrip().rstrip("}") + ', "deep": ' + "[" * 100000 + "]" * 100000
                                        + "}").encode()),
        "nested_objects_100000": raw(lambda t: (t.rstrip().rstrip("}") + ', "deep": ' + '{"a":' * 100000 + "1"
                                                + "}" * 100000 + "}").encode()),
        "non_utf8": raw(lambda t: t.replace('"water_type": "', '"water_type": "\xff', 1).encode("latin-1")),
        "bom": raw(lambda t: b"\xef\xbb\xbf" + t.encode()),
        "huge_file": raw(lambda t: json.dumps(dict(json.loads(t), padding="x" * (6 << 20))).encode()),
        "huge_integer": number_text("vl_pixels", 0.123456789, "9" * 5000),
        "not_an_object_list": raw(lambda t: b"[1, 2, 3]"),
        "not_an_object_text": raw(lambda t: b'"a sidecar"'),
        "not_an_object_null": raw(lambda t: b"null"),
        "not_json": raw(lambda t: t[: len(t) // 2].encode()),
        "empty": raw(lambda t: b""),
        "outputs_string": edit(outputs="f001.jpg"),
        "outputs_parent": edit(**{"outputs.image": "../../../etc/passwd"}),
        "outputs_absolute": edit(**{"outputs.image": "/etc/passwd"}),
        "input_number": edit(input=17),
        "input_missing": drop("input"),
        "metadata_list": edit(metadata=[1, 2]),
        "latitude_1000": edit(**{"metadata.gps": {"latitude": 1000.0, "longitude": 10.0, "altitude": None}}),
        "gps_text": edit(**{"metadata.gps": "north"}),
        "uuid_malformed": edit(**{"metadata.image_uuid": "not-a-uuid"}),
        "sha_number": edit(**{"metadata.photo_sha256": 123}),
        "beta_ratios_3": edit(beta_ratios=[1.0, 1.0, 1.0]),
        "source_height_text": edit(**{"source.height": "big"}),
    }


SHAPES = _shapes()


@pytest.fixture(scope="module")
def spoilt(batch, tmp_path_factory):
    """For each shape, a copy of the batch whose f001.json has that shape."""
    made = {}

    def get(shape):
        if shape not in made:
            d = tmp_path_factory.mktemp(f"shape_{shape}")
            out = _copy(batch, d)
            (out / "f001.json").write_bytes(SHAPES[shape]((out / "f001.json").read_text()))
            made[shape] = out
        return made[shape]
    return get


def _one_line_about_f001(text: str) -> list[str]:
    return [line for line in text.splitlines() if "f001.json" in line]


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_a_malformed_sidecar_is_one_line_and_the_page_is_made(spoilt, shape):
    out = spoilt(shape)
    r = uwhl("report", out)
    assert "Traceback" not in r.stdout + r.stderr, r.stderr
    assert r.returncode == 0, r.stdout + r.stderr
    assert "(2 photos," in r.stdout, r.stdout
    lines = _one_line_about_f001(r.stdout)
    assert len(lines) == 1 and "note:" in lines[0], r.stdout
    names = [p["name"] for p in _page_data((out / "report" / "index.html").read_text())["photos"]]
    assert names == ["f000", "f002"]


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_a_malformed_sidecar_is_one_line_and_the_ifdo_is_made(spoilt, shape, tmp_path):
    out = spoilt(shape)
    r = uwhl("ifdo", out, "--header", _header(tmp_path))
    assert "Traceback" not in r.stdout + r.stderr, r.stderr
    assert r.returncode == 0, r.stdout + r.stderr
    assert "(2 photos)" in r.stdout, r.stdout
    lines = _one_line_about_f001(r.stdout)
    assert len(lines) == 1 and "note:" in lines[0], r.stdout
    doc = yaml.safe_load((out / "ifdo.yaml").read_text())
    assert sorted(doc["image-set-items"]) == ["f000.jpg", "f002.jpg"]
    assert _all_finite(doc)
    validator().validate(doc)


# ------------------------------------------------------------------ 4. the iFDO


def _all_finite(v) -> bool:
    if isinstance(v, float):
        return bool(np.isfinite(v))
    if isinstance(v, dict):
        return all(_all_finite(x) for x in v.values())
    if isinstance(v, list):
        return all(_all_finite(x) for x in v)
    return True


@pytest.mark.parametrize("field,value", [
    ("image-latitude", 1000), ("image-latitude", "north"), ("image-longitude", float("nan")),
    ("image-set-uuid", "1234-not-a-uuid"), ("image-coordinate-uncertainty-meters", -1),
    ("image-acquisition", "painting"), ("image-datetime", 5),
])
def test_header_values_the_schema_refuses_are_refused_with_the_field_named(batch, tmp_path, field, value):
    out = _copy(batch, tmp_path)
    p = tmp_path / "header.json"
    p.write_text(json.dumps({**HEADER, **POSITION, field: value}))  # JSON: NaN as the writer of a file may put it
    r = uwhl("ifdo", out, "--header", p)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 2 and field in r.stderr, r.stdout + r.stderr
    assert not (out / "ifdo.json").exists()


def test_items_never_leave_the_folder_and_positions_are_finite(batch, tmp_path):
    out = _copy(batch, tmp_path)
    doc = json.loads((out / "f001.json").read_text())
    for k, image in enumerate(["../../../etc/passwd", "/etc/passwd", "sub/../../x.jpg"]):
        (out / f"h{k}.json").write_text(json.dumps({**doc, "outputs": {**doc["outputs"], "image": image}}))
    text = (out / "f002.json").read_text()
    (out / "f002.json").write_text(text.replace('"latitude": ', '"latitude": NaN, "x": ', 1))
    r = uwhl("ifdo", out, "--header", _header(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    written = (out / "ifdo.yaml").read_text()
    items = yaml.safe_load(written)["image-set-items"]
    assert sorted(items) == ["f000.jpg", "f001.jpg"], sorted(items)
    assert _all_finite(yaml.safe_load(written))
    for k in range(3):
        assert any(f"h{k}.json" in line for line in r.stdout.splitlines()), r.stdout


def _yaml_bomb(levels=9):
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("kind", ["billion_laughs", "recursive_alias", "deep_nesting", "fifo", "huge", "non_utf8",
                                  "date_value", "devnull_link", "huge_integer", "python_tag"])
def test_hostile_header_files_are_refused_without_hanging(batch, tmp_path, kind):
    out = _copy(batch, tmp_path)
    p = tmp_path / "header.yaml"
    plain = yaml.safe_dump({**HEADER, **POSITION})
    if kind == "billion_laughs":
        p.write_text(plain + _yaml_bomb())
    elif kind == "recursive_alias":
        p.write_text(plain + "loop: &loop [*loop]\n")
    elif kind == "deep_nesting":
        p.write_text(plain + "deep: " + "[" * 10000 + "]" * 10000 + "\n")
    elif kind == "fifo":
        os.mkfifo(p)
    elif kind == "huge":
        p.write_text(plain + "pad: " + "x" * (2 << 20) + "\n")
    elif kind == "non_utf8":
        p.write_bytes(plain.encode() + b"note: \xff\xfe\n")
    elif kind == "date_value":
        p.write_text(plain + "image-set-related-date: 2026-11-30\n")
    elif kind == "huge_integer":
        p.write_text(plain + "count: " + "9" * 5000 + "\n")
    elif kind == "python_tag":
        p.write_text(plain + "x: !!python/object/apply:os.system ['true']\n")
    else:
        os.symlink("/dev/zero", p)
    r = uwhl("ifdo", out, "--header", p)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 2, r.stdout + r.stderr
    want = {"billion_laughs": "aliases", "recursive_alias": "aliases", "deep_nesting": "nested deeper",
            "fifo": "not a regular file", "huge": "larger than", "non_utf8": "not UTF-8",
            "date_value": "image-set-related-date", "devnull_link": "not a regular file",
            "huge_integer": "cannot be read", "python_tag": "not YAML"}[kind]
    assert want in r.stderr, r.stderr
    assert not (out / "ifdo.yaml").exists()


def test_two_sidecars_naming_one_photo_give_one_item(batch, tmp_path):
    out = _copy(batch, tmp_path)
    shutil.copy(out / "f000.json", out / "copy_of_f000.json")
    r = uwhl("ifdo", out, "--header", _header(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    doc = yaml.safe_load((out / "ifdo.yaml").read_text())
    assert sorted(doc["image-set-items"]) == ["f000.jpg", "f001.jpg", "f002.jpg"]
    names = [e["name"] for e in doc["image-set-header"]["image-set-provenance"]["provenance-entities"]]
    assert sorted(names) == ["f000.jpg", "f001.jpg", "f002.jpg"]
    # the copy names f000.jpg, not an output of its own name: planted, left out whole
    assert "copy_of_f000.json: not a usable sidecar: outputs.image is 'f000.jpg', not an output of its own name" \
        in r.stdout, r.stdout


def test_a_large_ifdo_json_of_the_folder_is_no_sidecar(batch, tmp_path):
    out = _copy(batch, tmp_path)
    r = uwhl("ifdo", out, "--header", _header(tmp_path, name="h.json"), "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads((out / "ifdo.json").read_text())
    doc["image-set-header"]["image-abstract"] = "x" * (2 << 20)  # a big batch's file is this large
    (out / "ifdo.json").write_text(json.dumps(doc))
    r = uwhl("report", out)
    assert r.returncode == 0 and "(3 photos," in r.stdout and "ifdo.json" not in r.stdout, r.stdout


def test_notes_quoting_names_and_sidecars_cannot_drive_the_terminal(batch, tmp_path):
    out = _copy(batch, tmp_path)
    (out / "\x1b[2J\x1b[31mred.json").write_text("{ not json")
    doc = json.loads((out / "f001.json").read_text())
    doc["input"] = "in/\x1b]0;title\x07f001.jpg"
    (out / "f001.json").write_text(json.dumps(doc))
    for r in (uwhl("report", out), uwhl("ifdo", out, "--header", _header(tmp_path))):
        assert r.returncode == 0, r.stdout + r.stderr
        assert "\x1b" not in r.stdout + r.stderr and "\x07" not in r.stdout + r.stderr
    assert "\\x1b[31mred.json" in uwhl("report", out).stdout


# ------------------------------------------------------------------ 5. thumbnails


def _thumb_of(out, page_url_rel):
    return np.asarray(Image.open(out / "report" / page_url_rel).convert("RGB"), dtype=float)


def _small(path, like):
    im = Image.open(path).convert("RGB").resize((like.shape[1], like.shape[0]))
    return np.asarray(im, dtype=float)


def test_thumbnails_of_a_b_and_a__b_are_their_own(tmp_path):
    _make_inputs(tmp_path / "in", [("a/b.png", 11), ("a__b.png", 12)])
    # distinct photos: one much darker
    im = Image.open(tmp_path / "in" / "a__b.png")
    Image.eval(im, lambda v: v // 4).save(tmp_path / "in" / "a__b.png")
    out = tmp_path / "out"
    r = uwhl("restore", tmp_path / "in", "-o", out, "-q", timeout=600)
    assert r.returncode == 0, r.stderr
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    photos = {p["name"]: p for p in _page_data((out / "report" / "index.html").read_text())["photos"]}
    assert photos["a/b"]["ti"] != photos["a__b"]["ti"] and photos["a/b"]["to"] != photos["a__b"]["to"]
    for name, src in (("a/b", "a/b.png"), ("a__b", "a__b.png")):
        t = _thumb_of(out, photos[name]["ti"])
        mine = np.abs(t - _small(tmp_path / "in" / src, t)).mean()
        other = np.abs(t - _small(tmp_path / "in" / ("a__b.png" if name == "a/b" else "a/b.png"), t)).mean()
        assert mine < other, (name, mine, other)


def test_a_relative_input_is_the_batchs_own_from_another_directory(batch, tmp_path):
    out = _copy(batch, tmp_path / "here")
    # another folder with inputs of the same names but other pictures
    elsewhere = tmp_path / "elsewhere"
    _make_inputs(elsewhere / "in", [("f000.jpg", 21), ("f001.jpg", 22), ("f002.jpg", 23)])
    os.remove(tmp_path / "here" / "in" / "f002.jpg")  # this one is gone
    r = uwhl("report", out, cwd=elsewhere)
    assert r.returncode == 0, r.stdout + r.stderr
    photos = {p["name"]: p for p in _page_data((out / "report" / "index.html").read_text())["photos"]}
    for name in ("f000", "f001"):
        t = _thumb_of(out, photos[name]["ti"])
        mine = np.abs(t - _small(tmp_path / "here" / "in" / f"{name}.jpg", t)).mean()
        decoy = np.abs(t - _small(elsewhere / "in" / f"{name}.jpg", t)).mean()
        assert mine < decoy, (name, mine, decoy)
    assert photos["f002"]["ti"] is None
    assert any("in/f002.jpg" in line for line in r.stdout.splitlines()), r.stdout


def test_an_input_folder_named_report_keeps_its_photos_and_outputs(tmp_path):
    # Z.png's thumbnail once went to report/thumbs/Z_in.jpg: the output of report/thumbs/Z_in.png
    _make_inputs(tmp_path / "in", [("Z.png", 31), ("report/thumbs/Z_in.png", 32), ("report/index.png", 33)])
    out = tmp_path / "out"
    r = uwhl("restore", tmp_path / "in", "-o", out, "-q", timeout=600)
    assert r.returncode == 0, r.stderr
    before = {p: _sha(out / p) for p in ("report/thumbs/Z_in.jpg", "report/index.jpg", "report/thumbs/Z_in.json")}
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "(3 photos," in r.stdout, r.stdout
    assert {p: _sha(out / p) for p in before} == before
    names = sorted(p["name"] for p in _page_data((out / "report" / "index.html").read_text())["photos"])
    assert names == ["Z", "report/index", "report/thumbs/Z_in"]


# ------------------------------------------------------------------ 6. links at the temporaries


def _plant(links_dir, names, victim):
    links_dir.mkdir(parents=True, exist_ok=True)
    for n in names:
        os.symlink(victim, links_dir / n)


def test_links_planted_at_the_temporaries_are_not_written_through(batch, tmp_path):
    from uwhl_rs import ifdo, report

    out = _copy(batch, tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    pid = os.getpid()  # the temporaries' names have the writer's process id: this one writes
    old_thumbs = [f"{s}_{w}.jpg" for s in ("f000", "f001", "f002") for w in ("in", "out")]
    _plant(out / "report", [f".index.html.{pid}.tmp"] + [f".uwhl-{pid}-{n}.tmp.html" for n in range(300)], victim)
    _plant(out / "report" / "thumbs", [f".{t}.{pid}.tmp" for t in old_thumbs]
           + [f".uwhl-{pid}-{n}.tmp.jpeg" for n in range(300)] + [f".uwhl-{pid}-{n}.tmp.jpg" for n in range(300)],
           victim)
    _plant(out, [f".ifdo.yaml.{pid}.tmp"] + [f".uwhl-{pid}-{n}.tmp.yaml" for n in range(300)], victim)
    done = report.write_report(str(out))
    assert done["photos"] == 3
    ifdo.write_ifdo(str(out), {**HEADER, **POSITION})
    assert victim.read_text() == "keep me"
    data = _page_data((out / "report" / "index.html").read_text())
    made = [out / "report" / p[k] for p in data["photos"] for k in ("ti", "to") if p[k]]
    assert len(made) >= 3
    for p in [out / "report" / "index.html", out / "ifdo.yaml"] + made:
        assert p.is_file() and not p.is_symlink(), p


def test_a_linked_report_folder_is_not_written_through(batch, tmp_path):
    out = _copy(batch, tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    os.symlink(elsewhere, out / "report")
    r = uwhl("report", out)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode != 0 and "report" in r.stderr, r.stdout + r.stderr
    assert os.listdir(elsewhere) == []


def test_the_fitted_blue_attenuation_is_drawn_from_what_a_fit_writes_only(tmp_path):
    """The sequence's fourth panel (METHOD §13.2 step 6): the blue
    attenuation of each photo whose distance was used, with a bar over its
    plausible range; a record that is not what a fit writes (a beta outside
    its own range, lo > hi, strings, a huge or negative value, the distance
    not used) draws nothing, and without any fit there is no panel."""
    from uwhl_rs import report_series

    good = {"used": True, "water": {"beta": [0.3, 0.1, 0.05], "beta_range": [[0.2, 0.4], [0.05, 0.2], [0.03, 0.08]]}}
    assert report_series.fitted_blue({"distance": good}) == (0.05, 0.03, 0.08)
    bad = [
        {"used": False, "water": good["water"]},
        {"used": "true", "water": good["water"]},
        {"used": True, "water": {"beta": [0.3, 0.1, 0.5], "beta_range": good["water"]["beta_range"]}},
        {"used": True, "water": {"beta": [0.3, 0.1, 0.05], "beta_range": [[0, 1], [0, 1], [0.08, 0.03]]}},
        {"used": True, "water": {"beta": [0.3, 0.1, "x"], "beta_range": good["water"]["beta_range"]}},
        {"used": True, "water": {"beta": [0.3, 0.1, 0.05], "beta_range": [[0, 1], [0, 1], [-1, 1e300]]}},
        {"used": True, "water": {"beta": [0.3, 0.1, 0.05], "beta_range": {"2": [0.03, 0.08]}}},
        {"used": True, "water": MARKUP},
        None,
    ]
    for d in bad:
        assert report_series.fitted_blue({"distance": d}) is None, d
    _make_inputs(tmp_path / "in", [(f"p{k}.png", k + 3) for k in range(4)])
    out = tmp_path / "out"
    r = uwhl("restore", tmp_path / "in", "-o", out, "-q", timeout=600)
    assert r.returncode == 0, r.stderr
    page = lambda: (out / "report" / "index.html").read_text(encoding="utf-8")  # noqa: E731
    assert uwhl("report", out).returncode == 0 and "blue attenuation fitted" not in page()
    for k, d in enumerate([good, bad[2], good, bad[5]]):
        doc = json.loads((out / f"p{k}.json").read_text())
        doc["distance"] = d
        (out / f"p{k}.json").write_text(json.dumps(doc))
    r = uwhl("report", out)
    assert r.returncode == 0, r.stdout + r.stderr
    series = page()[page().index('class="series"'):]
    series = series[:series.index("</svg>")]
    assert "blue attenuation fitted from the distance" in series
    assert series.count("<line ") == 2  # one range bar for each of the two records a fit writes


def test_a_summary_line_too_long_to_be_a_row_ends_its_reading(tmp_path):
    """summary.csv is read a line at a time (docs/REPORT.md): a line of
    more than a mebibyte, or a field past csv's limit, is no summary of
    ours and is not held whole; the rows of a sound one are all counted,
    and those before a bad line are kept, with where the reading stopped."""
    from uwhl_rs import outdir

    head = "input,status,error\n"
    (tmp_path / "summary.csv").write_text(head + "a.png,failed,x\nb.png,done,\nc.png,failed,y\n")
    rows, total, why = outdir.failed_inputs(str(tmp_path))
    assert total == 2 and [r["input"] for r in rows] == ["a.png", "c.png"] and why is None
    for junk in ("d.png,failed," + "z" * (outdir.LINE_MAX + 10) + "\n",
                 'd.png,failed,"' + "z\n" * 100_000 + '"\n'):
        (tmp_path / "summary.csv").write_text(head + "a.png,failed,x\n" + junk)
        rows, total, why = outdir.failed_inputs(str(tmp_path))
        assert total == 1 and [r["input"] for r in rows] == ["a.png"] and "not read from row 2 on" in why, why


def test_control_and_bidi_characters_of_a_water_type_are_escaped_on_the_page(batch, tmp_path):
    """docs/REPORT.md: text from a sidecar is shown as the console shows it,
    \\xNN and \\uNNNN, so a name cannot reorder the page around it; the
    water type too, in the summary line, the histogram and the series."""
    out = _copy(batch, tmp_path)
    side = sorted(out.glob("*.json"))[0]
    doc = json.loads(side.read_text())
    bad = "\u202eIII\u0007\u001b[31m"
    doc["scores"] = {bad if k == doc["water_type"] else k: v for k, v in doc["scores"].items()}
    doc["water_type"] = bad
    side.write_text(json.dumps(doc))
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    page = (out / "report" / "index.html").read_text()
    assert not any(c in page for c in "\u202e\u0007\u001b"), [c for c in "\u202e\u0007\u001b" if c in page]
    assert "\\u202eIII\\x07\\x1b[31m" in page
