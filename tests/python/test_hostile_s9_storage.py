"""Hostile inputs of the ninth pass on object storage: an output folder
holding objects far larger than anything the readers take (a 400 MB
"sidecar", a sidecar whose ``input`` names a 400 MB object), storage
options that are malformed rather than a store that cannot be reached,
and names that ``restore`` writes but its readers refused (a backslash, a
name too long for the output's staging folder).

What must happen is known without the code: a reader asks the store for
at most its limit plus one byte of an object (counted here by a fake
fsspec filesystem that serves every byte it is asked for, and may lie
about sizes); a bad option is a bad argument (exit 2, docs/CLI.md) naming
the option, and an unreachable store stays exit 7; a photo ``restore``
wrote is one ``report`` and ``ifdo`` show; a name too long for the
output is a failed write (exit 5) wherever the output is."""

from __future__ import annotations

import hashlib
import io
import json
import os
import subprocess
import sys

import pytest
import yaml
from PIL import Image

from loopback import Server
from test_ifdo import HEADER, POSITION
from test_metadata import _gps_exif, _scene

fsspec = pytest.importorskip("fsspec")
from fsspec.implementations.memory import MemoryFileSystem  # noqa: E402

GUARD = 300  # seconds: only so that a hang fails the test instead of holding the suite
PROTOCOL = "uwhlcount"
#: the bucket of the tests on moto (its own: moto's buckets are shared by the process)
BUCKET = "survey9"


def uwhl(*args, cwd=None, timeout=GUARD):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, stdin=subprocess.PIPE, env=dict(os.environ))


# ------------------------------------------------------------------ a store that counts what it serves


class _Reader(io.RawIOBase):
    """A read-only file over bytes that counts every byte it hands out."""

    def __init__(self, fs, path: str, data: bytes):
        self.fs, self.path, self.data, self.pos = fs, path, data, 0

    def readable(self):
        return True

    def seekable(self):
        return True

    def seek(self, offset, whence=0):
        self.pos = [offset, self.pos + offset, len(self.data) + offset][whence]
        return self.pos

    def tell(self):
        return self.pos

    def read(self, n=-1):
        end = len(self.data) if n is None or n < 0 else self.pos + n
        out = self.data[self.pos:end]
        self.pos += len(out)
        self.fs.count(self.path, len(out))
        return out


class CountingFS(MemoryFileSystem):
    """An in-memory store (``uwhlcount://``) that records the bytes it
    serves (``served``: path -> total; ``largest``: path -> the most in one
    request) and says the sizes in ``lies`` instead of the true ones, in
    listings and ``info``, as a stale listing or a hostile store would."""

    protocol = (PROTOCOL,)
    store: dict = {}
    pseudo_dirs = [""]
    served: dict = {}
    largest: dict = {}
    lies: dict = {}

    @classmethod
    def _strip_protocol(cls, path):
        path = str(path)
        if path.startswith(PROTOCOL + "://"):
            path = path[len(PROTOCOL) + 3:]
        return super()._strip_protocol(path)

    @classmethod
    def reset(cls):
        cls.store.clear()
        cls.pseudo_dirs[:] = [""]
        cls.served.clear()
        cls.largest.clear()
        cls.lies.clear()

    def count(self, path, n):
        path = self._strip_protocol(path)
        self.served[path] = self.served.get(path, 0) + n
        self.largest[path] = max(self.largest.get(path, 0), n)

    def _lie(self, info):
        if info.get("name") in self.lies:
            info = {**info, "size": self.lies[info["name"]]}
        return info

    def info(self, path, **kwargs):
        return self._lie(super().info(path, **kwargs))

    def ls(self, path, detail=True, **kwargs):
        out = super().ls(path, detail=detail, **kwargs)
        return [self._lie(i) for i in out] if detail else out

    def find(self, path, maxdepth=None, withdirs=False, detail=False, **kwargs):
        out = super().find(path, maxdepth=maxdepth, withdirs=withdirs, detail=detail, **kwargs)
        return {k: self._lie(v) for k, v in out.items()} if detail else out

    def cat_file(self, path, start=None, end=None, **kwargs):
        data = super().cat_file(path, start=start, end=end, **kwargs)
        self.count(path, len(data))
        return data

    def _open(self, path, mode="rb", block_size=None, autocommit=True, cache_options=None, **kwargs):
        if mode != "rb":
            return super()._open(path, mode, block_size, autocommit, cache_options, **kwargs)
        p = self._strip_protocol(path)
        if p not in self.store:
            raise FileNotFoundError(p)
        return _Reader(self, p, bytes(self.store[p].getbuffer()))


