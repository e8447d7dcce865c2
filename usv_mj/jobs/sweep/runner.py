"""Running a sweep on Dask: one task per run, results streamed to ``DIR/results.parquet``.

- :func:`run_one` is the task: it simulates one scenario and returns its summary row; it never
  raises for a run that fails (the row says ``failed`` and why), only for a run that cannot be set
  up on its worker (:class:`WorkerSetupError`: its plug-in modules do not import there, its
  scenario does not unpickle there, or it does not build there), which stops the sweep.
- The scenario travels to the worker as pickled bytes (:func:`pack`) and is unpickled inside the
  task: a scenario that Dask itself had to unpickle while reading the scheduler's message would, on
  failing, leave the worker's link to the scheduler broken and the sweep waiting without end.
- :func:`open_client` gives a ``distributed.Client``: on an existing scheduler (``--scheduler
  ADDRESS``, any Dask cluster, e.g. one made by ``dask-jobqueue`` on a batch system, see
  :func:`jobqueue_cluster`), or on a ``LocalCluster`` with one single-threaded worker process per core.
- :func:`run_sweep` submits the runs that are not in the results yet, records them as they finish
  (a worker that dies mid-task is retried by Dask on another worker up to the scheduler's
  ``allowed-failures``; after that the run is recorded as ``failed: worker died``), and rewrites
  ``results.parquet`` atomically at most every ``flush_every`` seconds and at the end, so that an
  interrupted sweep keeps what it had and ``--resume`` runs only the missing ids.

Row columns: ``run_id``; ``vary.<path>`` for each varied path; ``status`` (ok | diverged | failed)
and ``reason``; ``passed`` (status ok and the run passed the criterion its controller declares,
:mod:`usv_mj.record.criteria`: the funnel of docs/model.md §3, |z_i| < 1, for the paper's controller; the
criterion's kind, words and largest errors are the ``criterion.*`` columns); ``task_wall_time_s``;
``max_abs_error_after_transient.{x,y,psi}`` [m, m, rad] and ``max_position_error_after_transient``
[m] (hypot of the x, y errors) after the sweep's ``transient``; then every field of :func:`usv_mj.record.summary.summarize` flattened with dots
(``errors_at.5.x``, ``quantizer_switches.u``, ...), with the summary's ``status`` renamed
``record_status``. Rows are sorted by ``run_id``.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import math
import os
import pickle
import signal
import sys
import time
import uuid
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from usv_mj.core.errors import WorkerError, WorkerSetupError
from usv_mj.jobs.sweep.spec import RunSpec, SweepError, SweepPlan
from usv_mj.support.spawning import group_signals_blocked, start_resource_tracker

RESULTS_FILE = "results.parquet"
#: What a sweep writes into its folder, by name (listed in its manifest before they are written).
OUTPUT_PATTERNS = ("sweep.json", RESULTS_FILE, f".{RESULTS_FILE}.*.tmp", "report.md", "figures", "figures/*.png",
                   "logs", "logs/run-*")
FINGERPRINT_KEY = b"usv_mj.jobs.sweep.fingerprint"
TIMING_COLUMNS = ("task_wall_time_s", "wall_time_s", "realtime_factor")
"""Columns that measure time on the machine: they differ between two runs of the same sweep."""
STRING_COLUMNS = ("status", "reason", "record_status", "stop_reason", "preset", "plant", "controller",
                  "criterion.kind", "criterion.noun", "criterion.description")


# --- the task -------------------------------------------------------------------------------------


def flatten(d: dict, prefix: str = "") -> dict:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out = {}
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _finite_or_none(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def transient_errors(record, transient: float) -> dict:
    """Max |x - x_d|, |y - y_d| [m], |wrap(psi - psi_d)| [rad] and max hypot(x err, y err) [m] for t > transient.

    None where the run did not reach the transient's end.
    """
    from usv_mj.record.summary import column_chunks, pose_errors

    names = ("t", "x", "x_d", "y", "y_d", "psi", "psi_d")
    peak: dict = {}
    for chunk in column_chunks(record, names):   # chunk by chunk: a long stored record stays on disk
        c = dict(zip(names, chunk))
        after = c["t"] > transient
        if not after.any():
            continue
        err = pose_errors(c)
        for key, v in (("x", np.abs(err["x"])), ("y", np.abs(err["y"])), ("psi", np.abs(err["psi"])),
                       ("pos", np.hypot(err["x"], err["y"]))):
            m = np.max(v[after])
            peak[key] = m if key not in peak else np.maximum(peak[key], m)   # NaN, as np.max, wins
    if not peak:
        return {"max_abs_error_after_transient.x": None, "max_abs_error_after_transient.y": None,
                "max_abs_error_after_transient.psi": None, "max_position_error_after_transient": None}
    out = {f"max_abs_error_after_transient.{a}": _finite_or_none(peak[a]) for a in ("x", "y", "psi")}
    out["max_position_error_after_transient"] = _finite_or_none(peak["pos"])
    return out


def pack(scenario) -> bytes:
    """``scenario`` as the bytes a task carries (:func:`run_one` unpickles them on the worker)."""
    try:
        return pickle.dumps(scenario, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:   # a part defined in __main__ or a lambda (a worker that shares this process)
        import cloudpickle

        return cloudpickle.dumps(scenario, protocol=pickle.HIGHEST_PROTOCOL)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except Exception:   # not on a Dask worker (a run in this process)
        return ""


def set_up(run_id: int, scenario, options: dict, build_it: bool = True):
    """On the worker: import the run's plug-in modules, unpickle its scenario (bytes from :func:`pack`)
    and build it; returns ``(scenario, parts or None)``. Any failure raises
    :class:`usv_mj.core.errors.WorkerSetupError`: every run would fail the same way there, so the sweep
    stops on it (the run is left out of the results: ``--resume`` runs it again)."""
    stage = "importing"
    try:
        for module in options.get("imports", ()):
            stage = f"importing {module}"
            importlib.import_module(module)
        if isinstance(scenario, (bytes, bytearray)):
            stage = "unpickling its scenario"
            scenario = pickle.loads(scenario)
        parts = None
        if build_it:
            stage = "building it"
            from usv_mj.builder import build

            parts = build(scenario)
        return scenario, parts
    except Exception as exc:
        raise WorkerSetupError(int(run_id), stage, _one_line(exc), _worker_address()) from None


def failed_row(run_id: int, values: dict, reason: str, wall: float | None = None) -> dict:
    """The row of a run that produced no record (raised, or its worker died)."""
    row = {"run_id": int(run_id)}
    row.update({f"vary.{p}": v for p, v in values.items()})
    row.update({"status": "failed", "reason": reason, "passed": False, "task_wall_time_s": wall})
    return row


def run_one(run_id: int, scenario, values: dict, options: dict | None = None) -> dict:
    """Simulate one run of a sweep and return its row (see the module docstring). ``scenario``: a
    Scenario, or its bytes (:func:`pack`); raises :class:`WorkerSetupError` when the run cannot be set
    up here (:func:`set_up`), returns a ``failed`` row when it fails once running.

    ``options``: ``transient`` [s]; ``log_path`` (write an MCAP log there through
    ``usv_mj.outputs.log.RunLogWriter``); ``imports`` (modules that register the run's kinds at
    runtime: imported first, :func:`usv_mj.scenario.kinds.worker_imports`); ``episode_fn``
    (``"module:function"``, ``fn(scenario, options) -> RunRecord`` runs the episode instead of
    :func:`usv_mj.loop.simulate.simulate`: a learned policy, :mod:`usv_mj.jobs.bench.policy`); ``row_hook``
    (``"module:function"``, ``fn(record, options) -> dict`` of columns added to the row: the
    benchmark's metrics, :mod:`usv_mj.jobs.bench.episode`); ``hooks`` (tests only,
    honoured only when the environment variable ``USV_MJ_SWEEP_TEST_HOOKS`` is "1" in the worker:
    ``raise`` / ``exit_worker`` sets of run ids; ``hold``: those runs touch
    ``$USV_MJ_SWEEP_TEST_RELEASE.started-<id>`` and wait until the file ``$USV_MJ_SWEEP_TEST_RELEASE``
    exists, so that a test can interrupt a sweep that is certainly not finished).
    """
    from usv_mj.loop.simulate import simulate
    from usv_mj.record.summary import summarize

    options = options or {}
    wall0 = time.perf_counter()
    hooks = options.get("hooks") or {}
    # a WorkerSetupError goes to the parent (the sweep stops); the run's own failures make its row
    scenario, parts = set_up(run_id, scenario, options, build_it=not options.get("episode_fn"))
    try:
        if hooks and os.environ.get("USV_MJ_SWEEP_TEST_HOOKS") == "1":
            if run_id in hooks.get("exit_worker", ()):
                os._exit(13)  # the worker process dies mid-task
            if run_id in hooks.get("raise", ()):
                raise RuntimeError(f"test hook: run {run_id} raises")
            release = os.environ.get("USV_MJ_SWEEP_TEST_RELEASE")
            if run_id in hooks.get("hold", ()) and release:   # says it started, then waits for the file
                Path(f"{release}.started-{run_id}").touch()
                while not os.path.exists(release):
                    time.sleep(0.01)
        sinks = []
        writer = None
        if options.get("log_path"):
            from usv_mj.outputs.log import RunLogWriter

            # in this process: a Dask worker is a daemonic process and may not start the writer's child
            writer = RunLogWriter(options["log_path"], scenario, background=False)
            from usv_mj.outputs.log.writer import log_every

            sinks.append(writer.sink(run="main", log_every=log_every(options.get("log_rate"), scenario.control_period)))
        try:
            if options.get("episode_fn"):
                record = resolve(options["episode_fn"])(scenario, options)
            else:
                ready, parts = parts, None
                record = simulate(ready, sinks=sinks)   # it closes the parts, however it ends
        except BaseException:
            if writer is not None:
                with contextlib.suppress(Exception):
                    writer.close()
            raise
        if writer is not None:
            writer.close()
        summary = summarize(record)
    except Exception as exc:  # the sweep goes on: the row says why
        return failed_row(run_id, values, f"{type(exc).__name__}: {exc}", time.perf_counter() - wall0)
    finally:
        if parts is not None:   # built, but a hook or the log writer failed before the run
            with contextlib.suppress(Exception):
                parts.close()
    row = row_of(run_id, values, record, summary, options)
    row["task_wall_time_s"] = time.perf_counter() - wall0
    return row


def row_of(run_id: int, values: dict, record, summary: dict, options: dict) -> dict:
    """The row of a run from its record and summary (module docstring; but ``task_wall_time_s``)."""
    status = {"completed": "ok", "diverged": "diverged"}.get(record.status, "failed")
    row = {"run_id": int(run_id)}
    row.update({f"vary.{p}": v for p, v in values.items()})
    row["status"] = status
    row["reason"] = record.stop_reason or None
    row["passed"] = bool(status == "ok" and summary["criterion"]["passed"] is True)
    row.update(transient_errors(record, float(options.get("transient", 20.0))))
    flat = flatten(summary)
    flat["record_status"] = flat.pop("status")
    row.update(flat)
    if options.get("row_hook"):
        try:
            row.update(resolve(options["row_hook"])(record, options))
        except Exception as exc:  # the run is a result; the hook that could not read it says why
            row["status"], row["reason"] = "failed", f"row hook {options['row_hook']}: {type(exc).__name__}: {exc}"
    return row


def batchable(options: dict | None) -> bool:
    """A run that :func:`run_many` may run in a batch (usv_mj.loop.batch): no log to write, no episode
    function of its own (a learned policy's), no test hooks."""
    options = options or {}
    return not (options.get("log_path") or options.get("episode_fn") or options.get("hooks"))


def run_many(runs: list) -> list[dict]:
    """Several runs in one task: their rows, each the row :func:`run_one` makes of that run (bit for bit,
    but ``task_wall_time_s``: the batch's wall time shared evenly). ``runs``: (run_id, scenario or its
    bytes, values, options) tuples; the batchable ones (:func:`batchable`) are simulated together in
    one compiled batch (:func:`usv_mj.loop.batch.run_batch`), the others one by one through
    :func:`run_one`. A run that cannot be set up here raises :class:`WorkerSetupError`, as in run_one."""
    from usv_mj.loop.batch import run_batch
    from usv_mj.record.summary import summarize

    rows: dict[int, dict] = {}
    batch = []
    try:
        for i, (run_id, scenario, values, options) in enumerate(runs):
            if not batchable(options):
                rows[i] = run_one(run_id, scenario, values, options)
                continue
            batch.append((i, set_up(run_id, scenario, options or {})[1]))
        if batch:
            t0 = time.perf_counter()
            errors: list = []
            records = run_batch([p for _, p in batch], raise_errors=False, errors=errors)
            share = (time.perf_counter() - t0) / len(batch)
            for (i, _), record, error in zip(batch, records, errors):
                run_id, _, values, options = runs[i]
                try:
                    if error is not None:
                        raise error
                    rows[i] = row_of(run_id, values, record, summarize(record), options or {})
                except Exception as exc:  # the sweep goes on: the row says why (as run_one's)
                    rows[i] = failed_row(run_id, values, f"{type(exc).__name__}: {exc}")
                rows[i]["task_wall_time_s"] = share
    finally:
        for _, parts in batch:
            with contextlib.suppress(Exception):
                parts.close()
    return [rows[i] for i in range(len(runs))]


def resolve(spec: str):
    """The object named by ``"package.module:name"`` (imported here: on a worker, in its process)."""
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def warm_up(scenario, steps: int = 5) -> dict:
    """Simulate ``scenario`` for ``steps`` control periods in this process, so that the runs after it
    pay neither the imports (numba, mujoco, the package) nor the compiled loop of its combination
    (:mod:`usv_mj.loop.compiled`: compiled into the disk cache when it is not there yet, loaded from
    it otherwise). Returns ``{"loop", "loop_reason", "seconds"}``, or ``{"error", "seconds"}``:
    it never raises (a scenario that cannot run says so in its own task's row).
    A scenario with obstacles is not run here (its build composes the harbour and plans a path):
    only the modules are imported, and each run takes the loop its parts allow (standing obstacles:
    the compiled one, compiled by the first run that needs it).
    """
    t0 = time.perf_counter()
    try:
        from usv_mj.loop.simulate import simulate

        if isinstance(scenario, (bytes, bytearray)):   # on a worker (:func:`pack`)
            scenario = pickle.loads(scenario)
        if scenario.obstacles:
            import usv_mj.obstacles.hooks  # noqa: F401
            return {"loop": "per run", "loop_reason": "not warmed up: obstacles (the build composes the harbour)",
                    "seconds": time.perf_counter() - t0}
        record = simulate(scenario, duration=steps * scenario.control_period)
        if record.status == "interrupted":  # a Ctrl-C (or SIGTERM) in the warm-up stops the sweep as anywhere
            raise KeyboardInterrupt(record.stop_reason)
        return {"loop": record.metadata.get("loop"), "loop_reason": record.metadata.get("loop_reason"),
                "seconds": time.perf_counter() - t0}
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}", "seconds": time.perf_counter() - t0}


