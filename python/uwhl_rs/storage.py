"""Where a batch reads and writes: local paths, ``file://`` URLs and
object-storage URLs (``s3://``, ``gs://``, ...) through fsspec
(docs/SCALE.md), the storage client's errors said as what to do, and
:class:`Folder`, the output folder as its readers and writers see it
(``uwhl report``, ``uwhl ifdo``), with one set of operations wherever the
batch wrote.

fsspec (and its backends) is the optional extra ``uwhl_rs[dask]``,
imported only when a URL needs it. Paths inside a folder are relative and
``/``-separated.
"""

from __future__ import annotations

import copy
import datetime as _dt
import errno
import hashlib
import importlib
import os
import posixpath
import re
import stat
import tempfile
import weakref

from .errors import BatchError
from .images import atomic_write_bytes
from .storage_options import is_option_error, parse_storage_options, storage_option_problem

__all__ = ["EXTRA", "is_url", "local_path", "parse_storage_options", "storage_option_problem", "need", "filesystem",
           "storage_error", "on_storage", "read_bytes", "spool", "download", "scheme", "sha256_of", "open_regular", "read_regular", "modified", "Folder"]

#: how to get what batches on Dask or object storage need
EXTRA = 'pip install "uwhl_rs[dask]"'

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def need(*modules: str):
    """Imports ``modules`` or raises a BatchError naming the extra."""
    out = []
    for m in modules:
        try:
            out.append(importlib.import_module(m))
        except ImportError as e:
            raise BatchError(f"{m} is not installed ({e}); batches on Dask or object storage need the extra: {EXTRA}",
                             "bad_arguments") from None
    return out


def is_url(path: str) -> bool:
    """Whether ``path`` is a URL of a storage other than the local disk
    (``file://`` URLs are local paths)."""
    return bool(_URL.match(str(path))) and not str(path).startswith("file://")


def local_path(path: str) -> str:
    """``path`` without a leading ``file://``."""
    return path[len("file://"):] if str(path).startswith("file://") else str(path)


def join(base: str, rel: str) -> str:
    """``rel`` (``/``-separated, may be empty) under ``base``, a folder or URL."""
    if not rel:
        return base.rstrip("/") if is_url(base) else base
    return base.rstrip("/") + "/" + rel if is_url(base) else os.path.join(base, rel)


def _build_client(fs, url: str) -> None:
    """Builds ``fs``'s client now when the backend defers it to the first
    request (s3fs): building it reads the options and sends nothing, so
    an option the client refuses is a bad argument that names it, before
    anything is listed, restored or written."""
    protocols = fs.protocol if isinstance(fs.protocol, (tuple, list)) else (fs.protocol,)
    connect = getattr(fs, "connect", None)
    if not any(p in ("s3", "s3a") for p in protocols) or not callable(connect):
        return
    # fsspec gives one instance per options: a batch plan asks for it per input, and
    # asking its client each time is a trip through the client's event loop
    try:
        if fs in _BUILT:
            return
    except TypeError:  # not hashable, not weakly referable: asked each time
        pass
    try:
        connect()
    except (TypeError, ValueError, AttributeError, KeyError) as e:
        raise BatchError(f"{url}: bad storage options ({type(e).__name__}: {e})", "bad_arguments") from None
    except Exception as e:
        if is_option_error(e):
            raise BatchError(f"{url}: bad storage options ({type(e).__name__}: {e})", "bad_arguments") from None
        raise storage_error(e, url) from None
    try:
        _BUILT.add(fs)
    except TypeError:
        pass


#: the filesystems whose client :func:`_build_client` built
_BUILT: weakref.WeakSet = weakref.WeakSet()


