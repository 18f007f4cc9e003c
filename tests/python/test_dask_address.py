"""``uwhl restore --dask ADDRESS`` pointed at something that is not a Dask
scheduler (issue 30): an HTTP server, a port that sends other bytes, one
that accepts and never answers. Each is refused within UWHL_DASK_TIMEOUT
with one line naming the address, exit 7 (docs/CLI.md), nothing written.
The servers run in this process, on loopback."""

from __future__ import annotations

import http.server
import os
import subprocess
import sys
import threading

import pytest

from uwhl_rs import synth
from uwhl_rs.images import write_image

from loopback import Server

pytest.importorskip("distributed")


def _junk(conn):
    # what a web server's status line looks like to a reader of Dask frames: an 8-byte length of ~3 EiB
    try:
        conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 0\r\n\r\n")
    except OSError:
        pass


def _silent(conn):
    pass  # accepted, kept open, never a byte


@pytest.fixture
def http_server():
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    srv.daemon_threads = True
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    yield srv.server_address[1]
    srv.shutdown()
    srv.server_close()


@pytest.fixture
def photo(tmp_path):
    img, _ = synth.demo_input(40, 60, seed=3)
    path = tmp_path / "in" / "a.png"
    path.parent.mkdir()
    write_image(path, img, encoding="linear")
    return path


def _restore(tmp_path, photo, address):
    env = {**os.environ, "UWHL_DASK_TIMEOUT": "2"}
    # the subprocess timeout only turns a hang into a failure; the assertions are the code and the line
    return subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(photo), "-o", str(tmp_path / "out"),
                           "--dask", address], capture_output=True, text=True, env=env, timeout=120)


def _refused(r, tmp_path, address, needle):
    assert r.returncode == 7, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    line = [x for x in r.stderr.splitlines() if f"--dask {address}" in x]
    assert line and needle in line[0], r.stderr
    assert not os.path.exists(tmp_path / "out") or not os.listdir(tmp_path / "out")


def test_an_http_server_is_not_waited_on_for_good(tmp_path, photo, http_server):
    address = f"127.0.0.1:{http_server}"
    _refused(_restore(tmp_path, photo, address), tmp_path, address, "cannot reach the Dask scheduler (no answer within 2 s")


@pytest.mark.parametrize("handler, scheme, words", [
    # a port that sends other bytes: refused, not a traceback
    (_junk, "tcp://", "does not speak Dask's protocol"),
    # a server that accepts and never answers: given up on
    (_silent, "", "cannot reach the Dask scheduler (no answer within 2 s"),
], ids=["sends_other_bytes", "accepts_and_never_answers"])
def test_a_server_that_is_no_scheduler_is_refused(tmp_path, photo, handler, scheme, words):
    srv = Server(handler)
    try:
        address = f"{scheme}127.0.0.1:{srv.port}"
        _refused(_restore(tmp_path, photo, address), tmp_path, address, words)
    finally:
        srv.close()


def test_a_bad_timeout_is_a_usage_error(tmp_path, photo):
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(photo), "-o", str(tmp_path / "out"),
                        "--dask", "127.0.0.1:9"], capture_output=True, text=True,
                       env={**os.environ, "UWHL_DASK_TIMEOUT": "soon"}, timeout=120)
    assert r.returncode == 2 and "UWHL_DASK_TIMEOUT" in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize("elsewhere", [True, False])
def test_a_dask_run_hands_its_workers_paths_that_hold_where_they_run(tmp_path, monkeypatch, elsewhere):
    """A worker started in another folder: ``-o out``, a relative input,
    ``--water-from cal``, a ``--distance`` template and a navigation log
    named from the command's folder reach it as the same files (absolute),
    while ``--altitude 2.5`` stays metres. Workers in the command's own
    folder (``--dask local:N``) get the paths as given, so their sidecars
    record what a local run records."""
    from uwhl_rs import batch, cluster, images, synth

    monkeypatch.chdir(tmp_path)
    img, _ = synth.demo_input(40, 50, water_type="3C", seed=1)
    images.write_image(tmp_path / "p.png", img, bits=8, encoding="linear")
    (tmp_path / "cal").mkdir()
    (tmp_path / "nav.csv").write_text("name,altitude\np.png,2.0\n")
    seen = {}

    class Fake:
        dashboard_link = "-"

        def run(self, f, *a, **k):
            return {"tcp://w1": str(tmp_path / "elsewhere") if elsewhere else f(*a)}

        def close(self):
            pass

    monkeypatch.setattr(cluster, "connect", lambda client, dask, threads: (Fake(), None, None))
    monkeypatch.setattr(cluster, "check_workers", lambda c: None)

    def run(c, groups, opts, so, overwrite, reuse, reuse_wm, settle):
        seen.setdefault("items", []).extend(it for g in groups for it in g)
        seen.setdefault("opts", []).append(dict(opts))

    monkeypatch.setattr(cluster, "run_on_cluster", run)
    for altitude in ("nav.csv", "2.5", "xmp"):
        batch.run_batch(["p.png"], "out", client=object(), overwrite=True,
                        options={"water_from": "cal", "distance": "depth/{stem}.tif", "mask": "m.png",
                                 "altitude": altitude})
    it, opts = seen["items"][0], seen["opts"]
    here = (lambda p: str(tmp_path / p)) if elsewhere else (lambda p: p)
    assert it.input == here("p.png") and it.out_dir == here("out")
    assert opts[0]["water_from"] == here("cal") and opts[0]["mask"] == here("m.png")
    assert opts[0]["distance"] == (str(tmp_path / "depth" / "{stem}.tif") if elsewhere else "depth/{stem}.tif")
    assert [o["altitude"] for o in opts] == [here("nav.csv"), "2.5", "xmp"]


def test_a_script_starting_a_local_cluster_without_the_main_guard_is_told_so(tmp_path):
    """Dask's local workers import the calling script (spawn): without
    ``if __name__ == "__main__":`` each starts the batch again and the
    cluster fails to start; the call raises a BatchError saying what to
    do (docs/API.md)."""
    pytest.importorskip("distributed")
    img, _ = synth.demo_input(40, 56, water_type="II", seed=0)
    (tmp_path / "in").mkdir()
    write_image(tmp_path / "in" / "a.png", img, bits=8, encoding="linear")
    script = tmp_path / "noguard.py"
    script.write_text("from uwhl_rs.batch import restore_many\nrestore_many('in', 'out', dask='local:1')\n")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(os.path.dirname(os.path.abspath(synth.__file__))),
                                         env.get("PYTHONPATH", "")])
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode != 0
    assert "BatchError" in r.stderr and 'if __name__ == "__main__":' in r.stderr, r.stderr[-2000:]