@pytest.fixture
def store():
    """The counting store, empty, registered as ``uwhlcount://``."""
    fsspec.register_implementation(PROTOCOL, CountingFS, clobber=True)
    CountingFS.reset()
    fs = CountingFS()
    yield fs
    CountingFS.reset()


@pytest.fixture(scope="module")
def restored(tmp_path_factory):
    """One photo restored into a local folder (its input beside it): the
    files to put on the store."""
    d = tmp_path_factory.mktemp("restored")
    (d / "in").mkdir()
    Image.fromarray(_scene(60, 80, seed=1)).save(d / "in" / "f00.jpg", quality=90, exif=_gps_exif())
    r = uwhl("restore", "in", "-o", "out", "-q", cwd=d)
    assert r.returncode == 0, r.stderr
    return d


def _put(fs, local_dir, prefix):
    for name in os.listdir(local_dir):
        if os.path.isfile(os.path.join(local_dir, name)):
            fs.pipe_file(f"{prefix}/{name}", open(os.path.join(local_dir, name), "rb").read())


# ------------------------------------------------------------------ 1. objects larger than a reader takes


def test_a_huge_sidecar_is_refused_from_its_listed_size_unfetched(store, restored):
    """The listing says the object is 6 MiB, over a sidecar's 4 MiB: it is
    a note, and not one byte of it is asked for (it used to be fetched
    whole, then measured: 1.3 GB of memory for a 400 MB object)."""
    from uwhl_rs import report
    from uwhl_rs.sidecars import MAX_BYTES

    _put(store, restored / "out", "/survey/out")
    store.pipe_file("/survey/out/huge.json", b" " * (6 << 20))
    done = report.write_report(f"{PROTOCOL}://survey/out")
    assert done["photos"] == 1
    assert any(p.endswith(f"huge.json: cannot read (larger than {MAX_BYTES} bytes)") for p in done["problems"]), done
    assert store.served.get("/survey/out/huge.json", 0) == 0


def test_a_listing_that_lies_still_brings_no_more_than_the_limit(store, restored):
    """The listing says 100 bytes (the object replaced since, or a hostile
    store): the read is bounded by the limit itself, 4 MiB + 1 byte."""
    from uwhl_rs.outdir import collect_sidecars
    from uwhl_rs.sidecars import MAX_BYTES

    _put(store, restored / "out", "/survey/out")
    store.pipe_file("/survey/out/huge.json", b" " * (6 << 20))
    store.lies["/survey/out/huge.json"] = 100
    photos, problems = collect_sidecars(f"{PROTOCOL}://survey/out")
    assert [p.sidecar for p in photos] == ["f00.json"]
    assert problems == [f"{PROTOCOL}://survey/out/huge.json: cannot read (larger than {MAX_BYTES} bytes)"]
    assert 0 < store.served["/survey/out/huge.json"] <= MAX_BYTES + 1


