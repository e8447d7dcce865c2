"""Many episodes in one compiled kernel: the single run's loop, once per episode, under ``prange``.

A batch is N independent episodes (each its own vessel, start pose, sea, reference, controller
gains and actuator state) advanced together::

    records = simulate_batch([scenario_0, scenario_1, ...])     # one RunRecord per episode

Every episode's record is the one :func:`usv_mj.simulate` makes of it alone, bit for bit: the batch
runs the compiled loop's own ``run_block`` (:mod:`usv_mj.loop.compiled`, made by the one generator
:mod:`usv_mj.loop.generate`, so the same control step and ``advance``) for each episode, with that
episode's arguments, inside a ``numba.prange`` over the episodes (threads across the cores: the
MuJoCo plant's ``mj_step`` is called by address and its passive callback is a C function reading
the episode's own mjData, so no thread takes the GIL). Nothing in the kernels knows about batches.

How the episodes' kernel arguments are held (:func:`stack`, per role and argument):

- episodes are **grouped** by kernel combination (the functions, their argument counts, each
  argument's type and, for arrays, dtype and shape): one generated wrapper per group;
- an argument a kernel writes (``Kernel.state``, :mod:`usv_mj.core.kernels`) is **stacked**: the
  batch owns an (N, ...) array holding every episode's copy, and writes each row back into the
  part's own array at every block's end, so the Python objects are where the single run leaves
  them;
- a parameter (only read) equal in every episode (the same object, or equal values) is passed
  **once**; otherwise it is stacked (domain randomisation: each episode its own gains or hull);
- a kernel that does not declare its state has every array copied per episode (always right);
- scalars equal in every episode are passed once, else as an array of N.

Each episode keeps its own :class:`~usv_mj.record.run_record.RunRecord` (in memory or streamed),
sinks, events and metadata, made as :func:`usv_mj.loop.simulate.simulate` makes them: the batch
writes the rows straight into each record's window (by address, ``usv_mj.support.pointers``), and
between blocks Python does for each episode what the single run's compiled loop does (flush, events,
progress). Episodes whose parts have no kernel, or that have a hook, run alone through the single
run's loop, after the batch.

The plants' kernels are taken once, for the whole run (the sea's grids generated that far at once:
they are deterministic, earlier values never change), so the arguments do not move between blocks.
"""

from __future__ import annotations

import contextlib
from typing import NamedTuple

import numpy as np

from usv_mj.builder import Parts, as_scenario, build
from usv_mj.core.kernels import Kernel
from usv_mj.loop import simulate as single
from usv_mj.loop.compiled import (_ROLES, _TEMPLATE as BLOCK_TEMPLATE, BLOCK_END, BLOCK_FIELDS, BLOCK_IMPORTS, DONE,
                                  PLANT_FAILED, _after, _hold_signals, block_kernels, kernels_of, no_hook)  # noqa: F401 (DONE: API)
from usv_mj.loop.generate import generate
from usv_mj.scenario.spec import Scenario

_BATCH_TEMPLATE = '''

@njit(cache=True, parallel=True)
def run_batch(K, STATUS, STOP, N, DT, BASE, ADDR, ROWS, n_cols, n_diag, LIM, X, OUT, ref_a, ctrl_a, step_a, plant_a,
              hook_a):
    """run_block (above) for every episode i whose STATUS is BLOCK_END, from row K[i] to STOP[i],
    its rows into the window at address ADDR[i] (ROWS[i] x n_cols, row BASE[i] first)."""
    for i in prange(X.shape[0]):
        if STATUS[i] != {BLOCK_END}:  # ended (done, diverged, failed): skipped
            continue
        data = carray(f64_ptr(ADDR[i]), (ROWS[i], n_cols))
        k, status, x = run_block(K[i], STOP[i], N[i], DT[i], data, BASE[i], n_diag, LIM[i, 0], LIM[i, 1], LIM[i, 2],
                                 LIM[i, 3], X[i], OUT[i], False, {ref_ep}, {ctrl_ep}, {step_ep}, {plant_ep}, {hook_ep})
        K[i] = k
        STATUS[i] = status
        for j in range(6):
            X[i, j] = x[j]
'''

_BATCH_IMPORTS = "from numba import carray, prange\nfrom usv_mj.support.pointers import f64_ptr"


