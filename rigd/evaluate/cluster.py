"""Evaluation trials on a Dask distributed cluster: ``rigd evaluate ... --cluster tcp://host:8786``.

Dask rather than Ray: two pure-Python wheels of about 1.5 MB and 1 MB (Ray's is about 79 MB, both x86-64 and
aarch64), whose few compiled dependencies (psutil, msgpack, tornado) have aarch64 wheels; a scheduler and a
worker each start in about a second, which keeps the cluster test short; and a team points it at machines with
two commands (``dask scheduler``, ``dask worker tcp://host:8786``) and no cluster manager. docs/evaluation.md.

Features are computed once per worker process, not per trial: each worker keeps the features of the last
(dataset path and files' stamp, settings) it was asked for in a module-level cache, filled by its first trial
under a lock (a worker with several threads extracts once and its threads share the features). A new dataset
replaces them, so a long-lived worker holds one dataset's features at a time. Every task carries this client's
:func:`code_version`; a worker with other sources or numerical libraries refuses it, since the results would
not be those of a local run.
"""

from __future__ import annotations

import hashlib
import importlib
import threading
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TypeVar

import cv2
import numpy as np
import scipy
from distributed import Client, KilledWorker, as_completed, get_worker
from distributed.comm.addressing import parse_address, parse_host_port
from distributed.comm.registry import get_backend

from rigd.calibration.request import CalibrationRequest
from rigd.errors import RigdError
from rigd.evaluate.trials import WorkerState, collect, extract_state

T = TypeVar("T")
R = TypeVar("R")


@dataclass(frozen=True)
class FeatureKey:
    """What a worker's features depend on: the request (its dataset's path must be the same on every worker);
    ``stamp`` (:func:`dataset_stamp`) changes when the dataset is rewritten at the same path."""

    request: CalibrationRequest
    stamp: str


def dataset_stamp(root: Path) -> str:
    """A hash of the names, sizes and modification times of rig.yaml and every file under pairs/."""
    digest = hashlib.sha256()
    for path in sorted([root / "rig.yaml", *(p for p in (root / "pairs").rglob("*") if p.is_file())]):
        stat = path.stat()
        digest.update(f"{path.relative_to(root).as_posix()}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()[:16]


@cache
def code_version() -> tuple[tuple[str, str], ...]:
    """What a trial's result depends on besides its inputs: the sources of calib and rigd (sha256 of the .py
    files) and the numerical libraries' versions."""
    digest = hashlib.sha256()
    for name in ("calib", "rigd"):
        package = Path(importlib.import_module(name).__file__ or "").parent
        for path in sorted(package.rglob("*.py")):
            digest.update(path.relative_to(package.parent).as_posix().encode() + b"\0" + path.read_bytes())
    return (("sources", digest.hexdigest()[:16]), ("numpy", np.__version__), ("scipy", scipy.__version__),
            ("opencv", cv2.__version__))


# Worker side: one cache per worker process, shared by its threads.
_LOCK = threading.Lock()
_CACHED: tuple[FeatureKey, WorkerState] | None = None
_COUNTS: Counter[str] = Counter()  # "extractions" and "tasks" of this worker: worker_counts()


def worker_counts() -> dict[str, int]:
    """How often this worker process extracted features and how many trials it ran (run it on the workers with
    ``Client.run``)."""
    with _LOCK:
        return dict(_COUNTS)


def _features(key: FeatureKey) -> WorkerState:
    global _CACHED
    with _LOCK:
        _COUNTS["tasks"] += 1
        if _CACHED is None or _CACHED[0] != key:
            _CACHED = None  # free the previous dataset's features before extracting the next
            cv2.setNumThreads(1)  # one trial per core: the workers already occupy the cores
            _CACHED = (key, extract_state(key.request))
            _COUNTS["extractions"] += 1
        return _CACHED[1]


def _on_worker(key: FeatureKey, client_code: tuple[tuple[str, str], ...], fn: Callable[[WorkerState, T], R],
               task: T) -> R:
    here = get_worker().address
    mine = code_version()
    if client_code != mine:
        differ = ", ".join(f"{k}: client {theirs}, worker {ours}"
                           for (k, theirs), (_, ours) in zip(client_code, mine, strict=True) if theirs != ours)
        raise RigdError(f"worker {here} runs other code than the client ({differ}): install the same rigd and "
                        "libraries on every worker")
    state = _features(key)
    if state.error is not None:
        raise RigdError(f"on worker {here}: {state.error}")
    return fn(state, task)


class DaskCluster:
    """The workers of the Dask scheduler at ``address`` (a :class:`rigd.evaluate.pools.TrialRunner`)."""

    def __init__(self, address: str, timeout_s: float, request: CalibrationRequest) -> None:
        self._address = address
        try:
            scheme, location = parse_address(address)
            get_backend(scheme)
            if scheme in ("tcp", "tls"):
                parse_host_port(location)
        except ValueError as exc:
            raise RigdError(f"--cluster {address}: not a scheduler address like tcp://host:8786 ({exc})") from exc
        try:
            self._client = Client(address, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise RigdError(f"--cluster {address}: no Dask scheduler answered within {timeout_s:g} s ({exc}); "
                            "start one with `dask scheduler` and workers with `dask worker ADDRESS`") from exc
        try:
            self._client.wait_for_workers(1, timeout=timeout_s)
        except TimeoutError as exc:
            self._client.close()
            raise RigdError(f"--cluster {address}: the scheduler has no workers after {timeout_s:g} s; start "
                            f"them with `dask worker {address}`") from exc
        self.workers = len(self._client.nthreads())
        self._key = FeatureKey(request, dataset_stamp(request.dataset))

    def run(self, fn: Callable[[WorkerState, T], R], tasks: Sequence[T], desc: str, progress: bool) -> list[R]:
        futures = [self._client.submit(_on_worker, self._key, code_version(), fn, t, pure=False) for t in tasks]
        try:
            return collect(as_completed(futures, loop=self._client.loop), len(futures), desc, progress)
        except KilledWorker as exc:
            raise RigdError(f"{desc}: workers of {self._address} died running a trial ({exc}); each worker "
                            "process holds the dataset's features: fewer per machine need less memory") from exc
        except (OSError, CancelledError) as exc:
            raise RigdError(f"{desc}: lost the Dask scheduler at {self._address} ({exc!r})") from exc
        finally:
            self._client.cancel(futures)

    def close(self) -> None:
        self._client.close()