def warm_workers(client, scenario) -> dict:
    """:func:`warm_up` on every worker of ``client`` (at once); returns ``{"seconds", "loops": {worker: loop}}``.
    A worker that joins later pays its warm-up in its first task."""
    t0 = time.perf_counter()
    try:
        done = client.run(warm_up, pack(scenario), on_error="return")
    except Exception as exc:  # no workers yet, a scheduler that went away: the tasks will say
        return {"seconds": time.perf_counter() - t0, "loops": {}, "error": f"{type(exc).__name__}: {exc}"}
    loops = {w: (r.get("loop") or r.get("error")) if isinstance(r, dict) else f"{type(r).__name__}: {r}"
             for w, r in done.items()}
    return {"seconds": time.perf_counter() - t0, "loops": loops}


def describe_startup(startup: dict) -> str:
    """One line: this process's warm-up, the cluster's start and the workers' warm-up, in seconds."""
    here = startup.get("here", {})
    loops = sorted({str(v) for v in startup.get("workers", {}).get("loops", {}).values()})
    loop = here.get("loop") or here.get("error") or "?"
    if here.get("loop_reason"):
        loop += f" ({here['loop_reason']})"
    return (f"start-up {startup.get('total_s', 0.0):.1f} s: loop warmed here {here.get('seconds', 0.0):.1f} s "
            f"[{loop} loop], cluster {startup.get('cluster_s', 0.0):.1f} s, workers warmed "
            f"{startup.get('workers', {}).get('seconds', 0.0):.1f} s [{', '.join(loops) or 'no workers yet'}]")