# --- stacking the episodes' arguments ---------------------------------------------------------------------------

_SCALARS = (bool, int, float, np.bool_, np.integer, np.floating)


def _scalar_dtype(v):
    return np.bool_ if isinstance(v, (bool, np.bool_)) else np.int64 if isinstance(v, (int, np.integer)) else np.float64


def signature(kernel: Kernel) -> tuple:
    """What must be equal for episodes to share a generated wrapper: the function and, per argument,
    its kind (a scalar's type; an array's dtype and shape: arrays of another shape cannot be stacked)."""
    sig = []
    for j, v in enumerate(kernel.args):
        if isinstance(v, np.ndarray):
            sig.append(("array", v.dtype.str, v.shape))
        elif isinstance(v, _SCALARS):
            sig.append(("scalar", _scalar_dtype(v).__name__))
        else:
            raise TypeError(f"usv_mj.loop.batch: argument {j} of {kernel.fn.py_func.__qualname__} is a "
                            f"{type(v).__name__}: a batch holds arrays and scalars only")
    return (kernel.fn, len(kernel.args), tuple(sig), kernel.state)


class Stacked(NamedTuple):
    """One role's arguments for a batch (:func:`stack`)."""

    args: tuple            # per argument: the shared value, or the (N, ...) stack
    mask: tuple            # per argument: True = stacked (indexed by episode in the kernel)
    back: tuple            # (argument index, [each episode's own array]) written back from the stack


def stack(kernels: list) -> Stacked:
    """The N episodes' ``Kernel`` s of one role (the same :func:`signature`) as one argument tuple
    (module docstring: state stacked, equal parameters shared)."""
    k0 = kernels[0]
    state = k0.state
    args, mask, back = [], [], []
    for j, v0 in enumerate(k0.args):
        vals = [k.args[j] for k in kernels]
        same = all(v is v0 for v in vals)
        if not isinstance(v0, np.ndarray):   # a scalar: passed by value, never state
            if all(type(v) is type(v0) and v == v0 for v in vals):
                args.append(v0)
                mask.append(False)
            else:
                args.append(np.array(vals, dtype=_scalar_dtype(v0)))
                mask.append(True)
            continue
        written = state is None or j in state
        if written:
            if state is None and same and (v0.size == 0 or not v0.flags.writeable):
                shared = True     # undeclared, but nothing can be written there
            else:
                shared = False
        else:   # a declared parameter
            shared = same or all(v.dtype == v0.dtype and np.array_equal(v, v0) for v in vals)
        if shared:
            args.append(v0)
            mask.append(False)
            continue
        args.append(np.ascontiguousarray(np.stack(vals)))
        mask.append(True)
        if written and v0.flags.writeable:   # (one object in several episodes: the last one's is kept)
            back.append((j, vals))
    return Stacked(tuple(args), tuple(mask), tuple(back))


def write_back(stacked: Stacked, i: int) -> None:
    """Episode ``i``'s rows of the stacked state into its parts' own arrays."""
    for j, vals in stacked.back:
        vals[i][...] = stacked.args[j][i]


def episode_tuple(role: str, mask: tuple) -> str:
    """The source of one episode's argument tuple of ``role``: ``(role_a[0][i], role_a[1], )``."""
    return "(" + "".join(f"{role}_a[{j}][i], " if m else f"{role}_a[{j}], " for j, m in enumerate(mask)) + ")"


def batch_function(kernels: dict, masks: dict):
    """The generated ``run_batch`` for this kernel combination (one episode's kernels) and these
    stacked/shared masks (one per role)."""
    fields = {f"{role}_ep": episode_tuple(role, masks[role]) for role in _ROLES}
    module = generate("usv_mj_batch", BLOCK_TEMPLATE + _BATCH_TEMPLATE, block_kernels(kernels),
                      imports=BLOCK_IMPORTS + "\n" + _BATCH_IMPORTS, **BLOCK_FIELDS, **fields)
    return module.run_batch


# --- the driver ------------------------------------------------------------------------------------------------