def storage_error(e: BaseException, where: str) -> BatchError:
    """An error of the storage client as a BatchError that says what to do."""
    name = type(e).__name__
    text = str(e) or name
    if "credential" in text.lower() or name in ("NoCredentialsError", "PartialCredentialsError"):
        return BatchError(f"{where}: no credentials ({text}); give them with --storage-option key=... "
                          "--storage-option secret=... (or profile=NAME, or anon=true for a public bucket), "
                          "or the AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY environment variables")
    if isinstance(e, PermissionError) or "AccessDenied" in text or "Forbidden" in text:
        return BatchError(f"{where}: access refused ({text}); check the credentials and the bucket's policy")
    if is_option_error(e):
        # an option the client judges only when it signs a request, before sending it
        return BatchError(f"{where}: bad storage options ({name}: {text})", "bad_arguments")
    return BatchError(f"{where}: cannot reach the storage ({name}: {text})")


#: botocore's timeouts and attempts unless the options give their own: its
#: defaults (60 s a read, retried) under s3fs's own 5 attempts held a batch
#: 7 minutes on an endpoint that accepts connections and never answers
S3_DEADLINES = {"connect_timeout": 10, "read_timeout": 20, "retries": {"total_max_attempts": 2}}

#: s3fs's own attempts at a call (its default 5, each with botocore's): 2 x 2
#: reads of 20 s give up on a silent endpoint in about 80 s, and a throttled
#: request (SlowDown) is still tried 4 times
S3FS_ATTEMPTS = 2


def scheme(url: str) -> str:
    """The scheme of a storage URL, lower case (``s3``, ``http``)."""
    return url.split("://", 1)[0].lower()


def _is_s3(url: str) -> bool:
    """Whether ``url`` is one s3fs serves (the deadlines below are its client's)."""
    return scheme(url) in ("s3", "s3a")


def with_deadlines(url: str, storage_options: dict | None) -> dict:
    """``storage_options`` for ``url`` with :data:`S3_DEADLINES` under
    ``config_kwargs`` for an S3 URL, each only where the options do not set
    it (the user's own timeouts and retries win)."""
    so = dict(storage_options or {})
    if not _is_s3(url):
        return so
    config = dict(so.get("config_kwargs") or {})
    for key, value in S3_DEADLINES.items():
        # a copy: the client may change what it is given, and the next call's options must be the same
        config.setdefault(key, copy.deepcopy(value))
    so["config_kwargs"] = config
    return so


def filesystem(url: str, storage_options: dict | None):
    """(filesystem, path) of ``url`` through fsspec, its client built (s3fs
    otherwise builds it at the first request). Options that are malformed
    (:func:`storage_option_problem`) or that the client refuses while it
    is built, before any request, are a BatchError of kind
    ``bad_arguments`` naming them; a store that cannot be reached is
    found by the first request, as before."""
    (fsspec,) = need("fsspec")
    why = storage_option_problem(storage_options)
    if why:
        raise BatchError(f"{url}: bad storage options ({why})", "bad_arguments")
    try:
        fs, path = fsspec.core.url_to_fs(url, **with_deadlines(url, storage_options))
    except ImportError as e:
        raise BatchError(f"{url}: no fsspec backend for this protocol is installed ({e}); "
                         f"{EXTRA} brings s3fs (s3://)", "bad_arguments") from None
    except (ValueError, TypeError) as e:
        raise BatchError(f"{url}: bad storage options ({e})", "bad_arguments") from None
    _build_client(fs, url)
    if hasattr(fs, "retries") and _is_s3(url):
        fs.retries = S3FS_ATTEMPTS
    return fs, path


#: fsspec protocols whose first path component is a bucket (a container)
#: that a write does not create
_BUCKET_STORES = ("s3", "s3a", "gs", "gcs", "az", "abfs", "abfss", "oss")


