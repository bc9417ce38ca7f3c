"""Running the jobs of a batch: one after another, on a local process pool, or on a Dask cluster.

Every executor runs :func:`ivslam_cli.fleet.job.run_job` on each job and hands its record to
``done`` as it completes; a job never raises (a broken log is an ``error`` record), and a
worker lost under a job (killed, out of memory) makes that job an ``error`` record too.

- ``sequential``: in this process.
- ``pool``: :class:`concurrent.futures.ProcessPoolExecutor` on the ``forkserver`` context,
  whose server imports ivslam once (:mod:`.preload`), so every worker starts from it with
  the modules loaded; the jitted kernels are compiled once into the on-disk cache (a cold
  cache: the first job of each mode runs alone first) and loaded from it by every worker.
- ``dask``: ``dask.distributed.Client(address).map`` on an existing cluster; the workers need
  ivslam installed and write the results to the output directory themselves, so its path
  (absolute) must be one they share with the client.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from typing import Any

from ivslam_cli.errors import IvslamError
from ivslam_cli.fleet.audit import error_record
from ivslam_cli.fleet.job import Job, run_job

Record = dict[str, Any]
Done = Callable[[int, Record], None]


def default_jobs() -> int:
    """The machine's cores (those this process may run on)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def run_sequential(jobs: Sequence[Job], done: Done) -> None:
    for i, job in enumerate(jobs):
        done(i, run_job(job))


def _lost(job: Job, exc: BaseException) -> Record:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return error_record(job, f"{job.label or job.log}: the worker running it was lost "
                             f"({type(exc).__name__}: {text})", 1, 0.0)


def _cache_is_warm(mode: str) -> bool:
    """True if the on-disk kernel cache holds kernels of ``mode``'s pipeline (its directories
    are named after the package: ``<mode>_<hash>``), so no worker compiles them."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    try:
        subdirs = [e for e in os.scandir(root) if e.is_dir() and e.name.startswith(f"{mode}_")] if root else []
        return any(f.endswith(".nbi") for e in subdirs for f in os.listdir(e.path))
    except OSError:
        return False


def run_pool(jobs: Sequence[Job], done: Done, workers: int) -> None:
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["ivslam_cli.fleet.preload"])
    order = list(range(len(jobs)))
    # a cold kernel cache: one job per such mode first, alone, so the kernels compile once
    first: list[int] = []
    seen: set[str] = set()
    for i in order:
        mode = jobs[i].opts.mode
        if mode not in seen and mode != "auto" and not _cache_is_warm(mode):
            first.append(i)
        seen.add(mode)
    rest = [i for i in order if i not in first]
    with ProcessPoolExecutor(max_workers=max(1, min(workers, len(jobs))), mp_context=ctx) as pool:
        try:
            for i in first:
                fut = pool.submit(run_job, jobs[i])
                try:
                    rec = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker fails its job alone
                    rec = _lost(jobs[i], exc)
                done(i, rec)
            futures = {pool.submit(run_job, jobs[i]): i for i in rest}
            pending = set(futures)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    i = futures[fut]
                    try:
                        rec = fut.result()
                    except Exception as exc:  # noqa: BLE001
                        rec = _lost(jobs[i], exc)
                    done(i, rec)
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def connect(address: str):
    """A ``dask.distributed.Client`` on the scheduler at ``address``; one-line errors."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise IvslamError("--scheduler needs dask.distributed: pip install 'ivslam[fleet]'") from None
    try:
        return Client(address, timeout="20s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        text = " ".join(str(exc).split())[:200]
        raise IvslamError(f"cannot connect to the Dask scheduler ({type(exc).__name__}: {text})",
                          address) from None


def run_dask(jobs: Sequence[Job], done: Done, client) -> None:
    """Run ``jobs`` on the cluster of ``client`` (see :func:`connect`), then close it."""
    from dask.distributed import as_completed

    try:
        futures = client.map(run_job, list(jobs), pure=False,
                             key=[f"ivslam-run-{i}-{os.getpid()}-{id(jobs)}" for i in range(len(jobs))])
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for fut in as_completed(futures, loop=client.loop):
                i = index[fut.key]
                try:
                    rec = fut.result()
                except Exception as exc:  # noqa: BLE001 - KilledWorker, a lost connection
                    rec = _lost(jobs[i], exc)
                done(i, rec)
        except BaseException:
            client.cancel(futures)
            raise
    finally:
        client.close()


def run_jobs(jobs: Sequence[Job], done: Done, *, workers: int, scheduler: str | None, client=None) -> str:
    """Run ``jobs`` (on ``client``'s cluster when ``scheduler`` is given); returns the executor's
    description (for the audit)."""
    if scheduler is not None or (workers > 1 and len(jobs) > 1):
        jobs = [dataclasses.replace(j, opts=j.opts.replace(threads=1)) for j in jobs]  # in parallel over the logs
    if scheduler is not None:
        run_dask(jobs, done, client if client is not None else connect(scheduler))
        return f"dask {scheduler}"
    if workers <= 1 or len(jobs) <= 1:
        run_sequential(jobs, done)
        return "sequential"
    run_pool(jobs, done, workers)
    return "process pool"