# --- results on disk ------------------------------------------------------------------------------


def _column_type(name: str, values: list):
    import pyarrow as pa

    present = [v for v in values if v is not None]
    if name in STRING_COLUMNS:
        return pa.string()
    if not present:
        return pa.float64()
    if all(isinstance(v, bool) for v in present):
        return pa.bool_()
    if all(isinstance(v, int) and not isinstance(v, bool) for v in present):
        return pa.int64()
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return pa.float64()
    return pa.string()


def _column_order(rows: list[dict], paths: list[str]) -> list[str]:
    first = ["run_id"] + [f"vary.{p}" for p in paths] + ["status", "reason", "passed", "criterion.kind",
                                                         "task_wall_time_s"]
    seen = dict.fromkeys(first)
    for row in rows:
        for key in row:
            seen.setdefault(key)
    return list(seen)


def rows_to_table(rows: list[dict], paths: list[str], fingerprint: str = ""):
    """A pyarrow Table of ``rows`` sorted by run id; missing fields are nulls; types inferred per column."""
    import pyarrow as pa

    rows = sorted(rows, key=lambda r: r["run_id"])
    names = _column_order(rows, paths)
    arrays = []
    fields = []
    for name in names:
        col = [r.get(name) for r in rows]
        typ = _column_type(name, col)
        if typ == pa.string():
            col = [None if v is None else (v if isinstance(v, str) else json.dumps(v)) for v in col]
        elif typ == pa.float64():
            col = [None if v is None else float(v) for v in col]
        arrays.append(pa.array(col, type=typ))
        fields.append(pa.field(name, typ))
    meta = {FINGERPRINT_KEY: fingerprint.encode()} if fingerprint else None
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))


