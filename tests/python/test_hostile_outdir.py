"""A hostile output folder, for both commands (``uwhl restore`` and
``uwhl-rs restore``; issue 30): summary.csv with a link planted at it, two
runs writing it at once, input names that a spreadsheet would evaluate;
reruns from another working directory, by another name of the same file,
with ``--overwrite`` beside foreign files, after a stale claim of another
input, on a read-only mount; a missing output bucket; the sidecar's
``max_memory`` when none was asked (tests/python/test_sidecar_parameters.py).

Every hostile file is made here. Expected values come from the rules of
docs/OUTPUTS.md, not from either command's output.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import subprocess
import sys

import pytest

import uwhl_rs
from uwhl_rs import synth
from uwhl_rs.images import write_image

FACES = ["python", "rust"]

#: what OWASP's advice makes a spreadsheet take as a formula
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


def _cmd(face: str, binary: str, args) -> list:
    args = [a if isinstance(a, bytes) else str(a) for a in args]
    if face == "python":
        return [sys.executable, "-m", "uwhl_rs", "restore", *args]
    return [binary, "restore", *args]


def _run(face, binary, args, cwd=None, prefix=()):
    return subprocess.run([*prefix, *_cmd(face, binary, args)], capture_output=True, text=True, timeout=300,
                          env=_env(), cwd=cwd, errors="replace")


def _image(path, seed=0):
    img, _ = synth.demo_input(48, 64, water_type="II", seed=seed)
    write_image(path, img, bits=8, encoding="linear")


def _files(d) -> dict:
    """Every file of a folder (recursively) with its bytes, summary.csv aside."""
    got = {}
    for dp, _, fs in os.walk(d):
        for f in fs:
            p = os.path.join(dp, f)
            if f != "summary.csv":
                got[os.path.relpath(p, d)] = open(p, "rb").read()
    return got


def _names(d) -> set:
    return {os.fsdecode(n) for n in os.listdir(d) if n != "summary.csv"}


def _rows(out) -> list[dict]:
    with open(os.path.join(out, "summary.csv"), newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# ------------------------------------------------------------ summary.csv


@pytest.mark.parametrize("face", FACES)
def test_a_link_planted_at_summary_csv_is_replaced_not_written_through(face, binary, tmp_path):
    """The link's target keeps its bytes; summary.csv is a new regular file
    (a run alone starts it afresh by a rename, as it writes the photos)."""
    _image(tmp_path / "a.png")
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_bytes(b"not yours")
    os.symlink(victim, out / "summary.csv")
    r = _run(face, binary, [tmp_path / "a.png", "-o", out, "-q"])
    assert r.returncode == 0, r.stderr
    assert victim.read_bytes() == b"not yours"
    assert not os.path.islink(out / "summary.csv")
    assert [row["status"] for row in _rows(out)] == ["done"]


PAIRS = [("python", "python"), ("rust", "rust"), ("python", "rust")]


@pytest.mark.parametrize("pair", PAIRS, ids=["-".join(p) for p in PAIRS])
def test_two_runs_on_one_folder_keep_every_row_whole(pair, binary, tmp_path):
    """Two processes on one output folder (docs/OUTPUTS.md): each input is
    restored once, and summary.csv parses, with the header once, every row
    whole, and every input's rows either once (the second run started after
    the first ended, afresh) or once per run (they overlapped)."""
    src = tmp_path / "in"
    src.mkdir()
    names = [f"p{k:02d}.png" for k in range(40)]
    for k, n in enumerate(names):
        _image(src / n, seed=k)
    out = tmp_path / "out"
    procs = [subprocess.Popen(_cmd(face, binary, [src, "-o", out, "-q", "--format", "png"]), env=_env(),
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True) for face in pair]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
    text = open(out / "summary.csv", newline="", encoding="utf-8").read()
    lines = list(csv.reader(io.StringIO(text, newline="")))
    header = lines[0]
    assert header[:2] == ["input", "status"]
    assert sum(1 for line in lines if line[:2] == ["input", "status"]) == 1, "a header was written twice"
    rows = [dict(zip(header, line)) for line in lines[1:]]
    for line in lines[1:]:
        assert len(line) == len(header), f"a spliced row: {line[:3]}"
    count: dict[str, int] = {}
    done: dict[str, int] = {}
    for row in rows:
        name = os.path.basename(row["input"])
        assert name in names, f"a row of no input: {row['input']!r}"
        assert row["status"] in ("done", "skipped"), row
        count[name] = count.get(name, 0) + 1
        done[name] = done.get(name, 0) + (row["status"] == "done")
    assert set(count) == set(names), f"rows missing: {sorted(set(names) - set(count))}"
    assert len(set(count.values())) == 1 and set(count.values()) <= {1, 2}, count
    assert all(v <= 1 for v in done.values()), done
    # each input restored once, under its own name
    assert {n for n in _names(out) if n.endswith(".json")} == {n[:-4] + ".json" for n in names}


@pytest.mark.parametrize("face", FACES)
def test_formula_characters_in_cells_are_neutralised_and_readers_get_them_back(face, binary, tmp_path):
    """Input names a spreadsheet would evaluate go in with one quote before
    them (OWASP); ``uwhl_rs.outdir.summary_cell`` gives the name back."""
    from uwhl_rs.outdir import summary_cell

    src = tmp_path / "in"
    src.mkdir()
    hostile = ["=HYPERLINK(\"x\").png", "+1.png", "-2.png", "@SUM(A1).png", "\tt.png",
               "'=q.png", "plain.png"]
    for n in hostile:
        (src / n).write_bytes(b"\x89PNG\r\n\x1a\n not really a png")
    _image(src / "=good.png")
    out = tmp_path / "out"
    r = _run(face, binary, ["-o", out, "-q", "--", *hostile, "=good.png"], cwd=src)
    assert r.returncode == 3, r.stderr
    rows = _rows(out)
    got = {row["input"]: row for row in rows}
    for n in hostile + ["=good.png"]:
        written = ("'" + n) if n.startswith(FORMULA_STARTS) or n.startswith("'=") else n
        assert written in got, (n, sorted(got))
        assert summary_cell(written) == n
    for row in rows:
        for col, cell in row.items():
            assert not cell.startswith(FORMULA_STARTS), (col, cell)
    assert got["'=good.png"]["status"] == "done"
    # numbers stay numbers: A is not quoted
    assert float(got["'=good.png"]["A_R"]) > 0


# ------------------------------------------------------------ reruns


@pytest.mark.parametrize("face", FACES)
def test_a_rerun_from_elsewhere_or_by_another_name_recognises_the_finished_input(face, binary, tmp_path):
    """The sidecar's ``input`` is relative to the first run's working
    directory; a rerun from another one, with an absolute path, or through
    a link to the same file skips the input instead of restoring it again
    as ``a_2``."""
    (tmp_path / "survey" / "in").mkdir(parents=True)
    _image(tmp_path / "survey" / "in" / "a.png")
    out = tmp_path / "out"
    r = _run(face, binary, ["in/a.png", "-o", out, "-q"], cwd=tmp_path / "survey")
    assert r.returncode == 0, r.stderr
    first = _files(out)
    assert json.loads(first["a.json"])["input"] == "in/a.png"
    os.symlink(tmp_path / "survey" / "in" / "a.png", tmp_path / "link.png")
    for args, cwd in [(["a.png", "-o", out], tmp_path / "survey" / "in"),
                      ([tmp_path / "survey" / "in" / "a.png", "-o", out], tmp_path),
                      (["survey/in/a.png", "-o", out], tmp_path)]:
        r = _run(face, binary, [*args, "-q"], cwd=cwd)
        assert r.returncode == 0, r.stderr
        assert _files(out) == first, (args, sorted(_names(out)))
        assert [row["status"] for row in _rows(out)] == ["skipped"]


@pytest.mark.parametrize("face", FACES)
def test_a_name_that_is_not_utf8_is_recognised_at_rerun(face, binary, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    raw = os.fsencode(src) + b"/caf\xe9.png"
    _image(tmp_path / "tmp.png")
    os.rename(tmp_path / "tmp.png", raw)
    out = tmp_path / "out"
    assert _run(face, binary, [raw, "-o", out, "-q"]).returncode == 0
    first = _files(out)
    assert len([n for n in first if n.endswith(".json")]) == 1
    r = _run(face, binary, [raw, "-o", out, "-q"])
    assert r.returncode == 0, r.stderr
    assert _files(out) == first, sorted(_names(out))


@pytest.mark.parametrize("foreign", [("a_t.png",), ("a_t.png", "a.json")], ids=["a_t.png", "a_t.png+a.json"])
@pytest.mark.parametrize("face", FACES)
def test_overwrite_beside_foreign_files_redoes_the_input_in_place_and_keeps_them(face, binary, tmp_path, foreign):
    """Foreign files at a's names sent the first run to ``a_2``;
    ``--overwrite`` redoes ``a_2`` and never writes over the foreign files,
    nor restores a.png a second time under another name."""
    _image(tmp_path / "a.png")
    out = tmp_path / "out"
    out.mkdir()
    theirs = {n: f"someone else's {n}".encode() for n in foreign}
    for n, body in theirs.items():
        (out / n).write_bytes(body)
    ours = {"a_2.png", "a_2_t.png", "a_2_t_color.png", "a_2_confidence.png", "a_2.json"}
    r = _run(face, binary, [tmp_path / "a.png", "-o", out, "--format", "png", "-q"])
    assert r.returncode == 0, r.stderr
    assert _names(out) == set(theirs) | ours
    for _ in range(2):
        r = _run(face, binary, [tmp_path / "a.png", "-o", out, "--format", "png", "--overwrite", "-q"])
        assert r.returncode == 0, r.stderr
        assert _names(out) == set(theirs) | ours
        for n, body in theirs.items():
            assert (out / n).read_bytes() == body, n
        assert [row["status"] for row in _rows(out)] == ["done"]


@pytest.mark.parametrize("face", FACES)
def test_a_summary_row_a_full_disk_cuts_is_taken_back(face, binary, tmp_path):
    """A write that runs out of room mid-row (here a file size limit, as a
    full disk does) left half a row that the next run's rows followed.
    The cut row is taken back: the file holds whole rows only."""
    import resource
    import signal
    src = tmp_path / "in"
    src.mkdir()
    for k in range(12):
        _image(src / f"photo_with_a_long_name_{k:02d}.png", seed=k)
    out = tmp_path / "out"
    out.mkdir()

    def limited():
        # no output fits (each input fails as unwritable); the rows meet the
        # limit mid-row. SIGXFSZ as a shell leaves it (its default kills the
        # writer mid-row): each command ignores it itself
        resource.setrlimit(resource.RLIMIT_FSIZE, (3000, 3000))
        signal.signal(signal.SIGXFSZ, signal.SIG_DFL)

    r = subprocess.run(_cmd(face, binary, [src, "-o", out, "-q", "--format", "png"]), env=_env(), capture_output=True,
                       text=True, timeout=300, preexec_fn=limited)
    assert r.returncode != 0 and "Traceback" not in r.stderr, r.stderr
    text = open(out / "summary.csv", newline="", encoding="utf-8").read()
    lines = list(csv.reader(io.StringIO(text, newline="")))
    assert 1 < len(lines) < 13, "the limit did not cut the rows"
    assert text.endswith("\r\n") and all(len(line) == len(lines[0]) for line in lines), text[-300:]


def _claim_name(name: str) -> str:
    """The claim file of an output name (docs/OUTPUTS.md: FNV-1a 64 of the name)."""
    h = 0xcbf29ce484222325
    for b in name.encode():
        h = ((h ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return f".uwhl-claim-{h:016x}"


@pytest.mark.parametrize("face", FACES)
def test_a_stale_claim_naming_another_input_does_not_replace_the_users_file(face, binary, tmp_path):
    _image(tmp_path / "x.png")
    out = tmp_path / "out"
    out.mkdir()
    (out / "x_t.png").write_bytes(b"the user's own x_t.png")
    # a killed run (a pid above the kernel's largest never runs) restoring another input
    (out / _claim_name("x")).write_text(f"4194399\nx\n{tmp_path / 'other' / 'x.png'}\n")
    r = _run(face, binary, [tmp_path / "x.png", "-o", out, "--format", "png", "-q"])
    assert r.returncode == 0, r.stderr
    assert (out / "x_t.png").read_bytes() == b"the user's own x_t.png"
    assert "x_2.json" in _names(out)


@pytest.mark.parametrize("face", FACES)
def test_an_overwrite_in_another_format_leaves_no_earlier_image(face, binary, tmp_path):
    """``--overwrite --format png`` after a JPEG run: the new sidecar lists
    x.png, and x.jpg of the earlier run (which a reader would take for this
    run's) is gone; a file of the user's beside it stays."""
    _image(tmp_path / "x.png")
    out = tmp_path / "out"
    r = _run(face, binary, [tmp_path / "x.png", "-o", out, "--format", "jpg", "-q"])
    assert r.returncode == 0, r.stderr
    assert "x.jpg" in _names(out)
    (out / "x_mine.txt").write_bytes(b"notes")
    r = _run(face, binary, [tmp_path / "x.png", "-o", out, "--format", "png", "--overwrite", "-q"])
    assert r.returncode == 0, r.stderr
    names = _names(out)
    assert "x.png" in names and "x.jpg" not in names, names
    assert (out / "x_mine.txt").read_bytes() == b"notes"
    listed = set(json.loads((out / "x.json").read_text())["outputs"].values())
    assert {n for n in names if n.startswith("x") and n not in ("x.json", "x_mine.txt")} == listed


def test_three_runs_over_dead_claims_restore_each_input_once(binary, tmp_path):
    """Three runs of both commands over inputs a killed run had claimed:
    each run may see a claim dead while another takes it over; each input
    is restored once, under its own name, and no claim or temporary is
    left."""
    src = tmp_path / "in"
    src.mkdir()
    names = [f"p{k:02d}.png" for k in range(16)]
    out = tmp_path / "out"
    out.mkdir()
    for k, n in enumerate(names):
        # large enough that the three runs overlap
        img, _ = synth.demo_input(240, 320, water_type="II", seed=k)
        write_image(src / n, img, bits=8, encoding="linear")
        # a killed run (a pid above the kernel's largest never runs) restoring this input
        (out / _claim_name(n[:-4])).write_text(f"4194399\n{n[:-4]}\n{os.path.realpath(src / n)}\n")
    procs = [subprocess.Popen(_cmd(face, binary, [src, "-o", out, "--format", "png"]), env=_env(),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for face in ("rust", "python", "rust")]
    done = 0
    for p in procs:
        text, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        # the last line of both commands: "N done, M skipped, K failed in S s"
        counts = re.search(r"(\d+) done, (\d+) skipped, (\d+) failed", text + err)
        assert counts, text + err
        done += int(counts.group(1))
        assert counts.group(3) == "0", text + err
    assert done == len(names), done
    assert {n for n in _names(out) if n.endswith(".json")} == {n[:-4] + ".json" for n in names}
    assert not [n for n in _names(out) if n.startswith(".uwhl-")]


def _read_only(path) -> list:
    """A prefix running a command with ``path`` bind-mounted read-only in a
    mount namespace of its own (nothing is left mounted); skips the test
    where namespaces are not allowed."""
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount --bind '{path}' '{path}' && "
                            f"mount -o remount,bind,ro '{path}' && ! touch '{path}/.probe' 2>/dev/null"],
                           capture_output=True)
    if probe.returncode != 0:
        pytest.skip("cannot make a read-only mount here (user namespaces refused)")
    return ["unshare", "-rm", "sh", "-c", f"mount --bind '{path}' '{path}' && mount -o remount,bind,ro '{path}' && "
            'exec "$@"', "sh"]


@pytest.mark.parametrize("face", FACES)
def test_a_finished_input_on_a_read_only_mount_is_skipped(face, binary, tmp_path):
    _image(tmp_path / "a.png")
    out = tmp_path / "out"
    assert _run(face, binary, [tmp_path / "a.png", "-o", out, "-q"]).returncode == 0
    first = _files(out)
    summary = (out / "summary.csv").read_bytes()
    r = _run(face, binary, [tmp_path / "a.png", "-o", out], prefix=_read_only(out))
    assert r.returncode == 0, r.stderr
    assert "skipped" in r.stdout + r.stderr
    assert _files(out) == first and (out / "summary.csv").read_bytes() == summary
    # an input not yet restored on the same mount still fails as unwritable
    _image(tmp_path / "b.png", seed=1)
    r = _run(face, binary, [tmp_path / "b.png", "-o", out, "-q"], prefix=_read_only(out))
    assert r.returncode == 5, r.stderr


# ------------------------------------------------------------ object storage


@pytest.fixture(scope="module")
def s3(moto_s3):
    """moto's S3 server (conftest) with the bucket "present"."""
    fs, endpoint = moto_s3
    fs.mkdir("present")
    return fs, endpoint


def test_a_missing_output_bucket_is_found_before_any_input_is_restored(s3, tmp_path):
    fs, endpoint = s3
    src = tmp_path / "in"
    src.mkdir()
    for k in range(3):
        _image(src / f"i{k}.png", seed=k)
    env = _env()
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", "s3://no-such-bucket/out/",
                        "--storage-option", f"endpoint_url={endpoint}"], capture_output=True, text=True,
                       timeout=300, env=env)
    assert r.returncode == 5, r.stderr
    assert r.stderr.count("no-such-bucket") == 1, r.stderr
    assert "does not exist" in r.stderr
    # no input was restored (no progress line of one), nothing was stored
    assert "i0.png" not in r.stdout + r.stderr
    assert not fs.exists("no-such-bucket")
    # an existing bucket without the folder is fine
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src / "i0.png"), "-o", "s3://present/new/",
                        "--storage-option", f"endpoint_url={endpoint}", "-q"], capture_output=True, text=True,
                       timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert fs.exists("present/new/i0.json")


