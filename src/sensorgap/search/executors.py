"""Where search batches are evaluated: in this process (threads) or on Dask distributed.

A batch of decoded candidates is split into chunks; each chunk is evaluated by
``evaluate_chunk(spec, family, decoded)``, a top-level function a Dask worker can run: it
rebuilds (and caches per worker process) the ``SearchProblem`` from a light, picklable
``ProblemSpec`` (vehicle, families, environments, mode, detection rule, sun search). The
chunks' results are concatenated in order, so the outcome does not depend on the executor
or the number of workers (same seed -> same ranking; tested).
"""

from __future__ import annotations

import contextlib
import logging
import re
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.config import load_environments
from sensorgap.errors import InputError
from sensorgap.models import load_system
from sensorgap.runtime import (
    children_spared_stop_signals,
    start_resource_tracker,
    tune_allocator,
)
from sensorgap.scenarios import load_families
from sensorgap.search.evaluate import DetectionRule, Evaluator
from sensorgap.search.problem import BatchOutcome, Decoded, SearchProblem


@dataclass(frozen=True)
class ProblemSpec:
    """Everything a worker needs to rebuild the search problems (hashable, picklable)."""

    vehicle: str
    families: tuple[str, ...]
    environments: tuple[str, ...]
    environments_file: str | None
    mode: str
    detection: str
    sun_search: bool

    def build(self) -> dict[str, SearchProblem]:
        """The problems, one per family."""
        all_envs = load_environments(
            Path(self.environments_file) if self.environments_file else None
        )
        envs = {e: all_envs[e] for e in self.environments}
        evaluator = Evaluator(
            load_system(self.vehicle), mode=self.mode, rule=DetectionRule.parse(self.detection)
        )
        return {
            f.name: SearchProblem(f, envs, evaluator, self.sun_search)
            for f in load_families(list(self.families))
        }


_CACHE: dict[ProblemSpec, dict[str, SearchProblem]] = {}
_LOCK = threading.Lock()


def problems_for(spec: ProblemSpec) -> dict[str, SearchProblem]:
    """The problems of ``spec``, built once per process."""
    with _LOCK:
        if spec not in _CACHE:
            _CACHE.clear()
            _CACHE[spec] = spec.build()
        return _CACHE[spec]


def evaluate_chunk(
    spec: ProblemSpec, family: str, decoded: Decoded, threads: int = 1
) -> BatchOutcome:
    """Evaluate decoded candidates of one family (runs on a worker)."""
    tune_allocator()  # a Dask worker process: as the command line does
    return problems_for(spec)[family].evaluate_decoded(decoded, threads=threads)


def _concat(outs: Sequence[BatchOutcome]) -> BatchOutcome:
    if len(outs) == 1:
        return outs[0]
    return BatchOutcome(
        {m: np.concatenate([o.metrics[m] for o in outs]) for m in outs[0].metrics},
        np.concatenate([o.feasible for o in outs]),
        [n for o in outs for n in o.notes],
        np.concatenate([o.objective for o in outs if o.objective is not None]),
    )