def write_results(path: Path, rows: list[dict], paths: list[str], fingerprint: str) -> None:
    """Write ``rows`` to ``path`` atomically (a temporary file, then ``os.replace``); an OSError
    (a full disk) names ``path`` and leaves it as it was."""
    import pyarrow.parquet as pq

    table = rows_to_table(rows, paths, fingerprint)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except OSError as exc:      # pyarrow's own errors carry no file name
        tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror or " ".join(str(exc).split()), str(path)) from None


def episodes_in(out: Path) -> int:
    """How many rows ``out/results.parquet`` holds (0 when it is missing or cannot be read): what an
    interrupted sweep or benchmark says it kept."""
    try:
        import pyarrow.parquet as pq

        return int(pq.read_metadata(Path(out) / RESULTS_FILE).num_rows)
    except Exception:  # noqa: BLE001 - no file, or a damaged one: nothing kept there
        return 0


def read_results(path: str | Path) -> tuple[list[dict], str]:
    """The rows (sorted by run id) and the plan fingerprint of a results file."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = table.schema.metadata or {}
    rows = sorted(table.to_pylist(), key=lambda r: r["run_id"])
    return rows, meta.get(FINGERPRINT_KEY, b"").decode()


# --- Dask -----------------------------------------------------------------------------------------


def _dashboard(client) -> str:
    try:
        import bokeh  # noqa: F401  (distributed serves its dashboard only with bokeh)
    except ImportError:
        return "not served (pip install \"usv_mj[hpc]\" for the Dask dashboard)"
    link = client.dashboard_link
    return link or "not served"


@contextlib.contextmanager
def open_client(scheduler: str | None = None, workers: int | None = None,
                echo: Callable[[str], None] | None = print, jobqueue: str | None = None,
                jobs: int = 1) -> Iterator[Any]:
    """A ``distributed.Client`` on ``scheduler`` (an address), on a batch system, or on a local cluster.

    ``jobqueue``: a batch system of ``dask-jobqueue`` (``slurm``, ``pbs``, ``sge``, ``lsf``, ...):
    ``jobs`` batch jobs of workers, sized by dask-jobqueue's own configuration
    (``~/.config/dask/jobqueue.yaml``: cores, memory, queue, walltime...).
    Local default: ``LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1,
    processes=True)`` (the runs are CPU-bound Python + numba: one process per core). The dashboard
    address is printed through ``echo``.
    """
    import logging

    from distributed import Client, LocalCluster

    echo = echo or (lambda s: None)
    if scheduler and jobqueue:
        raise SweepError("--scheduler and --jobqueue exclude each other: give one")
    if jobqueue:
        try:
            cluster = jobqueue_cluster(jobqueue, jobs)
        except SweepError:
            raise
        except Exception as exc:  # dask-jobqueue's own message (missing cores / memory, no sbatch...)
            raise SweepError(f"--jobqueue {jobqueue}: cannot make the batch cluster: {exc}") from None
        client = Client(cluster)
        echo(f"dask-jobqueue {jobqueue} cluster: {jobs} job(s) asked; scheduler {cluster.scheduler_address}; "
             f"dashboard: {_dashboard(client)}")
        try:
            yield client
        finally:
            client.close()
            cluster.close()
        return
    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise SweepError(f"--scheduler {scheduler!r}: cannot connect to a Dask scheduler there ({exc})") from None
        n = len(client.scheduler_info().get("workers", {}))
        echo(f"Dask scheduler {scheduler}: {n} workers; dashboard: {_dashboard(client)}")
        try:
            yield client
        finally:
            client.close()
        return
    n = int(workers or os.cpu_count() or 1)
    if n < 1:
        raise SweepError(f"--workers must be >= 1, got {n}")
    # the workers' own loggers at CRITICAL: a run that fails comes back as a row with its reason, and
    # a cluster closed under them (Ctrl-C) makes them log heartbeat ERRORs with tracebacks
    # the scheduler runs in this process and logs its start-up at INFO: shown on the console as soon
    # as anything has given the root logger a handler (absl does, on dm_control's import: a policy
    # suite); the line above says what the user needs, so its INFO stays quiet while the cluster lives
    scheduler_log = logging.getLogger("distributed")
    level = scheduler_log.level
    scheduler_log.setLevel(max(scheduler_log.getEffectiveLevel(), logging.WARNING))
    cluster = client = None
    try:
        # Made with a terminal's Ctrl-C and hang-up blocked in this thread (_TERMINAL): they signal
        # every process of the group, and a worker still starting died of them with a traceback
        # each (and the scheduler's "Nanny failed to start"). The cluster's IO loop thread, the
        # threads it starts and every worker they spawn (a replacement too) keep them blocked: this
        # process takes them, once the cluster is made (and assigned: the finally closes it), and
        # closes the cluster. SIGTERM stays the workers' (the nannies end them with it).
        start_resource_tracker()      # multiprocessing's, sheltered from a hang-up (support.spawning)
        with group_signals_blocked(_TERMINAL):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                   silence_logs=logging.CRITICAL)
        client = Client(cluster)
        echo(f"local Dask cluster: {n} worker processes x 1 thread; dashboard: {_dashboard(client)}")
        yield client
    finally:
        try:
            with _quiet_teardown():
                if client is not None:
                    client.close()
                if cluster is not None:
                    cluster.close()
        finally:
            scheduler_log.setLevel(level)


_TERMINAL = tuple(getattr(signal, name) for name in ("SIGINT", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def _quiet_teardown():
    """The local cluster closed after a Ctrl-C: its scheduler (in this process) logs at CRITICAL, with
    tracebacks, each task it can no longer report to the closed client ("Closed comm ... lost-data").
    That is the teardown, not a fault; its loggers are silenced while it lasts."""
    import logging

    loggers = [logging.getLogger(name) for name in ("distributed", "distributed.scheduler", "distributed.core",
                                                    "distributed.batched", "distributed.nanny")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def jobqueue_cluster(kind: str = "slurm", jobs: int = 1, **kwargs):
    """A ``dask-jobqueue`` cluster on an HPC batch system (``slurm``, ``pbs``, ``sge``, ``lsf``, ...),
    scaled to ``jobs`` jobs; ``kwargs`` go to its constructor (cores, memory, queue, walltime...).

    Use its scheduler address with ``usv-mj sweep --scheduler``::

        cluster = jobqueue_cluster("slurm", jobs=10, cores=8, memory="16GB", processes=8)
        print(cluster.scheduler_address)   # keep this process alive while the sweep runs
    """
    try:
        import dask_jobqueue
    except ImportError:
        from usv_mj.core.errors import missing_extra

        raise SweepError(str(missing_extra("dask_jobqueue", "--jobqueue"))) from None
    classes = {"slurm": "SLURMCluster", "pbs": "PBSCluster", "sge": "SGECluster", "lsf": "LSFCluster",
               "oar": "OARCluster", "htcondor": "HTCondorCluster", "moab": "MoabCluster"}
    if kind not in classes:
        raise SweepError(f"unknown batch system {kind!r}; known: {', '.join(classes)}")
    if jobs < 1:
        raise SweepError(f"--jobs must be >= 1, got {jobs}")
    cluster = getattr(dask_jobqueue, classes[kind])(**kwargs)
    cluster.scale(jobs=jobs)
    return cluster


def runlog_available() -> bool:
    """Whether ``usv_mj.outputs.log.RunLogWriter`` (the MCAP issue) is importable."""
    try:
        from usv_mj.outputs.log import RunLogWriter  # noqa: F401
    except ImportError:
        return False
    return True


def _workers_share_this_process(client) -> bool:
    """True when every worker of ``client`` runs in this process (an in-process cluster's threads)."""
    try:
        pids = client.run(os.getpid)
    except Exception:
        return False
    return bool(pids) and all(pid == os.getpid() for pid in pids.values())


LOST_WORKERS_S = 60.0
"""[s] How long a sweep waits, with runs still to do, on a cluster whose every worker has gone
(none came back): then it stops (:class:`usv_mj.core.errors.WorkerError`) instead of waiting without end."""


def _waiting(ac, watch: Callable[[], None], poll: float = 0.1, every: float = 1.0) -> Iterator[Any]:
    """The futures of ``ac`` (a ``distributed.as_completed``) as they complete, calling ``watch()``
    about every ``every`` seconds while none does (it raises to stop the wait)."""
    last = time.monotonic()
    while not ac.is_empty():
        if ac.has_ready():
            last = time.monotonic()
            yield next(ac)
            continue
        with ac.thread_condition:   # notified as each future completes (as as_completed's own wait)
            ac.thread_condition.wait(timeout=poll)
        if time.monotonic() - last >= every:
            watch()
            last = time.monotonic()


class _WorkerWatch:
    """Raises :class:`WorkerError` once the cluster, which had workers, has had none for ``limit`` s."""

    def __init__(self, client, limit: float | None):
        self.client, self.limit = client, limit
        self.seen = False
        self.gone_since: float | None = None

    def __call__(self) -> None:
        if self.limit is None:
            return
        try:
            n = len(self.client.nthreads())
        except Exception:   # the scheduler does not answer: no worker can be reached either
            n = 0
        now = time.monotonic()
        if n:
            self.seen, self.gone_since = True, None
        elif self.seen:
            self.gone_since = self.gone_since or now
            if now - self.gone_since >= self.limit:
                raise WorkerError(f"every Dask worker has been gone for {self.limit:g} s and none came back "
                                  f"(a worker that dies at start, a batch job that ended, a scheduler that "
                                  f"went away)")


def gather_rows(client, jobs: list[tuple[RunSpec, dict]], on_row: Callable[[dict], None],
                key_prefix: str = "usv-run", lost_workers_s: float | None = LOST_WORKERS_S, batch: int = 1) -> None:
    """Submit ``(run, options)`` pairs as one task each and call ``on_row(row)`` as each finishes.

    ``batch`` > 1: up to that many batchable runs (:func:`batchable`) in one task (:func:`run_many`:
    one compiled batch of episodes; the rows are those of one task per run, the episodes still the
    unit of the results and of ``--resume``).

    Each task carries its scenario as bytes (:func:`pack`), unpickled by :func:`run_one` on the worker.
    A task whose worker died more often than the scheduler's ``allowed-failures`` (Dask's
    ``KilledWorker``) or that could not be run at all gives a ``failed`` row with the reason. A run
    that cannot be set up on its worker raises :class:`usv_mj.core.errors.WorkerSetupError` here, and
    a cluster left without workers for ``lost_workers_s`` seconds (None: no limit) raises
    :class:`usv_mj.core.errors.WorkerError`. On an exception (those, Ctrl-C) the futures not yet
    done are cancelled and the exception goes on.
    """
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    from usv_mj.scenario.kinds import worker_imports

    token = uuid.uuid4().hex[:8]
    futures = {}
    shared = None  # whether every worker is a thread of this process (then it sees this registry)
    # The watch reads the cluster once now, before any run is submitted: a worker that takes the first
    # run and dies at once (before the wait's first watch, 1 s in) has then been seen, so its loss is
    # timed; read only while waiting, the cluster looked never to have had a worker and the wait had no end.
    watch = _WorkerWatch(client, lost_workers_s)
    watch()
    chunk: list = []

    def submit_chunk():
        if chunk:
            first = chunk[0][0].run_id
            fut = client.submit(run_many, [(r.run_id, pack(r.scenario), r.values, o) for r, o in chunk],
                                key=f"{key_prefix}-batch-{first}-{token}", pure=False, retries=0)
            futures[fut] = [r for r, _ in chunk]
            chunk.clear()

    for run, options in jobs:
        try:
            imports = worker_imports(run.scenario)  # SweepError for a kind that exists only in this process
        except SweepError:
            if shared is None:
                shared = _workers_share_this_process(client)
            if not shared:
                raise
            imports = ()
        if imports:
            options = {**(options or {}), "imports": imports}
        if batch > 1 and batchable(options):
            chunk.append((run, options))
            if len(chunk) >= batch:
                submit_chunk()
            continue
        fut = client.submit(run_one, run.run_id, pack(run.scenario), run.values, options,
                            key=f"{key_prefix}-{run.run_id}-{token}", pure=False, retries=0)
        futures[fut] = [run]
    submit_chunk()
    try:
        for fut in _waiting(as_completed(list(futures)), watch):
            runs = futures[fut]
            try:
                got = fut.result()
                got = got if isinstance(got, list) else [got]
            except WorkerSetupError:
                raise   # every run would fail the same way on that worker: the sweep stops here
            except KilledWorker as exc:
                got = [failed_row(run.run_id, run.values, f"worker died: the task was tried on a worker that "
                                  f"died, too many times (Dask KilledWorker: {exc})") for run in runs]
            except Exception as exc:  # a run that could not be run or sent back
                got = [failed_row(run.run_id, run.values, f"{type(exc).__name__}: {exc}") for run in runs]
            for row in got:
                on_row(row)
            fut.release()
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)