def check_output_bucket(url: str, storage_options: dict | None) -> None:
    """Refuses an output URL whose bucket does not exist, before any input
    is restored (each upload would fail after its restoration, every one
    naming its input instead of the bucket): one ``BatchError`` that
    names the bucket. A URL of a store without buckets passes."""
    fs, path = filesystem(url, storage_options)
    protocols = fs.protocol if isinstance(fs.protocol, (tuple, list)) else (fs.protocol,)
    bucket = path.strip("/").split("/", 1)[0]
    if not bucket or not any(p in _BUCKET_STORES for p in protocols):
        return
    # info, not exists: exists answers False for refused credentials too
    try:
        fs.info(bucket)
        there = True
    except FileNotFoundError:
        there = False
    except Exception as e:  # the storage itself: credentials, endpoint, permissions
        raise storage_error(e, url) from None
    if not there:
        raise BatchError(f"{url}: the output bucket does not exist (create it, or correct the URL); "
                         "no input was restored", "write_failed")


def _info_time(info: dict) -> float | None:
    """The modification time (seconds since the epoch) in an fsspec info
    record; each backend names it its own way."""
    when = info.get("LastModified") or info.get("mtime") or info.get("last_modified") or info.get("created")
    if isinstance(when, _dt.datetime):
        return when.timestamp()
    if isinstance(when, (int, float)):
        return float(when)
    return None


def on_storage(where: str, fn, *args, keep: tuple = (), **kwargs):
    """``fn(*args, **kwargs)``; when ``where`` is a storage URL, the storage
    client's own errors (unreachable, refused, no credentials) come out as a
    ``BatchError`` that names ``where`` and says what to do. Errors of
    the kinds in ``keep``, and every error of a local ``where``, pass as
    they are."""
    if not is_url(where):
        return fn(*args, **kwargs)
    try:
        return fn(*args, **kwargs)
    except (BatchError, *keep):
        raise
    except Exception as e:
        raise storage_error(e, where) from None


#: bytes asked of object storage in one request when an object is copied
#: (:func:`spool`): what memory holds of it at a time
CHUNK = 4 << 20


def _too_large(limit: int, where: str) -> OSError:
    return OSError(errno.EFBIG, f"larger than {limit} bytes", where)


def _refuse_larger(size, limit: int, where: str) -> None:
    """OSError EFBIG when ``size`` (bytes; not an int: unknown) is over ``limit``."""
    if isinstance(size, int) and size > limit:
        raise _too_large(limit, where)


def _read_object(fs, path: str, limit: int, where: str, size: int | None = None) -> bytes:
    """The bytes of the object ``path`` of ``fs``, at most ``limit`` of them
    (OSError EFBIG beyond). Its size (``size``, a listing's, else asked)
    refuses a large object before it is fetched; the fetch is one ranged
    read of ``limit + 1`` bytes, so a size that lies (the object replaced
    since it was listed, a hostile store) still brings no more."""
    if size is None:
        size = fs.info(path).get("size")
    _refuse_larger(size, limit, where)
    if size == 0:
        # a range of an empty object is refused (HTTP 416): nothing to fetch
        return b""
    data = fs.cat_file(path, start=0, end=limit + 1)
    if len(data) > limit:
        raise _too_large(limit, where)
    return data


def read_bytes(path: str, storage_options: dict | None = None, *, limit: int) -> bytes:
    """The bytes of a local regular file or a storage URL, at most
    ``limit`` of them: a larger one is an OSError (EFBIG) before more than
    ``limit + 1`` bytes are read."""
    if is_url(path):
        fs, p = filesystem(path, storage_options)
        return _read_object(fs, p, limit, path)
    return read_regular(path, limit, follow_links=True)


def spool(path: str, storage_options: dict | None = None, *, limit: int, digest=None):
    """A private copy of the object at the storage URL ``path``: a
    temporary file (gone when closed), open for reading at its start. At
    most ``limit`` bytes: a larger object is an OSError (EFBIG) before more
    than ``limit + 1`` bytes are fetched. The object comes :data:`CHUNK`
    bytes at a time, each fed to ``digest`` (a hashlib object) as it
    comes, so memory holds a chunk and never the object (a photo can be
    gigabytes)."""
    fs, p = filesystem(path, storage_options)
    _refuse_larger(fs.info(p).get("size"), limit, path)
    out = tempfile.TemporaryFile(prefix="uwhl-")
    try:
        for block in _chunks(fs, p, limit, path):
            if digest is not None:
                digest.update(block)
            out.write(block)
        out.seek(0)
        return out
    except BaseException:
        out.close()
        raise