def test_summary_and_an_earlier_ifdo_are_read_within_their_limits(store, restored, monkeypatch):
    """summary.csv (512 MiB), with its limit made small here and a size
    that lies: not asked for more than its limit plus one byte, and then as
    if absent. An earlier ifdo.yaml is read only for the set UUID at its
    head (made 2000 bytes here): never more than that is asked for, and a
    UUID beyond it is not seen."""
    from uwhl_rs import ifdo, outdir
    from uwhl_rs.storage import Folder

    monkeypatch.setattr(outdir, "SUMMARY_MAX_BYTES", 1000)
    monkeypatch.setattr(ifdo, "EARLIER_HEAD_BYTES", 2000)
    row = "input,status\nx.png,failed\n"
    store.pipe_file("/survey/out/summary.csv", (row * 5000).encode())
    u = "0b6f1c2e-4a1d-4c8e-9f3a-2d5e7b9c1a40"
    store.pipe_file("/survey/out/ifdo.yaml", b"#" * 2100 + f"image-set-header:\n  image-set-uuid: {u}\n".encode())
    store.lies.update({"/survey/out/summary.csv": 10, "/survey/out/ifdo.yaml": 10})
    folder = Folder(f"{PROTOCOL}://survey/out")
    rows, total, why = outdir.failed_inputs(folder)
    assert (rows, total) == ([], 0) and "summary.csv: not read at all" in why, why
    assert ifdo._earlier_uuid(folder) is None
    assert 0 < store.served["/survey/out/summary.csv"] <= 1001
    assert 0 < store.served["/survey/out/ifdo.yaml"] <= 2000
    # at the head it is found, whatever follows (a planted ten megabytes of items)
    store.pipe_file("/survey/out/ifdo.yaml", f"image-set-header:\n  image-set-uuid: {u}\nx: [".encode() + b"1," * 5_000_000)
    assert ifdo._earlier_uuid(Folder(f"{PROTOCOL}://survey/out")) == u
    # within the limit they are read (the small summary's one failed row)
    store.pipe_file("/survey/out/summary.csv", row.encode())
    store.lies.clear()
    assert outdir.failed_inputs(Folder(f"{PROTOCOL}://survey/out"))[1] == 1


def test_an_input_on_the_store_is_hashed_a_chunk_at_a_time(store, restored, monkeypatch):
    """The sidecar's ``input`` names an object of the folder's store: it is
    hashed as it comes, a chunk a request (made 64 KiB here), never fetched
    whole into memory, and its thumbnail is made from the copy."""
    from uwhl_rs import report, storage

    monkeypatch.setattr(storage, "CHUNK", 64 << 10, raising=False)
    data = (restored / "in" / "f00.jpg").read_bytes()
    data += b"\0" * (400 << 10)  # a JPEG with bytes after its end: still the photo, and 7 chunks long
    store.pipe_file("/survey/in/f00.jpg", data)
    _put(store, restored / "out", "/survey/out")
    side = json.loads(store.cat_file("/survey/out/f00.json"))
    side["input"] = f"{PROTOCOL}://survey/in/f00.jpg"
    side["metadata"]["input_sha256"] = hashlib.sha256(data).hexdigest()
    store.pipe_file("/survey/out/f00.json", json.dumps(side).encode())
    done = report.write_report(f"{PROTOCOL}://survey/out")
    assert done["thumbnails_written"] == 2 and not done["problems"], done
    assert store.served["/survey/in/f00.jpg"] == len(data)
    assert store.largest["/survey/in/f00.jpg"] <= 64 << 10


