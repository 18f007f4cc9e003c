"""A finished batch's output folder as its readers see it (``uwhl report``,
``uwhl ifdo``): on the local disk or at an object-storage URL through
fsspec (docs/SCALE.md), with one set of operations for both, so a page or
an iFDO is made the same way wherever the batch wrote.

Paths inside the folder are relative and ``/``-separated.
"""

from __future__ import annotations

import os
import posixpath

__all__ = ["Folder", "read_bytes", "modified", "on_storage"]


def _is_url(path: str) -> bool:
    from .batch import is_url

    return is_url(path)


def _fs(url: str, storage_options: dict | None):
    from .batch import _fs as fs_of

    return fs_of(url, storage_options or {})


def _info_time(info: dict) -> float | None:
    """The modification time (seconds since the epoch) in an fsspec info
    record; each backend names it its own way."""
    import datetime as _dt

    when = info.get("LastModified") or info.get("mtime") or info.get("last_modified") or info.get("created")
    if isinstance(when, _dt.datetime):
        return when.timestamp()
    if isinstance(when, (int, float)):
        return float(when)
    return None


def on_storage(where: str, fn, *args, keep: tuple = (), **kwargs):
    """``fn(*args, **kwargs)``; when ``where`` is a storage URL, the storage
    client's own errors (unreachable, refused, no credentials) come out as a
    ``batch.BatchError`` that names ``where`` and says what to do. Errors of
    the kinds in ``keep``, and every error of a local ``where``, pass as
    they are."""
    if not _is_url(where):
        return fn(*args, **kwargs)
    from .batch import BatchError, _storage_error

    try:
        return fn(*args, **kwargs)
    except (BatchError, *keep):
        raise
    except Exception as e:
        raise _storage_error(e, where) from None


def read_bytes(path: str, storage_options: dict | None = None) -> bytes:
    """The bytes of a local file or a storage URL."""
    from .batch import _local

    if _is_url(path):
        fs, p = _fs(path, storage_options)
        return fs.cat_file(p)
    with open(_local(path), "rb") as f:
        return f.read()


def modified(path: str, storage_options: dict | None = None) -> float | None:
    """When a local file or a storage URL was last written (seconds since
    the epoch), None when it is not there; other storage errors propagate."""
    from .batch import _local

    if _is_url(path):
        fs, p = _fs(path, storage_options)
        try:
            return _info_time(fs.info(p))
        except FileNotFoundError:
            return None
    try:
        return os.path.getmtime(_local(path))
    except FileNotFoundError:
        return None


class Folder:
    """An output folder: ``root`` is a local path (or ``file://`` URL) or a
    storage URL, read and written with ``storage_options``."""

    def __init__(self, root, storage_options: dict | None = None):
        from .batch import _local

        root = os.fspath(root)
        self.storage_options = storage_options or {}
        self.is_url = _is_url(root)
        if self.is_url:
            self.fs, path = _fs(root, self.storage_options)
            self.root = path.rstrip("/")
            #: the folder as the user names it: its URL, or its absolute path
            self.display = root.rstrip("/")
        else:
            self.fs = None
            self.root = _local(root)
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

    def read(self, rel: str) -> bytes:
        """The bytes of ``rel``."""
        return read_bytes(self.path(rel), self.storage_options)

    def read_many(self, rels: list[str]) -> dict[str, bytes | Exception]:
        """The bytes of each of ``rels``, or the error that reading it
        raised (on object storage fetched concurrently, in one call)."""
        if not self.is_url:
            got: dict[str, bytes | Exception] = {}
            for rel in rels:
                try:
                    got[rel] = self.read(rel)
                except OSError as e:
                    got[rel] = e
            return got
        full = {self.root + "/" + rel: rel for rel in rels}
        fetched = self.fs.cat(list(full), on_error="return") if full else {}
        return {rel: fetched.get(path, FileNotFoundError(2, "not found", path)) for path, rel in full.items()}

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
        os.makedirs(os.path.dirname(where) or ".", exist_ok=True)
        tmp = os.path.join(os.path.dirname(where), f".{os.path.basename(where)}.{os.getpid()}.tmp")
        try:
            with open(tmp, "wb") as f:
                f.write(data)
            os.replace(tmp, where)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return where