def _chunks(fs, p: str, limit: int, where: str):
    """The object ``p`` of ``fs``, :data:`CHUNK` bytes at a time; more than
    ``limit`` bytes is an OSError (EFBIG) once ``limit + 1`` are fetched."""
    got = 0
    # block_size and no cache: each read is one ranged request of a chunk,
    # whatever default_block_size the storage options give
    with fs.open(p, "rb", block_size=CHUNK, cache_type="none") as f:
        while True:
            block = f.read(min(CHUNK, limit + 1 - got))
            if not block:
                return
            got += len(block)
            if got > limit:
                raise _too_large(limit, where)
            yield block


def download(url: str, local: str, storage_options: dict | None = None) -> None:
    """Copies the object at ``url`` to the local file ``local`` a chunk at
    a time: memory holds a chunk, never the object (fsspec's get_file held
    ten parts of 50 MiB at once on S3, more than a photo's own plan)."""
    fs, p = filesystem(url, storage_options)
    if scheme(url) in ("http", "https"):
        # a web server need not answer ranges (ranged reads fail past the first chunk);
        # fsspec streams its get_file in blocks
        fs.get_file(p, local)
        return
    with open(local, "wb") as out:
        for block in _chunks(fs, p, 1 << 62, url):
            out.write(block)


def sha256_of(f) -> str:
    """The SHA-256 (hex) of what is left to read of the binary file object
    ``f``, read a mebibyte at a time."""
    h = hashlib.sha256()
    for block in iter(lambda: f.read(1 << 20), b""):
        h.update(block)
    return h.hexdigest()


def open_regular(path: str, follow_links: bool = False):
    """The local regular file ``path`` opened for reading (a binary file
    object). A FIFO, device or socket is refused before it is opened (so
    nothing blocks and no device is touched), and so is a symbolic link at
    the last component unless ``follow_links`` (a file the user named
    himself); what is opened is checked again to be the file looked at.
    OSError otherwise, naming the path."""
    path = local_path(path)
    st = os.stat(path) if follow_links else os.lstat(path)
    if stat.S_ISLNK(st.st_mode):
        raise OSError(errno.ELOOP, "a symbolic link (not followed)", path)
    if not stat.S_ISREG(st.st_mode):
        raise OSError(errno.EINVAL, "not a regular file", path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    fd = os.open(path, flags)
    try:
        now = os.fstat(fd)
        if not stat.S_ISREG(now.st_mode) or (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):
            raise OSError(errno.EINVAL, "replaced while being opened", path)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str, limit: int | None = None, follow_links: bool = False) -> bytes:
    """The bytes of the local regular file ``path`` (:func:`open_regular`),
    at most ``limit`` of them: a larger file is an OSError (EFBIG) before
    more than ``limit + 1`` bytes are read."""
    with open_regular(path, follow_links) as f:
        if limit is not None and os.fstat(f.fileno()).st_size > limit:
            raise OSError(errno.EFBIG, f"larger than {limit} bytes", local_path(path))
        data = f.read(-1 if limit is None else limit + 1)
    if limit is not None and len(data) > limit:
        raise OSError(errno.EFBIG, f"larger than {limit} bytes", local_path(path))
    return data


def modified(path: str, storage_options: dict | None = None) -> float | None:
    """When a local file or a storage URL was last written (seconds since
    the epoch), None when it is not there; other storage errors propagate."""
    if is_url(path):
        fs, p = filesystem(path, storage_options)
        try:
            return _info_time(fs.info(p))
        except FileNotFoundError:
            return None
    try:
        return os.path.getmtime(local_path(path))
    except FileNotFoundError:
        return None