def test_an_input_or_output_over_the_limit_is_not_fetched_past_it(store, restored, monkeypatch):
    """An input (and the restored photo) larger than the report takes
    (MAX_INPUT_BYTES, 4 GiB, made 300 KiB here), one of them listed as
    small: neither is asked for more than the limit plus one byte, and the
    page says why its thumbnail is missing."""
    from uwhl_rs import report

    limit = 300 << 10
    monkeypatch.setattr(report, "MAX_INPUT_BYTES", limit)
    _put(store, restored / "out", "/survey/out")
    big = b"\xff\xd8" + b"\0" * (1 << 20)
    store.pipe_file("/survey/in/f00.jpg", big)
    store.pipe_file("/survey/out/f00.jpg", big)
    store.lies["/survey/out/f00.jpg"] = 1000
    side = json.loads(store.cat_file("/survey/out/f00.json"))
    side["input"] = f"{PROTOCOL}://survey/in/f00.jpg"
    side["metadata"]["input_sha256"] = hashlib.sha256(big).hexdigest()
    store.pipe_file("/survey/out/f00.json", json.dumps(side).encode())
    store.served.clear()
    done = report.write_report(f"{PROTOCOL}://survey/out")
    assert done["thumbnails_written"] == 0
    assert f"{PROTOCOL}://survey/in/f00.jpg: larger than {limit} bytes; not shown" in done["problems"], done
    assert f"{PROTOCOL}://survey/out/f00.jpg: no thumbnail (larger than {limit} bytes)" in done["problems"], done
    assert store.served.get("/survey/in/f00.jpg", 0) == 0  # its size said it
    assert 0 < store.served["/survey/out/f00.jpg"] <= limit + 1


@pytest.fixture(scope="module")
def s3(moto_s3):
    """moto's S3 server (conftest) with the bucket "survey9". moto keeps
    its buckets for the whole process: another module's server, or this
    module's started again, may have it already."""
    fs, endpoint = moto_s3
    try:
        fs.mkdir(BUCKET)
    except FileExistsError:
        pass
    return fs, endpoint


def test_report_and_ifdo_on_s3_read_bounded_ranges(s3, restored, tmp_path, monkeypatch):
    """The same through a real S3 client (moto), every byte its GET
    requests return counted: an oversized sidecar is a note and is not
    fetched, the rest is read through ranged reads (an empty ``.json``
    too, of which a range would be refused), the thumbnails of the input
    and output made from copies; ``ifdo`` lists the photo."""
    import s3fs

    from uwhl_rs import ifdo, report

    fs, endpoint = s3
    fs.put(str(restored / "in" / "f00.jpg"), "survey9/in/f00.jpg")
    r = uwhl("restore", "s3://survey9/in/", "-o", "s3://survey9/out/", "--storage-option", f"endpoint_url={endpoint}",
             "-q")
    assert r.returncode == 0, r.stderr
    fs.pipe("survey9/out/huge.json", b" " * (6 << 20))
    fs.pipe("survey9/out/empty.json", b"")
    served: dict = {}
    cat_file, fetch_range = s3fs.S3FileSystem._cat_file, s3fs.core.S3File._fetch_range

    async def counted_cat(self, path, *a, **k):
        data = await cat_file(self, path, *a, **k)
        served[path] = served.get(path, 0) + len(data)
        return data

    def counted_range(self, start, end):
        data = fetch_range(self, start, end)
        served[self.path] = served.get(self.path, 0) + len(data)
        return data

    monkeypatch.setattr(s3fs.S3FileSystem, "_cat_file", counted_cat)
    monkeypatch.setattr(s3fs.core.S3File, "_fetch_range", counted_range)
    so = {"endpoint_url": endpoint}
    done = report.write_report("s3://survey9/out/", storage_options=so)
    assert done["photos"] == 1 and done["thumbnails_written"] == 2, done
    assert f"s3://survey9/out/huge.json: cannot read (larger than {4 << 20} bytes)" in done["problems"]
    assert any(p.startswith("s3://survey9/out/empty.json: not a usable sidecar: not JSON") for p in done["problems"])
    assert served.get("survey9/out/huge.json", 0) == 0
    assert served["survey9/out/f00.jpg"] == fs.size("survey9/out/f00.jpg")
    head = tmp_path / "header.yaml"
    head.write_text(yaml.safe_dump({**HEADER, **POSITION}))
    served.clear()
    got = ifdo.write_ifdo("s3://survey9/out/", str(head), storage_options=so)
    assert got["items"] == 1, got
    assert served.get("survey9/out/huge.json", 0) == 0


# ------------------------------------------------------------------ 2. malformed storage options


