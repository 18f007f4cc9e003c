import json
import os
import shutil
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="session")
def binary():
    """The ``uwhl-rs`` executable: the one ``cargo test --release --features
    cli,internals`` (the CI command) builds, asked of cargo with ``--no-run``
    so that nothing is compiled again (a plain ``cargo build`` would resolve
    the dependencies' features without the dev-dependencies and rebuild
    them); ``UWHL_RS_BIN`` points the tests at another build."""
    path = os.environ.get("UWHL_RS_BIN")
    if path:
        return path
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("cargo is not installed: cannot build the uwhl-rs binary")
    r = subprocess.run(
        [cargo, "test", "--release", "--no-run", "--features", "cli,internals",
         "--message-format=json-render-diagnostics"],
        cwd=ROOT, capture_output=True, text=True, timeout=1800,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    for line in r.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg.get("executable") and \
                msg["target"]["name"] == "uwhl-rs" and msg["target"]["kind"] == ["bin"] and not msg["profile"]["test"]:
            return msg["executable"]
    pytest.fail("cargo built no uwhl-rs executable")


@pytest.fixture(scope="module")
def moto_s3():
    """moto's S3 server on 127.0.0.1 (the tests' object storage) with test
    credentials in the environment: ``(fs, endpoint)``, fs an fsspec
    filesystem on it; the caller makes its buckets."""
    pytest.importorskip("moto")
    s3fs = pytest.importorskip("s3fs")
    from moto.server import ThreadedMotoServer

    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    endpoint = f"http://{host}:{port}"
    creds = dict(AWS_ACCESS_KEY_ID="testing", AWS_SECRET_ACCESS_KEY="testing", AWS_DEFAULT_REGION="us-east-1",
                 AWS_EC2_METADATA_DISABLED="true")
    old = {k: os.environ.get(k) for k in creds}
    os.environ.update(creds)
    yield s3fs.S3FileSystem(endpoint_url=endpoint), endpoint
    server.stop()
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