@pytest.mark.parametrize("mode", [["--stream"], ["--raw-frames", "8x6"]])
def test_a_pipe_into_a_missing_output_folder_holds_it_before_any_output(binary, tmp_path, mode):
    """Every run holds its output folder with a shared lock, so that a run
    in another pid namespace (whose pids this one cannot see) never sweeps
    its temporaries. A pipe into a folder that did not exist yet held
    nothing until it ended: the folder is made and held when the run starts,
    before the first input arrives."""
    import fcntl
    import time

    out = tmp_path / "not" / "yet"
    p = subprocess.Popen([binary, "restore", *mode, "-o", str(out)], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        # waiting for the run to start (a condition, not a time limit on it)
        deadline = time.monotonic() + 60
        while not out.is_dir() and time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.05)
        assert out.is_dir(), p.poll()
        fd = os.open(out, os.O_RDONLY)
        try:
            # the run takes its lock right after making the folder
            while time.monotonic() < deadline:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    break
                fcntl.flock(fd, fcntl.LOCK_UN)
                time.sleep(0.05)
            else:
                pytest.fail("the running pipe does not hold its output folder")
            assert p.poll() is None
        finally:
            os.close(fd)
    finally:
        _, err = p.communicate(b"", timeout=120)
    assert p.returncode == 0, err


