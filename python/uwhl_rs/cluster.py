"""Batches on a Dask cluster: the cluster started or reached
(``--dask local:N`` or a scheduler's address), the workers checked, and
the inputs submitted as tasks (``tasks.restore_items``), each asking for
the memory its inputs' plans need (docs/SCALE.md "Memory").

distributed is the optional extra ``uwhl_rs[dask]``, imported only here
and only when a batch runs on a cluster.
"""

from __future__ import annotations

import importlib.metadata
import os
import threading

import uwhl_rs

from . import _core
from .errors import EXIT, BatchError
from .storage import need
from .tasks import MEMORY, Item, probe, restore_items, row

__all__ = ["connect", "check_workers", "runs_elsewhere", "run_on_cluster"]

#: inputs whose header one planning task reads
_PROBE_BATCH = 32


def _from_a_script() -> bool:
    """Whether this process runs a script of the user's (``python x.py``),
    rather than the ``uwhl`` command or an interactive session."""
    import sys
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    return (bool(getattr(main, "__file__", None)) and not (spec and spec.name.startswith("uwhl_rs"))
            and os.path.basename(sys.argv[0] if sys.argv else "") != "uwhl")


def connect(client, dask: str | None, threads: int | None):
    """(client, cluster to close or None, threads for the core) for ``dask``
    (None: ``client`` as given, or in this process)."""
    if client is not None or dask is None:
        return client, None, threads
    (distributed,) = need("distributed")
    if dask == "local" or dask.startswith("local:"):
        n = int(dask.split(":", 1)[1]) if ":" in dask else max(1, (os.cpu_count() or 1))
        from distributed.system import MEMORY_LIMIT

        cores = os.cpu_count() or 1
        # Dask's own share of the machine (cgroups and ulimit counted); a
        # task may plan up to 80% of it, where Dask would pause the worker
        memory = int(MEMORY_LIMIT // n)
        try:
            cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                               memory_limit=memory, resources={MEMORY: int(memory * 0.8)},
                                               dashboard_address="127.0.0.1:0", host="127.0.0.1",
                                               silence_logs=40)
        except (Exception, MemoryError) as e:
            # the common cause from a script: its workers import it (spawn)
            # and, unguarded, start the batch again; the real cause is chained
            hint = ("; a script that starts it calls restore_many under `if __name__ == \"__main__\":` (docs/API.md)"
                    if _from_a_script() else "")
            raise BatchError(f"--dask {dask}: the local cluster's workers did not start "
                             f"({type(e).__name__}: {e}){hint}") from e
        return distributed.Client(cluster), cluster, threads if threads is not None else max(1, cores // n)
    address = dask if "://" in dask else f"tcp://{dask}"
    timeout = _timeout()
    _handshake(address, dask, timeout)
    try:
        c = distributed.Client(address, timeout=timeout)
    except (OSError, TimeoutError) as e:
        raise BatchError(f"--dask {dask}: cannot reach the Dask scheduler ({type(e).__name__}: {e})") from None
    except (Exception, MemoryError) as e:  # it answered the handshake, then something that is not Dask
        raise BatchError(f"--dask {dask}: the Dask scheduler's answer cannot be read "
                         f"({type(e).__name__}: {str(e)[:200]})") from None
    return c, None, threads


def _timeout() -> float:
    """UWHL_DASK_TIMEOUT, seconds (default 10): how long the scheduler has to answer."""
    raw = os.environ.get("UWHL_DASK_TIMEOUT", "10")
    try:
        t = float(raw)
    except ValueError:
        t = float("nan")
    if not 0 < t < 1e6:
        raise BatchError(f"UWHL_DASK_TIMEOUT={raw!r}: a number of seconds > 0", "bad_arguments")
    return t


def _handshake(address: str, dask: str, timeout: float) -> None:
    """Connects to ``address`` and completes Dask's handshake (its first
    message each way) within ``timeout`` seconds in all, then closes. The
    Client's own timeout covers only the connect: a server that accepts and
    never answers (an HTTP server, a silent port) would hold it for good,
    and one that sends other bytes makes distributed read them as a frame
    length (exabytes). Either is refused here, naming the address."""
    import asyncio

    from distributed.comm import connect as dask_connect

    async def shake():
        comm = await dask_connect(address, timeout=timeout)
        await comm.close()

    def run():
        # a loop of its own, in a thread: the caller may be inside a running event loop (a notebook)
        try:
            asyncio.run(asyncio.wait_for(shake(), timeout))
        except BaseException as e:
            failed.append(e)

    failed: list[BaseException] = []
    t = threading.Thread(target=run, name="uwhl-dask-handshake", daemon=True)
    t.start()
    t.join(2 * timeout + 5)  # wait_for ends it at timeout; this only guards a cancellation that hangs
    try:
        if t.is_alive():
            raise TimeoutError
        if failed:
            raise failed[0]
    except (TimeoutError, asyncio.TimeoutError):
        # the same words as a refused connect: when nothing listens, either deadline may come first
        raise BatchError(f"--dask {dask}: cannot reach the Dask scheduler (no answer within {timeout:g} s: not "
                         "running, not a Dask scheduler, or slower than UWHL_DASK_TIMEOUT)") from None
    except OSError as e:
        raise BatchError(f"--dask {dask}: cannot reach the Dask scheduler ({type(e).__name__}: {e})") from None
    except (Exception, MemoryError) as e:
        # MemoryError: other bytes read as a frame length; the rest: a frame that is not Dask's
        raise BatchError(f"--dask {dask}: the server does not speak Dask's protocol (its answer cannot be read: "
                         f"{type(e).__name__}: {str(e)[:200]})") from None


def check_workers(client) -> None:
    """The workers have this uwhl_rs (another version would write other
    outputs; none would fail every task)."""
    try:
        found = client.run(importlib.metadata.version, "uwhl_rs", on_error="return")
    except Exception as e:
        raise BatchError(f"cannot ask the Dask workers for their uwhl_rs ({type(e).__name__}: {e})") from None
    if not found:
        raise BatchError("the Dask cluster has no workers")
    wrong = {w: v for w, v in found.items() if v != uwhl_rs.__version__}
    if wrong:
        w, v = sorted(wrong.items())[0]
        v = "no uwhl_rs" if isinstance(v, BaseException) else f"uwhl_rs {v}"
        raise BatchError(f"{len(wrong)} of {len(found)} Dask workers do not run uwhl_rs {uwhl_rs.__version__} "
                         f"(worker {w}: {v}); install the same version on the workers", "bad_arguments")


def runs_elsewhere(client) -> bool:
    """Whether some worker runs in another folder than this process (a
    worker started by hand elsewhere, or on another machine): relative
    paths would name other files there. Workers of ``--dask local:N`` run
    here."""
    try:
        folders = client.run(os.getcwd, on_error="return")
    except Exception:
        return True  # not known: paths that hold anywhere
    here = os.getcwd()
    return any(f != here for f in folders.values())


def _largest_worker_memory(client) -> int | None:
    """The largest MEMORY resource of the workers, or None when some worker
    has none (then tasks ask for no resource, and each worker checks its
    own limit)."""
    info = client.scheduler_info().get("workers", {})
    values = [w.get("resources", {}).get(MEMORY) for w in info.values()]
    if not values or any(v is None for v in values):
        return None
    return max(int(v) for v in values)


#: the run whose task a worker process ran last
_LAST_RUN: list[str | None] = [None]


def _restore_in_run(run: str, *args) -> list[dict]:
    """Task: :func:`tasks.restore_items` as part of ``run``. A worker serves
    one run after another: at its first task of a run the ``--water-from``
    folders and ``--altitude`` logs are read again (an earlier run read them as they were then)."""
    if run != _LAST_RUN[0]:
        _LAST_RUN[0] = run
        _core.new_run()
    return restore_items(*args)


def run_on_cluster(c, groups: list[list[Item]], opts, so, overwrite, reuse, reuse_wm, settle) -> None:
    """Submits the planning and restoring tasks and settles each input as
    its task completes. A task whose worker died is retried by the
    scheduler (its ``allowed-failures``); one that kept killing workers is
    reported failed with the reason."""
    from distributed import as_completed

    budget = _largest_worker_memory(c)
    run = os.urandom(8).hex()  # the tasks of this run: a worker reads --water-from and --altitude logs again when a new run starts
    pending = as_completed()
    meta = {}  # future key -> ("probe"|"restore", payload)

    def submit_restore(g: list[Item]):
        most = max((it.need or 0) for it in g)
        if budget is not None and most > budget:
            for it in g:
                settle(it.index, row(it, "failed", error_kind="over_budget", exit_code=EXIT["over_budget"],
                                     worker=None, error=f"needs about {most} bytes, over every worker's "
                                     f"memory ({budget} bytes); use --max-side or larger workers"))
            return
        kw = {"resources": {MEMORY: most}} if budget is not None and most > 0 else {}
        f = c.submit(_restore_in_run, run, g, opts, so, overwrite, reuse, reuse_wm, pure=False,
                     key=f"uwhl-restore-{g[0].index}-{os.urandom(4).hex()}", **kw)
        meta[f.key] = ("restore", g)
        pending.add(f)

    if budget is not None:
        # a group is submitted once the headers of all its items are read:
        # per group, how many are still unread
        unread = {id(g): len(g) for g in groups}
        group_of = {it.index: g for g in groups for it in g}
        flat = [it for g in groups for it in g]
        item_of = {it.index: it for it in flat}
        for i in range(0, len(flat), _PROBE_BATCH):
            chunk = [(it.index, it.input) for it in flat[i:i + _PROBE_BATCH]]
            f = c.submit(probe, chunk, opts, so, pure=False, key=f"uwhl-probe-{chunk[0][0]}-{os.urandom(4).hex()}")
            meta[f.key] = ("probe", chunk)
            pending.add(f)
    else:
        for g in groups:
            submit_restore(g)
    try:
        for f in pending:
            what, payload = meta.pop(f.key)
            try:
                result = f.result()
            except Exception as e:  # the task itself never raises: its worker died, or it was cancelled
                if what == "probe":
                    result = [(k, None) for k, _ in payload]
                else:
                    for it in payload:
                        settle(it.index, _lost_row(it, e))
                    continue
            if what == "probe":
                for k, planned in result:
                    item_of[k].need = planned
                    g = group_of[k]
                    unread[id(g)] -= 1
                    if unread[id(g)] == 0:
                        submit_restore(g)
            else:
                for it, r in zip(payload, result):
                    settle(it.index, r)
    except KeyboardInterrupt:
        for f in list(pending.futures):
            f.cancel()
        raise


def _lost_row(item: Item, e: BaseException) -> dict:
    name = type(e).__name__
    if name == "KilledWorker":
        why = ("the workers running it died every time it was tried (killed, out of memory or preempted): "
               f"{e}")
    else:
        why = f"the task was lost ({name}: {e})"
    return row(item, "failed", error_kind="internal", error=why, exit_code=EXIT["internal"], worker=None)