class _Episode:
    """One episode of a batch: its parts, its started run (usv_mj.loop.simulate._start) and kernels."""

    def __init__(self, index, parts, start, kernels, hooks, sinks):
        self.index, self.parts, self.start, self.kernels = index, parts, start, kernels
        self.hooks, self.sinks = hooks, sinks
        self.pk = kernels["plant"]
        self.syncs = [kernels[r].sync for r in ("ref", "ctrl", "step", "hook") if kernels[r].sync is not None]
        self.error = None

    def key(self) -> tuple:
        return (tuple(signature(self.kernels[r]) for r in _ROLES), len(self.start.record.diagnostic_fields))


@contextlib.contextmanager
def threads(n: int | None):
    """numba's thread count set to ``n`` (None: as it is) for the block, then put back."""
    if n is None:
        yield
        return
    import numba

    old = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(old)


def simulate_batch(scenarios, *, plant_kind: str | None = None, controller_kind: str | None = None,
                   duration: float | None = None, block: int = 2000, store=False, progress=None,
                   n_threads: int | None = None, raise_errors: bool = True) -> list:
    """Run the episodes of ``scenarios`` (each a :class:`Scenario`, a preset name or the
    :class:`usv_mj.builder.Parts` of a build) together and return their records, in order: each the
    record :func:`usv_mj.simulate` makes of that episode alone (bit for bit: the rows, the events,
    the status; the metadata's wall time is the batch's). ``plant_kind``, ``controller_kind`` and
    ``duration`` apply to every scenario built here. ``store``: as simulate's (False: in memory).
    ``progress(n)``: called with each episode's new rows. ``n_threads``: numba threads for the batch
    (None: numba's setting). A part that raises (a plant's failure) fails its episode only: its
    record says so (status "failed"), the others go on; ``raise_errors`` then raises the first
    error once every episode is finished (as simulate raises it)."""
    parts, fleets = [], {}
    try:
        for i, sc in enumerate(scenarios):
            if not isinstance(sc, Parts):
                sc = sc if isinstance(sc, Scenario) else as_scenario(sc, "simulate_batch")
                if sc.vessels:   # a fleet: its own loop (usv_mj.loop.fleet), as simulate runs it
                    fleets[i] = sc
                    continue
                sc = build(sc, plant_kind=plant_kind, controller_kind=controller_kind, duration=duration)
            parts.append(sc)
        records = iter(run_batch(parts, block=block, store=store, progress=progress, n_threads=n_threads,
                                 raise_errors=raise_errors))
        return [single.simulate(fleets[i], plant_kind=plant_kind, duration=duration, block=block)
                if i in fleets else next(records) for i in range(len(parts) + len(fleets))]
    finally:
        for p in parts:
            p.close()


def run_batch(parts: list, *, block: int = 2000, store=False, progress=None, n_threads: int | None = None,
              raise_errors: bool = True, errors: list | None = None) -> list:
    """:func:`simulate_batch` of built parts (not closed here). ``errors``: a list given is filled with
    each episode's exception (None: it raised none), in order."""
    records: list = [None] * len(parts)
    found_errors: list = [None] * len(parts)
    alone, episodes = [], []
    fleets = []
    for i, p in enumerate(parts):
        if not isinstance(p, Parts):   # a fleet's parts: its own loop (usv_mj.loop.fleet), as simulate runs it
            fleets.append(i)
            continue
        hooks = tuple(p.hooks)
        found, _ = kernels_of(p, hooks)
        if found is None or found["hook"].fn is not no_hook:   # Python parts, or a hook: the single run's loop
            alone.append(i)
            continue
        sinks = list(p.sinks)
        start = single._start(p, sinks, block, progress, hooks, True, store, None)
        kernels, _ = kernels_of(p, hooks, start.step)   # again after the resets: the kernels' state is theirs
        kernels["plant"] = p.plant.kernel(start.n * start.dt)   # the whole run (the sea's grids generated at once)
        episodes.append(_Episode(i, p, start, kernels, hooks, sinks))
    groups: dict = {}
    for ep in episodes:
        groups.setdefault(ep.key(), []).append(ep)
    with threads(n_threads):
        for group in groups.values():
            _run_group(group, block)
    for ep in episodes:
        records[ep.index] = ep.start.record
        found_errors[ep.index] = ep.error
    for i in alone + fleets:   # as simulate runs them (its errors raised as it raises them)
        p = parts[i]
        try:
            records[i] = single._run(p, list(p.sinks), block, progress, tuple(p.hooks), store=store) \
                if i in alone else single.simulate(p, block=block, progress=progress)
        except Exception as exc:
            if raise_errors:
                raise
            found_errors[i] = exc
    if errors is not None:
        errors[:] = found_errors
    first = next((e for e in found_errors if e is not None), None)
    if first is not None and raise_errors:
        raise first
    return records