# --- the sweep ------------------------------------------------------------------------------------


class _StopAfter(Exception):
    """``max_runs`` new rows are in: stop the sweep here (the rest is left for ``--resume``)."""


class SweepResult:
    """What :func:`run_sweep` did: ``rows`` (all, sorted), ``ran`` (this call), ``failed``, ``out``,
    ``complete`` (every run of the plan is in the table), ``timing`` (``startup``: the warm-ups and
    the cluster's start, see :func:`describe_startup`; ``runs_s``: first submission to last result)."""

    def __init__(self, rows, ran, out, complete=True, timing=None):
        self.rows = rows
        self.ran = ran
        self.out = out
        self.complete = complete
        self.timing = timing or {}

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)


def run_sweep(plan: SweepPlan, out: str | Path, *, scheduler: str | None = None, workers: int | None = None,
              resume: bool = False, keep_logs: bool = False, progress: bool = True, flush_every: float = 2.0,
              client=None, echo: Callable[[str], None] | None = print, report: bool = True,
              max_runs: int | None = None, jobqueue: str | None = None, jobs: int = 1,
              retry_failed: bool = False, log_rate: float | None = None,
              lost_workers_s: float | None = LOST_WORKERS_S, batch: int = 1) -> SweepResult:
    """Run the plan's missing runs on Dask, streaming rows into ``out/results.parquet``; then the report.

    ``client``: an existing ``distributed.Client`` (else one is opened by :func:`open_client`).
    ``max_runs``: stop after this many new rows, as an interrupt would (the rest waits for ``resume``).
    ``jobqueue``, ``jobs``: run on a batch system through dask-jobqueue (see :func:`open_client`).
    ``retry_failed``: with ``resume``, run the ``failed`` rows again too (a worker that died of a
    lack of memory, say); diverged runs are results and stay. ``log_rate`` [Hz]: with ``keep_logs``,
    each log holds every n-th control step (``RunLogWriter.sink(log_every=n)``). ``lost_workers_s``:
    how long to wait on a cluster that lost every worker (see :func:`gather_rows`). ``batch``: up to
    that many runs per task, simulated together in one compiled batch (:func:`run_many`; the same rows).
    Raises :class:`SweepError` when ``out`` already holds results and ``resume`` is False, or holds
    results of another plan. KeyboardInterrupt and :class:`usv_mj.core.errors.WorkerError` (a run that
    cannot be set up on its worker, a cluster without workers) propagate after the rows so far are written.
    """
    echo = echo or (lambda s: None)
    out = Path(out)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    from usv_mj.outputs.outdir import record

    record(out, [], patterns=OUTPUT_PATTERNS)   # claimed before written: a killed sweep stays resumable
    results = out / RESULTS_FILE
    rows: dict[int, dict] = {}
    if results.exists():
        if not resume:
            raise SweepError(f"{results} exists: pass --resume to run only the missing runs, or choose another --out")
        try:
            old, fingerprint = read_results(results)
        except Exception as exc:
            raise SweepError(f"{results}: cannot read the results to resume ({exc})") from None
        if fingerprint != plan.fingerprint:
            raise SweepError(f"{results} holds the results of another sweep (its file, seed or base differ): "
                             f"choose another --out")
        if any("passed" not in r for r in old):
            raise SweepError(f"{results} was written before the runs were judged by their controller's criterion "
                             f"(it has no 'passed' column): choose another --out")
        rows = {int(r["run_id"]): r for r in old if not (retry_failed and r["status"] == "failed")}
    (out / "sweep.json").write_text(json.dumps({
        "source": plan.source, "fingerprint": plan.fingerprint, "runs": len(plan.runs), "seed": plan.seed,
        "samples": plan.samples, "transient_s": plan.transient, "base_preset": plan.base.preset,
        "axes": [{"path": a.path, "kind": a.kind, "args": list(a.args)} for a in plan.axes],
    }, indent=1, default=repr))
    todo = [r for r in plan.runs if r.run_id not in rows]
    log_dir = None
    if keep_logs:
        if runlog_available():
            log_dir = out / "logs"
            log_dir.mkdir(exist_ok=True)
        else:
            echo("--keep-logs: usv_mj.outputs.log.RunLogWriter (the MCAP issue) is not in this checkout yet; "
                 "running without per-run logs")
    base_options = {"transient": plan.transient, "hooks": plan.test_hooks or None}
    n_jobs = jobs
    tasks = []
    for run in todo[:max_runs]:        # only what will run is submitted (--max-runs 10 of 60,000: 10 tasks)
        opts = {**base_options, **run.options}
        if log_dir is not None:
            opts["log_path"] = str(log_dir / f"run-{run.run_id:06d}.mcap")
            opts["log_rate"] = log_rate
        tasks.append((run, opts))
    ran = 0
    timing: dict = {}
    if todo:
        echo(f"{len(plan.runs)} runs in the sweep, {len(rows)} already in {results}, {len(todo)} to run"
             + (f", {len(tasks)} of them now (max_runs)" if len(tasks) < len(todo) else ""))
        bar = None
        state = {"last_flush": time.monotonic(), "failed": sum(r["status"] != "ok" for r in rows.values()),
                 "dirty": False}

        def on_row(row):
            nonlocal ran
            rows[row["run_id"]] = row
            ran += 1
            state["dirty"] = True
            if row["status"] != "ok":
                state["failed"] += 1
            if bar is not None:
                bar.update(1)
                bar.set_postfix(diverged_or_failed=state["failed"], refresh=False)
            if time.monotonic() - state["last_flush"] >= flush_every:
                write_results(results, list(rows.values()), plan.paths, plan.fingerprint)
                state["last_flush"] = time.monotonic()
                state["dirty"] = False
            if max_runs is not None and ran >= max_runs:
                raise _StopAfter()

        def run_on(cl, t_start):
            nonlocal bar
            # the start-up, apart from the runs: every worker imports the package and loads the compiled
            # loop of the first run's combination before the first task
            startup["workers"] = warm_workers(cl, todo[0].scenario)
            startup["total_s"] = time.perf_counter() - t_start
            timing["startup"] = startup
            echo(describe_startup(startup))
            if progress:
                from tqdm import tqdm

                bar = tqdm(total=len(plan.runs), initial=len(rows), unit="run", dynamic_ncols=True,
                           file=sys.stderr)
            t_runs = time.perf_counter()
            try:
                gather_rows(cl, tasks, on_row, lost_workers_s=lost_workers_s, batch=batch)
            finally:
                timing["runs_s"] = time.perf_counter() - t_runs  # first submission to last result

        startup: dict = {"cluster_s": 0.0}
        try:
            t_start = time.perf_counter()
            # here first: a loop not in the disk cache yet is compiled once, not by every worker at once
            startup["here"] = warm_up(todo[0].scenario)
            if client is not None:
                run_on(client, t_start)
            else:
                t_cluster = time.perf_counter()
                with open_client(scheduler, workers, echo, jobqueue=jobqueue, jobs=n_jobs) as own:
                    startup["cluster_s"] = time.perf_counter() - t_cluster
                    run_on(own, t_start)
        except SweepError:
            if ran == 0:  # no cluster (a bad --jobqueue, a scheduler that does not answer): bad input,
                state["dirty"] = False  # so --out stays as it was
                if bar is not None:
                    bar.close()
                    bar = None
                if created:
                    import shutil

                    shutil.rmtree(out, ignore_errors=True)
                else:
                    (out / "sweep.json").unlink(missing_ok=True)
                state["no_cluster"] = True
            raise
        except _StopAfter:
            echo(f"stopped after {ran} runs (max_runs); --resume runs the rest")
        finally:
            if bar is not None:
                bar.close()
            if not state.get("no_cluster") and (state["dirty"] or not results.exists()):
                write_results(results, list(rows.values()), plan.paths, plan.fingerprint)
        if timing.get("runs_s") and ran:
            echo(f"{ran} runs in {timing['runs_s']:.1f} s from the first submission to the last result: "
                 f"{60 * ran / timing['runs_s']:.0f} runs/min (start-up apart)")
    elif not results.exists():
        write_results(results, [], plan.paths, plan.fingerprint)
    all_rows = sorted(rows.values(), key=lambda r: r["run_id"])
    complete = len(all_rows) == len(plan.runs)
    if report and complete:
        from usv_mj.jobs.sweep.report import write_report

        write_report(out, all_rows, plan)
    return SweepResult(all_rows, ran, out, complete, timing)