@pytest.mark.parametrize("item", [".x=1", "a..b=1", "a.=1", "client_kwargs. =1"])
def test_a_storage_option_with_an_empty_key_part_is_refused(item):
    """``.x=1`` and ``a..b=1`` were taken, and handed the client an option
    named "" (or a group of one)."""
    from uwhl_rs.errors import BatchError
    from uwhl_rs.storage import parse_storage_options

    with pytest.raises(BatchError, match="a part of the key is empty") as e:
        parse_storage_options([item])
    assert e.value.kind == "bad_arguments"


def _nested(item: str) -> dict:
    """``KEY=VALUE`` (``GROUP.KEY``) as the API's storage_options, the value as JSON when it is JSON."""
    key, _, value = item.partition("=")
    try:
        v = json.loads(value)
    except ValueError:
        v = value
    out: dict = {}
    d = out
    *parents, leaf = key.split(".")
    for p in parents:
        d = d.setdefault(p, {})
    d[leaf] = v
    return out


@pytest.mark.parametrize("item, says", [
    ("client_kwargs=foo", "client_kwargs is a group of options (client_kwargs.KEY=VALUE), not a value ('foo')"),
    ("config_kwargs.retries=3", "config_kwargs.retries is a group of options"),
    ("endpoint_url=", "endpoint_url must be an http:// or https:// URL with a host, not ''"),
    ("endpoint_url=notaurl", "endpoint_url must be an http:// or https:// URL with a host, not 'notaurl'"),
    ("endpoint_url=ftp://h", "endpoint_url must be an http:// or https:// URL with a host"),
    ("endpoint_url=http://", "endpoint_url must be an http:// or https:// URL with a host"),
    ("endpoint_url=http://h:99999", "endpoint_url must be an http:// or https:// URL with a host"),
    ("client_kwargs.endpoint_url=h", "client_kwargs.endpoint_url must be an http:// or https:// URL"),
    ("asynchronous=true", "asynchronous: not an option to give"),
    ("default_block_size=-1", "default_block_size must be a whole number >= 1, not -1"),
    ("default_block_size=1.5", "default_block_size must be a whole number >= 1, not 1.5"),
    ("max_concurrency=0", "max_concurrency must be a whole number >= 1, not 0"),
    ("config_kwargs.connect_timeout=-1", "config_kwargs.connect_timeout must be a number of seconds > 0"),
    ("anon=3", "anon must be true or false, not 3"),
])
def test_malformed_storage_options_are_named_before_any_request(item, says):
    from uwhl_rs.errors import BatchError
    from uwhl_rs.storage import filesystem, parse_storage_options, storage_option_problem

    with pytest.raises(BatchError) as e:
        parse_storage_options([item])
    assert e.value.kind == "bad_arguments" and str(e.value).startswith(f"--storage-option {says}"), e.value
    # the API's storage_options are checked alike
    so = _nested(item)
    assert storage_option_problem(so).startswith(says)
    with pytest.raises(BatchError) as e:
        filesystem("s3://survey9/x", so)
    assert e.value.kind == "bad_arguments" and says in str(e.value)
    # well-formed ones pass
    assert storage_option_problem({"endpoint_url": "https://s3.example.org:9000/", "anon": False,
                                   "default_block_size": 1 << 20, "client_kwargs": {"region_name": "eu"},
                                   "config_kwargs": {"retries": {"max_attempts": 0}, "read_timeout": 2.5}}) is None


@pytest.mark.parametrize("bad", ["nonsense_option=1", "config_kwargs.retries.mode=bogus",
                                 "client_kwargs.region_name=a/b", "config_kwargs.signature_version=zz"])