@pytest.mark.parametrize("face,mode", [("rust", []), ("rust", ["--stream"]), ("python", [])])
def test_a_folder_another_program_locks_exclusively_is_waited_for_with_a_note(face, binary, tmp_path, mode):
    """Runs hold their output folder with a shared lock, and their own
    exclusive locks are only tried and let go. A program holding an
    exclusive lock on the folder (``flock -x out sleep ...``) made a run
    wait for it without a word. The run says it is waiting (going on
    without its hold would let a run starting later take the folder for
    its own and start summary.csv afresh over its rows), and finishes once
    the lock is let go."""
    import fcntl

    src = tmp_path / "p.png"
    _image(src)
    out = tmp_path / "out"
    out.mkdir()
    fd = os.open(out, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    args = _cmd(face, binary, [*mode, "-o", out] + ([] if mode else [src]))
    p = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env())
    try:
        if mode:
            p.stdin.write(f"{src}\n".encode())
        p.stdin.close()
        # the note comes before anything is written; the lock is then let go
        line = p.stderr.readline().decode()
        assert "another program holds a lock on this folder" in line and str(out) in line, line
        assert not (out / "p.json").exists()
    finally:
        os.close(fd)
    rest = p.stderr.read().decode()
    assert p.wait(timeout=120) == 0, rest
    assert (out / "p.json").is_file()