class Executor:
    """Evaluates batches in this process (``threads`` per batch)."""

    name = "local"

    def __init__(self, threads: int = 2) -> None:
        self.threads = threads

    def evaluate(self, spec: ProblemSpec, problem: SearchProblem, decoded: Decoded) -> BatchOutcome:
        """The outcome of a batch (same order)."""
        return problem.evaluate_decoded(decoded, threads=self.threads)

    def close(self) -> None:
        """Release resources."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _quiet_dask_logs() -> None:
    """No more log lines of Dask (``distributed``), ``asyncio`` and ``tornado`` in this
    process: once its work is abandoned (a stop signal, an error), their loop thread logs
    what it was doing ("Task exception was never retrieved" with a traceback, workers
    closed or killed); the command says it stopped, in one line."""
    for name in ("distributed", "asyncio", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


@contextlib.contextmanager
def _dask_logs_quiet() -> Iterator[None]:
    """No log lines of Dask, ``asyncio`` and ``tornado`` while the block runs (their
    levels put back after it): a peer that is no Dask scheduler made Dask log a CRITICAL
    line with a traceback before the command's one line (hostile round 29)."""
    loggers = [logging.getLogger(n) for n in ("distributed", "asyncio", "tornado")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def _kind(exc: BaseException) -> str:
    """An exception's class name, with its module when it is not a builtin one
    (``struct.error``, not ``error``)."""
    cls = type(exc)
    return cls.__name__ if cls.__module__ == "builtins" else f"{cls.__module__}.{cls.__name__}"


def _remote_client(client_cls: Any, address: str, timeout_s: float) -> Any:
    """A Dask client of the scheduler at ``address``, connected within ``2 * timeout_s``
    (s) or ``InputError``: Dask bounds the connection by ``timeout_s`` but not the
    handshake after it (hostile round 29: a server that accepted and never answered hung
    the search forever). Whatever else goes wrong there (bytes that are no Dask message:
    ``struct.error``, a frame of EiB: ``MemoryError``...) is one line naming the address;
    a scheduler without workers is refused (its tasks would wait forever)."""
    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = client_cls(address, timeout=timeout_s)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    with _dask_logs_quiet():
        worker = threading.Thread(target=connect, name="sensorgap-dask-connect", daemon=True)
        worker.start()
        worker.join(2.0 * timeout_s)
    if worker.is_alive():
        raise InputError(
            "scheduler",
            "",
            f"{address!r} did not answer as a Dask scheduler within {2.0 * timeout_s:g} s "
            "(it accepted the connection, then said nothing); name the address of a "
            "running dask scheduler",
        )
    exc = box.get("error")
    if isinstance(exc, (OSError, TimeoutError)):
        raise InputError(
            "scheduler", "", f"cannot reach the Dask scheduler {address!r}: {exc}"
        ) from None
    if isinstance(exc, Exception):
        raise InputError(
            "scheduler",
            "",
            f"{address!r} did not answer as a Dask scheduler ({_kind(exc)}); "
            "name the address of a running dask scheduler",
        ) from None
    if exc is not None:  # a stop signal
        raise exc
    client = box["client"]
    try:
        workers = client.scheduler_info().get("workers", {})
    except Exception as err:  # noqa: BLE001 - the scheduler went away
        client.close()
        raise InputError(
            "scheduler", "", f"the Dask scheduler {address!r} stopped answering: {err}"
        ) from None
    if not workers:
        client.close()
        raise InputError(
            "scheduler",
            "",
            f"the Dask scheduler {address!r} has no workers (its tasks would wait for "
            "ever); start workers for it (dask worker ADDRESS) first",
        )
    return client


class DaskExecutor(Executor):
    """Evaluates batches on Dask distributed: a scheduler at ``address``, or a local
    cluster of ``workers`` processes (one thread each) when no address is given."""

    name = "dask"

    def __init__(
        self, address: str | None = None, workers: int = 2, timeout_s: float = 10.0
    ) -> None:
        super().__init__(threads=1)
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError(
                "executor", "", "dask is not installed: pip install 'sensorgap[distributed]'"
            ) from None
        self._cluster: Any = None
        try:
            if address:
                self.client = _remote_client(Client, address, timeout_s)
            else:
                # its processes (and its event loop's thread) spared the stop signals of
                # the process group; each worker leaves the group (search.daskworker)
                start_resource_tracker()
                try:
                    with children_spared_stop_signals():
                        self._cluster = LocalCluster(
                            n_workers=workers,
                            threads_per_worker=1,
                            processes=True,
                            dashboard_address=None,
                            preload=["sensorgap.search.daskworker"],
                            # the workers' own log (a task cancelled as the command
                            # stops, a lost scheduler) is not the command's to print:
                            # their errors reach it through the tasks
                            silence_logs=logging.CRITICAL,
                            # no dashboard; the scheduler's HTTP server (health routes)
                            # on a free local port: its default, 8787, held by another
                            # cluster (a second search) printed a UserWarning
                            scheduler_kwargs={
                                "dashboard": False,
                                "dashboard_address": "127.0.0.1:0",
                            },
                        )
                        self.client = Client(self._cluster)
                except BaseException:  # a stop signal delivered at the block's end too
                    self._close(quiet=True)
                    raise
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(
                "scheduler", "", f"cannot reach the Dask scheduler {address!r}: {exc}"
            ) from None
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})) or workers)

    def evaluate(self, spec: ProblemSpec, problem: SearchProblem, decoded: Decoded) -> BatchOutcome:
        n = len(decoded)
        chunks = max(1, min(self.workers * 2, -(-n // 256)))
        bounds = np.linspace(0, n, chunks + 1).astype(int)
        parts = [
            decoded.take(np.arange(a, b))
            for a, b in zip(bounds[:-1], bounds[1:], strict=True)
            if b > a
        ]
        futures = self.client.map(
            evaluate_chunk,
            [spec] * len(parts),
            [problem.family.name] * len(parts),
            parts,
            pure=False,
        )
        try:
            return _concat(self.client.gather(futures))
        except BaseException:  # a stop signal, an error: the work is abandoned
            _quiet_dask_logs()
            raise

    def close(self) -> None:
        self._close(quiet=False)

    def _close(self, quiet: bool) -> None:
        """Close the client and the local cluster (what of them was made). ``quiet``: the
        command is stopping (a stop signal, an error): ``_quiet_dask_logs`` first."""
        if quiet:
            _quiet_dask_logs()
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __exit__(self, *exc: object) -> None:
        self._close(quiet=exc[0] is not None)


_ADDRESS = re.compile(
    r"^(?:(?:tcp|ws)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
    r":(\d{1,5})$"
)
#: Dask protocols that need settings sensorgap does not pass (TLS certificates, UCX).
_UNSUPPORTED = re.compile(r"^(tls|wss|ucx)://", re.IGNORECASE)


def check_scheduler_address(address: str) -> str:
    """A Dask scheduler address ``[protocol://]host:port`` (protocol tcp or ws; port
    1..65535); anything else -> ``InputError`` before anything is started. tls://, wss://
    and ucx:// are refused: they need TLS certificates or UCX, which sensorgap does not
    configure (hostile round 28: internal errors, an empty store left)."""
    bad = _UNSUPPORTED.match(address)
    if bad is not None:
        raise InputError(
            "scheduler",
            "",
            f"{bad.group(1).lower()}:// needs "
            f"{'UCX' if bad.group(1).lower() == 'ucx' else 'TLS certificates'}, which "
            "sensorgap does not configure; use tcp://host:port or ws://host:port (e.g. "
            f"through an SSH tunnel), got {address!r}",
        )
    m = _ADDRESS.match(address)
    if m is None or not 1 <= int(m.group(1)) <= 65535:
        raise InputError(
            "scheduler", "", f"expected a scheduler address like tcp://host:8786, got {address!r}"
        )
    return address


def make_executor(name: str, scheduler: str | None = None, workers: int = 2) -> Executor:
    """``local`` (threads) or ``dask``; ``InputError`` for anything else."""
    if name == "local":
        return Executor(threads=workers)
    if name == "dask":
        return DaskExecutor(scheduler, workers)
    raise InputError("executor", "", f"must be local or dask, got {name!r}")