def test_an_option_the_client_refuses_is_a_bad_argument_and_sends_nothing(bad, tmp_path, monkeypatch):
    """These pass the parser, and the client refuses them when it is built
    (or signs, before it sends): they were "cannot reach the storage",
    exit 7. Now exit 2 naming the option, and nothing reaches the
    endpoint; an endpoint that answers nothing stays exit 7."""
    pytest.importorskip("s3fs")
    # credentials of its own: without any, the client stops at "no credentials" before it reaches the endpoint
    for k, v in dict(AWS_ACCESS_KEY_ID="testing", AWS_SECRET_ACCESS_KEY="testing", AWS_DEFAULT_REGION="us-east-1",
                     AWS_EC2_METADATA_DISABLED="true").items():
        monkeypatch.setenv(k, v)
    # counts the connections made to it, closing each
    where = Server(lambda conn: conn.close())
    try:
        env_so = ["--storage-option", f"endpoint_url=http://127.0.0.1:{where.port}"]
        r = uwhl("report", "s3://survey9/out/", *env_so, "--storage-option", bad)
        assert r.returncode == 2 and "bad storage options" in r.stderr, r.stderr
        assert bad.split("=")[0].split(".")[-1] in r.stderr or bad.split("=")[1] in r.stderr, r.stderr
        r = uwhl("restore", "s3://survey9/in/", "-o", tmp_path / "o", *env_so, "--storage-option", bad)
        assert r.returncode == 2 and "bad storage options" in r.stderr, r.stderr
        assert len(where.conns) == 0
        r = uwhl("report", "s3://survey9/out/", *env_so, "--storage-option", "config_kwargs.retries.max_attempts=0")
        assert r.returncode == 7 and "cannot reach the storage" in r.stderr, r.stderr
        assert len(where.conns) > 0
    finally:
        where.close()


def test_a_negative_block_size_is_a_bad_argument_not_every_input_unreadable(s3, restored, tmp_path):
    """``default_block_size=-1`` used to fail every input as "not a JPEG,
    PNG..." (exit 3): a whole copy of an input was cut to nothing."""
    fs, endpoint = s3
    fs.put(str(restored / "in" / "f00.jpg"), "survey9/blocks/f00.jpg")
    r = uwhl("restore", "s3://survey9/blocks/", "-o", tmp_path / "o", "--storage-option", f"endpoint_url={endpoint}",
             "--storage-option", "default_block_size=-1")
    assert r.returncode == 2, r.stderr
    assert "--storage-option default_block_size must be a whole number >= 1, not -1" in r.stderr
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ 3. names restore writes and its readers refused


def _scene_with_gps(path):
    Image.fromarray(_scene(60, 80, seed=2)).save(path, quality=90, exif=_gps_exif())


def _check_backslash_photo(done, items, handle_end):
    assert done["photos"] == 1 and done["thumbnails_written"] >= 1, done
    assert not any("not a usable sidecar" in p for p in done["problems"]), done["problems"]
    assert list(items) == ["back\\slash.jpg"]
    item = items["back\\slash.jpg"]
    # a backslash in a link is a separator to a browser: it is percent-encoded
    assert item["image-handle"].endswith(handle_end)


@pytest.mark.skipif("\\" in (os.sep + (os.altsep or "")), reason="a backslash separates folders here")
def test_a_backslash_name_restored_locally_is_reported_and_listed(tmp_path):
    """``back\\slash.png`` is restored as ``back\\slash.jpg`` and ``.json``
    (a POSIX name holds a backslash like any character), and report and
    ifdo said "outputs.image must be a file name beside the sidecar",
    leaving the photo out."""
    from uwhl_rs import ifdo, report

    (tmp_path / "in").mkdir()
    _scene_with_gps(tmp_path / "in" / "back\\slash.jpg")
    r = uwhl("restore", "in", "-o", "out", "-q", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "out" / "back\\slash.json").is_file(), r.stderr
    done = report.write_report(tmp_path / "out")
    assert done["thumbnails_written"] == 2, done
    page = (tmp_path / "out" / "report" / "index.html").read_text()
    assert '"full": "../back%5Cslash.jpg"' in page
    got = ifdo.build_ifdo(str(tmp_path / "out"), {**HEADER, **POSITION})[0]
    _check_backslash_photo(done, got["image-set-items"], "/out/back%5Cslash.jpg")
    used = got["image-set-header"]["image-set-provenance"]["provenance-activities"][0]["used-entities"][0]
    assert used["name"] == "back\\slash.jpg"


