"""``rigd evaluate convergence`` on the local process pool and on a local Dask cluster: same trials, same results?

Run: .venv/bin/python benchmarks/evaluate_cluster.py DATASET [--trials 20] [--workers 2] [--no-uncertainty]
Runs the convergence protocol (seed 0) with ``--workers`` local processes, then starts a Dask cluster on
127.0.0.1 (a TCP scheduler and ``--workers`` single-threaded worker processes, distributed.LocalCluster) and
runs the same trials there through ``--cluster ADDRESS``. Prints each wall time (the cluster's start apart),
the CPU seconds spent (this process and its workers: comparable under other load), the peak RSS of a
worker, and whether every run's result, cost, iterations, sigma and verdict are equal.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

from distributed import Client, LocalCluster

from calib.assess import TrustOptions
from rigd.evaluate.protocols import ConvergenceRequest, run_convergence
from rigd.evaluate.trials import EvaluationSettings, Run


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _cpu_s() -> float:
    """CPU seconds of this process and its reaped children (pool processes, the cluster's nannies and workers):
    unlike wall time, not inflated by other load on the machine."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def _key(run: Run) -> tuple[object, ...]:
    result = None if run.result is None else (run.result.rotation.tobytes(), run.result.translation_m.tobytes())
    return run.index, result, run.final_cost, run.iterations, run.sigma, run.verdict, run.error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-uncertainty", action="store_true")
    args = parser.parse_args()
    trust = None if args.no_uncertainty else TrustOptions()
    with tempfile.TemporaryDirectory() as tmp:
        def run(out: str, cluster: str | None) -> tuple[tuple[Run, ...], float]:
            settings = EvaluationSettings(args.dataset, workers=args.workers, out_dir=Path(tmp) / out,
                                          progress=False, trust=trust, cluster=cluster)
            started = time.monotonic()
            outcome = run_convergence(ConvergenceRequest(settings, trials=args.trials))
            return outcome.runs, time.monotonic() - started

        cpu = _cpu_s()
        local, local_s = run("local", None)
        local_rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        local_cpu, cpu = _cpu_s() - cpu, _cpu_s()
        started = time.monotonic()
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            start_s = time.monotonic() - started
            remote, remote_s = run("cluster", cluster.scheduler_address)
            remote_rss = max(client.run(_peak_rss_mb).values())
        remote_cpu = _cpu_s() - cpu  # with the cluster's start and stop
    same = [_key(a) for a in local] == [_key(b) for b in remote]
    print(f"{args.dataset}: convergence, {args.trials} trials, {args.workers} workers, "
          f"uncertainty {'off' if trust is None else 'on'}")
    print(f"local pool:     {local_s:7.1f} s wall, {local_cpu:7.1f} s CPU, peak worker RSS {local_rss:.0f} MB")
    print(f"local cluster:  {remote_s:7.1f} s wall (+ {start_s:.1f} s to start it), {remote_cpu:7.1f} s CPU, "
          f"peak worker RSS {remote_rss:.0f} MB")
    print(f"per-run results identical: {same} ({len(local)} runs)")


if __name__ == "__main__":
    main()