class Folder:
    """An output folder: ``root`` is a local path (or ``file://`` URL) or a
    storage URL, read and written with ``storage_options``."""

    def __init__(self, root, storage_options: dict | None = None):
        root = os.fspath(root)
        self.storage_options = storage_options or {}
        self.is_url = is_url(root)
        #: the sizes (bytes) of the files the last listings gave, by path relative to the folder
        self._sizes: dict[str, int] = {}
        if self.is_url:
            self.fs, path = filesystem(root, self.storage_options)
            self.root = path.rstrip("/")
            #: the folder as the user names it: its URL, or its absolute path
            self.display = root.rstrip("/")
        else:
            self.fs = None
            self.root = local_path(root)
            self.display = os.path.abspath(self.root)

    @property
    def name(self) -> str:
        """The folder's own name (the last part of its path)."""
        return posixpath.basename(self.display.rstrip("/")) or self.display

    def exists(self) -> bool:
        """Whether the folder is there (on object storage: holds anything)."""
        if self.is_url:
            return self.fs.isdir(self.root)
        return os.path.isdir(self.root)

    def path(self, rel: str) -> str:
        """The full local path or URL of ``rel`` (the form the readers of
        :func:`read_bytes` and :func:`modified` take)."""
        if self.is_url:
            return self.display + "/" + rel
        return os.path.join(self.root, *rel.split("/"))

    def files(self, under: str = "", skip_top: tuple[str, ...] = ()) -> list[tuple[str, float | None]]:
        """Every file under the folder (or its sub-folder ``under``) as
        (path relative to the folder, modification time), in the order of
        its path's parts; hidden files and folders, and the top-level
        folders ``skip_top``, are left out. One listing request on object
        storage."""
        found = []
        if self.is_url:
            top = self.root + ("/" + under.strip("/") if under else "")
            try:
                listing = self.fs.find(top, detail=True)
            except FileNotFoundError:
                listing = {}
            for path, info in listing.items():
                rel = path[len(self.root):].lstrip("/")
                parts = rel.split("/")
                if not rel or any(x.startswith(".") for x in parts) or (len(parts) > 1 and parts[0] in skip_top):
                    continue
                found.append((rel, _info_time(info)))
                if isinstance(info.get("size"), int):
                    self._sizes[rel] = info["size"]
        else:
            for d, dirs, names in os.walk(os.path.join(self.root, *under.split("/")) if under else self.root):
                rel_d = os.path.relpath(d, self.root)
                top = rel_d == "."
                dirs[:] = [x for x in dirs if not x.startswith(".") and not (top and x in skip_top)]
                for n in names:
                    if n.startswith("."):
                        continue
                    rel = n if top else "/".join([*rel_d.split(os.sep), n])
                    try:
                        found.append((rel, os.path.getmtime(os.path.join(d, n))))
                    except FileNotFoundError:  # removed while walking
                        continue
        found.sort(key=lambda f: tuple(f[0].split("/")))
        return found

    def read(self, rel: str, limit: int) -> bytes:
        """The bytes of ``rel``, at most ``limit`` of them (OSError EFBIG
        beyond, before more than ``limit + 1`` are read). Locally only a
        regular file, not through a symbolic link (:func:`read_regular`):
        what the folder holds is not trusted. On object storage the size of
        the last listing (else asked) refuses a large object unfetched."""
        if not self.is_url:
            return read_regular(self.path(rel), limit)
        return _read_object(self.fs, self.root + "/" + rel, limit, self.path(rel), self._sizes.get(rel))

    def head(self, rel: str, n: int) -> bytes:
        """The first ``n`` bytes of ``rel`` (fewer when it is shorter), as
        :meth:`read` takes the file: locally a regular file only, not
        through a link; on object storage one ranged read."""
        if not self.is_url:
            with open_regular(self.path(rel)) as f:
                return f.read(n)
        size = self._sizes.get(rel)
        if size is None:
            size = self.fs.info(self.root + "/" + rel).get("size")
        if size == 0:
            return b""  # a range of an empty object is refused (HTTP 416)
        return self.fs.cat_file(self.root + "/" + rel, start=0, end=n)[:n]

    def listed_size(self, rel: str) -> int | None:
        """The size in bytes the listing of :meth:`files` gave ``rel`` (object storage), or None."""
        return self._sizes.get(rel)

    def read_many(self, rels: list[str], limit: int) -> dict[str, bytes | Exception]:
        """The bytes of each of ``rels`` (as :meth:`read`), or the error
        that reading it raised (on object storage fetched concurrently, in
        one call: ranged reads of at most ``limit + 1`` bytes, the objects
        the listing says are larger not fetched)."""
        out: dict[str, bytes | Exception] = {}
        if not self.is_url:
            for rel in rels:
                try:
                    out[rel] = self.read(rel, limit)
                except OSError as e:
                    out[rel] = e
            return out
        fetch = []
        for rel in rels:
            size = self._sizes.get(rel)
            if size is None:
                try:  # not listed: asked alone
                    out[rel] = self.read(rel, limit)
                except Exception as e:
                    out[rel] = e
            elif size > limit:
                out[rel] = _too_large(limit, self.path(rel))
            elif size == 0:
                out[rel] = b""
            else:
                fetch.append(rel)
        # ranges, not cat: cat would read a name holding * ? or [ as a pattern
        got = self.fs.cat_ranges([self.root + "/" + rel for rel in fetch], 0, limit + 1,
                                 on_error="return") if fetch else []
        for rel, data in zip(fetch, got):
            if isinstance(data, bytes) and len(data) > limit:
                data = _too_large(limit, self.path(rel))
            out[rel] = data
        return {rel: out[rel] for rel in rels}

    def open(self, rel: str, limit: int):
        """``rel`` open for reading (a binary file object), at most
        ``limit`` bytes (OSError EFBIG beyond): locally the regular file
        itself (:func:`open_regular`), on object storage a private copy
        (:func:`spool`)."""
        if self.is_url:
            return spool(self.path(rel), self.storage_options, limit=limit)
        f = open_regular(self.path(rel))
        try:
            _refuse_larger(os.fstat(f.fileno()).st_size, limit, self.path(rel))
        except OSError:
            f.close()
            raise
        return f

    def modified(self, rel: str) -> float | None:
        """When ``rel`` was last written, None when it is not there."""
        return modified(self.path(rel), self.storage_options)

    def write(self, rel: str, data: bytes) -> str:
        """Writes ``rel`` whole or not at all (locally: a temporary file
        renamed; on object storage an object is stored in one request) and
        returns its full path or URL."""
        where = self.path(rel)
        if self.is_url:
            self.fs.pipe_file(self.root + "/" + rel, data)
            return where
        # the folders below the root are the program's own (report/thumbs):
        # one that is a link would carry the write elsewhere
        parts = rel.split("/")[:-1]
        for k in range(1, len(parts) + 1):
            d = os.path.join(self.root, *parts[:k])
            try:
                os.mkdir(d)
            except FileExistsError:
                pass
            if os.path.islink(d) or not os.path.isdir(d):
                raise OSError(errno.ELOOP if os.path.islink(d) else errno.ENOTDIR,
                              "a symbolic link or not a folder (not written through)", d)
        # the same exclusive temporary and durable rename as the photos
        # (files::commit): a link planted at a temporary's name is never opened
        def fill(tmp: str) -> None:
            fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))
            with os.fdopen(fd, "wb") as f:
                f.write(data)

        try:
            atomic_write_bytes(where, fill)
        except OSError as e:
            if e.filename:
                raise
            # the core's rename says "Is a directory (os error 21)" without the name it could not take
            raise OSError(e.errno, e.strerror or str(e), where) from None
        return where