def test_a_backslash_name_restored_to_s3_is_reported_and_listed(s3, tmp_path):
    """The same for a key ``odd/back\\slash.jpg`` restored to object
    storage, where a backslash never separates anything."""
    from uwhl_rs import ifdo, report

    fs, endpoint = s3
    _scene_with_gps(tmp_path / "x.jpg")
    fs.put(str(tmp_path / "x.jpg"), "survey9/odd/back\\slash.jpg")
    so = {"endpoint_url": endpoint}
    r = uwhl("restore", "s3://survey9/odd/", "-o", "s3://survey9/odd_out/", "--storage-option",
             f"endpoint_url={endpoint}", "-q")
    assert r.returncode == 0 and fs.exists("survey9/odd_out/back\\slash.json"), r.stderr
    done = report.write_report("s3://survey9/odd_out/", storage_options=so)
    assert done["thumbnails_written"] == 2, done
    got = ifdo.build_ifdo("s3://survey9/odd_out/", {**HEADER, **POSITION}, storage_options=so)[0]
    _check_backslash_photo(done, got["image-set-items"], "s3://survey9/odd_out/back%5Cslash.jpg")
    used = got["image-set-header"]["image-set-provenance"]["provenance-activities"][0]["used-entities"][0]
    assert used["name"] == "back\\slash.jpg"


def test_a_windows_folder_still_refuses_a_backslash_name(monkeypatch):
    """Where a backslash separates folders (Windows, made so here), a
    local folder's sidecar naming ``back\\slash.jpg`` points into a
    sub-folder: refused as before. On POSIX it is a name; an output role
    the readers do not use is not judged."""
    from uwhl_rs import sidecars

    doc = {"input": "x.png", "water_type": "II", "outputs": {"image": "back\\slash.jpg", "other": "a/b"}}
    assert sidecars.parse(json.dumps(doc).encode()) == doc
    monkeypatch.setattr(sidecars, "LOCAL_SEPARATORS", "/")
    assert sidecars.local_outputs_problem(doc) is None
    monkeypatch.setattr(sidecars, "LOCAL_SEPARATORS", "/\\")
    why = sidecars.local_outputs_problem(doc)
    assert why == "outputs.image must be a file name beside the sidecar (no folder, no ..)"
    assert not sidecars.plain_name("sub/x.jpg") and not sidecars.plain_name("..")


def test_a_name_too_long_for_its_outputs_is_a_failed_write_wherever_they_go(s3, restored, tmp_path):
    """A 245-character key: its outputs' names (``..._t_color.png``) are
    longer than the 255 bytes a file name may have. That failed with
    exit 5 (write_failed) for a local output folder and exit 3
    (unreadable_input) for an output on object storage, whose outputs
    are staged locally under the same names: now exit 5 for both."""
    fs, endpoint = s3
    key = "a" * 241 + ".jpg"
    fs.put(str(restored / "in" / "f00.jpg"), f"survey9/long/{key}")
    so = ["--storage-option", f"endpoint_url={endpoint}"]
    for out in (str(tmp_path / "o"), "s3://survey9/long_out/"):
        r = uwhl("restore", "s3://survey9/long/", "-o", out, *so, "--json-errors", "-q")
        assert r.returncode == 5, (out, r.stderr)
        lines = [json.loads(x) for x in r.stderr.splitlines() if x.startswith("{")]
        assert lines[0]["error"] == "write_failed", lines
        assert "more than the 255 a file name may have" in lines[0]["message"], lines
    assert not fs.exists("survey9/long_out/" + key[:-4] + ".json")