def _run_group(group: list, block: int) -> None:
    """Run one group's episodes (one kernel combination) in lockstep, block by block."""
    n_ep = len(group)
    stacks = {role: stack([ep.kernels[role] for ep in group]) for role in _ROLES}
    run = batch_function(group[0].kernels, {role: stacks[role].mask for role in _ROLES})
    st0 = group[0].start
    n_cols = st0.record.buffer.shape[1]
    n_diag = len(st0.record.diagnostic_fields)
    K = np.zeros(n_ep, np.int64)
    STATUS = np.full(n_ep, BLOCK_END, np.int64)
    STOP = np.zeros(n_ep, np.int64)
    N = np.array([ep.start.n for ep in group], np.int64)
    DT = np.array([ep.start.dt for ep in group], np.float64)
    BASE = np.zeros(n_ep, np.int64)
    ADDR = np.zeros(n_ep, np.int64)
    ROWS = np.zeros(n_ep, np.int64)
    LIM = np.array([(ep.start.limits.max_force, ep.start.limits.max_speed, ep.start.limits.max_yaw_rate,
                     ep.start.limits.max_distance) for ep in group], np.float64)
    X = np.array([np.asarray(ep.parts.plant.state, np.float64) for ep in group])
    OUT = np.zeros((n_ep, 2))
    running = list(range(n_ep))
    release = _hold_signals()   # its first call may compile it
    try:
        while running:
            for i in running:
                rec = group[i].start.record
                buf = rec.buffer
                assert buf.flags.c_contiguous and buf.dtype == np.float64
                STOP[i] = min(K[i] + block, N[i] + 1, rec.base + len(buf))   # never past the window
                BASE[i], ADDR[i], ROWS[i] = rec.base, buf.ctypes.data, len(buf)
            run(K, STATUS, STOP, N, DT, BASE, ADDR, ROWS, n_cols, n_diag, LIM, X, OUT,
                *(stacks[role].args for role in _ROLES))
            if release is not None:
                release, deliver = None, release
                deliver()
            still = []
            for i in running:
                if _after_block(group[i], stacks, i, int(K[i]), int(STATUS[i]), X[i], OUT[i], block):
                    STATUS[i] = BLOCK_END
                    still.append(i)
            running = still
    except KeyboardInterrupt as exc:   # every episode still running stops here, as a single run would
        for i in running:
            ep = group[i]
            for role in _ROLES:
                write_back(stacks[role], i)
            single._interrupted(ep.start.record, exc, ep.start.record.n_rows * ep.start.dt)
            _finish(ep)
    finally:
        if release is not None:
            release(deliver=False)


def _after_block(ep: _Episode, stacks: dict, i: int, k: int, status: int, x, out, block: int) -> bool:
    """The single run's work after a block for episode ``ep`` (row ``i`` of its group): its parts'
    state written back, rows flushed, the plant synced (usv_mj.loop.compiled._after); at its stop,
    the events and the finished record. True while it goes on."""
    st = ep.start
    for role in _ROLES:
        write_back(stacks[role], i)
    try:
        if _after(st.record, k, status, x.copy(), ep.pk, ep.syncs, st.flush, block):
            return True
        for sync in ep.syncs:
            sync()
        if status == PLANT_FAILED:
            ep.pk.fail(k - 1)   # raises the plant's error, as the single run does
        single._compiled_stop(st.record, k, status, x.copy(), out.copy(), st.limits, st.dt)
        if st.record.status == "running":
            st.record.status = "completed"
    except Exception as exc:
        if not single._failed(st.record, exc, st.record.n_rows * st.dt):
            ep.error = exc
    _finish(ep)
    return False


def _finish(ep: _Episode) -> None:
    st = ep.start
    single._finish_run(st.record, ep.sinks, st.flush, st.wall0, st.step)