@pytest.mark.parametrize("face", FACES)
@pytest.mark.parametrize("below", ["file", "dangling"])
def test_an_output_folder_that_cannot_be_made_is_refused_before_any_input(face, binary, tmp_path, below):
    """An output folder below a file, or below a link to nothing: one
    message naming the part of the path, exit 5, before any input is read
    (a pipe of frames restored every frame to fail each write, exit 0)."""
    src = tmp_path / "p.png"
    _image(src)
    if below == "file":
        (tmp_path / "x").write_text("a file")
    else:
        (tmp_path / "x").symlink_to(tmp_path / "nothing")
    out = tmp_path / "x" / "sub"
    r = _run(face, binary, [src, "-o", out])
    assert r.returncode == 5, r.stderr
    assert "x is " in r.stderr and ("not a folder" in r.stderr if below == "file" else "link to nothing" in r.stderr)
    assert "p.png" not in r.stderr.replace(str(out), "")
    if face == "rust":
        for mode, data in ((["--stream"], f"{src}\n".encode()), (["--raw-frames", "8x6"], bytes(8 * 6 * 3))):
            p = subprocess.run([binary, "restore", *mode, "-o", str(out)], input=data, capture_output=True, timeout=120)
            assert p.returncode == 5 and b"x is " in p.stderr, p.stderr


@pytest.mark.parametrize("face", FACES)
def test_a_batch_into_a_folder_the_system_will_not_make_is_one_error(face, binary, tmp_path):
    """``-o /proc/...``: the folder cannot be made (by root either), and a
    batch said so for every input and again for summary.csv; it is one
    error now, exit 5, as for a pipe of frames."""
    src = tmp_path / "p.png"
    _image(src)
    out = f"/proc/uwhl-not-here-{os.getpid()}/out"
    r = _run(face, binary, [src, src, "-o", out])
    assert r.returncode == 5, r.stderr
    assert "cannot make the output folder" in r.stderr and r.stderr.count("\n") == 1, r.stderr
