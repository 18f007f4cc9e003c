"""``--storage-option KEY=VALUE`` (``storage_options=`` in Python), the
fsspec options of URL inputs and outputs (docs/SCALE.md "Storage
options"): parsed, and checked for what can be told without a request.
s3fs builds its client at the first request, so a malformed option would
otherwise be said as a store that cannot be reached (exit 7), or not at
all (a negative block size made every input "not a JPEG, PNG...")."""

from __future__ import annotations

import json
import urllib.parse

from .errors import BatchError, shown

__all__ = ["parse_storage_options", "storage_option_problem", "is_option_error"]


def parse_storage_options(items: list[str] | None) -> dict:
    """``--storage-option KEY=VALUE`` values as fsspec storage options:
    values ``true``/``false``/``null`` and numbers are read as JSON, others
    kept as text; ``a.b=V`` nests (``client_kwargs.region_name=eu-west-1``)."""
    out: dict = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise BatchError(f"--storage-option {item!r} is not KEY=VALUE", "bad_arguments")
        try:
            v = json.loads(value) if value.strip() in ("true", "false", "null") or _is_number(value) else value
        except ValueError:
            v = value
        d = out
        *parents, leaf = key.split(".")
        if not all(x.strip() for x in [*parents, leaf]):
            # ".x" or "a..b" would hand the client an option named "" (or nest under one)
            raise BatchError(f"--storage-option {item!r}: a part of the key is empty (KEY or GROUP.KEY=VALUE)",
                             "bad_arguments")
        for p in parents:
            d = d.setdefault(p, {})
            if not isinstance(d, dict):
                raise BatchError(f"--storage-option {item!r}: {p} is given both as a value and as a group",
                                 "bad_arguments")
        d[leaf] = v
    why = storage_option_problem(out)
    if why:
        raise BatchError(f"--storage-option {why}", "bad_arguments")
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: options the program cannot take: it calls the storage synchronously
_REFUSED = {"asynchronous": "the program calls the storage synchronously",
            "loop": "the program runs the storage client's event loop itself"}
#: options that are groups of options (GROUP.KEY=VALUE), not values
_GROUPS = ("client_kwargs", "config_kwargs", "s3_additional_kwargs", "config_kwargs.retries")
#: options that are URLs of an endpoint
_URLS = ("endpoint_url", "client_kwargs.endpoint_url")
#: options that are whole numbers, and their least value
_WHOLE = {"default_block_size": 1, "max_concurrency": 1, "config_kwargs.max_pool_connections": 1,
          "config_kwargs.retries.max_attempts": 0, "config_kwargs.retries.total_max_attempts": 1}
#: options that are numbers of seconds, more than 0
_SECONDS = ("config_kwargs.connect_timeout", "config_kwargs.read_timeout")
#: options that are true or false
_FLAGS = ("anon", "use_ssl", "version_aware", "requester_pays", "cache_regions", "use_listings_cache",
          "skip_instance_cache", "fixed_upload_size")


def _option(options: dict, name: str):
    """(given, value) of the option ``name`` (dotted: a group's) in ``options``."""
    d = options
    for part in name.split("."):
        if not isinstance(d, dict) or part not in d:
            return False, None
        d = d[part]
    return True, d


def _is_endpoint(v) -> bool:
    """Whether ``v`` is an http(s) URL with a host (and a port, if any, that is one)."""
    if not isinstance(v, str):
        return False
    try:
        u = urllib.parse.urlsplit(v)
        u.port  # noqa: B018  (raises on a port that is no number or out of range)
    except ValueError:
        return False
    return u.scheme.lower() in ("http", "https") and bool(u.hostname)


def storage_option_problem(options: dict | None) -> str | None:
    """What is wrong with ``options`` (fsspec storage options) that can be
    told without a request, as ``NAME ...`` (the option and why), or None:
    an option named ``asynchronous`` or ``loop``; a group given a value; an
    endpoint that is not an http(s) URL with a host; a block size, count,
    retry count or timeout that is not a number in range; a flag that is
    not true or false. Other options are for the client to judge."""
    options = options or {}
    for name, why in _REFUSED.items():
        if name in options:
            return f"{name}: not an option to give ({why})"
    for name in _GROUPS:
        given, v = _option(options, name)
        if given and not isinstance(v, dict):
            return f"{name} is a group of options ({name}.KEY=VALUE), not a value ({shown(v)})"
    for name in _URLS:
        given, v = _option(options, name)
        if given and v is not None and not _is_endpoint(v):
            return f"{name} must be an http:// or https:// URL with a host, not {shown(v)}"
    for name, lo in _WHOLE.items():
        given, v = _option(options, name)
        if given and v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < lo):
            return f"{name} must be a whole number >= {lo}, not {shown(v)}"
    for name in _SECONDS:
        given, v = _option(options, name)
        if given and v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                                        or not 0 < v < float("inf")):
            return f"{name} must be a number of seconds > 0, not {shown(v)}"
    for name in _FLAGS:
        given, v = _option(options, name)
        if given and not isinstance(v, bool):
            return f"{name} must be true or false, not {shown(v)}"
    return None


#: errors of a storage client that say its options are wrong (botocore's, by
#: class name: the extra may be missing); its network errors are not among them
_OPTION_ERRORS = ("ProfileNotFound", "InvalidConfigError", "UnknownSignatureVersionError",
                  "InvalidRetryConfigurationError", "InvalidS3AddressingStyleError",
                  "InvalidEndpointConfigurationError", "InvalidProxiesConfigError", "ValidationError")


def is_option_error(e: BaseException) -> bool:
    """Whether ``e``, raised by a storage client, says that its options are
    wrong (a missing profile, a malformed region, retry mode or signature
    version) rather than that the store cannot be reached."""
    return any(c.__name__ in _OPTION_ERRORS for c in type(e).__mro__)
