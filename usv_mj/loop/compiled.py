"""The closed loop compiled: the parts' native kernels composed, one block of rows per call.

When every part of a run hands a kernel (:mod:`usv_mj.core.kernels`: the reference, the controller,
the control step (:mod:`usv_mj.loop.step`: the quantizers and the actuators), the plant, and the hook if the run has one: the obstacles' hook
has one for standing obstacles without guidance) and no part's class overrides a method below
the class of its kernel (:func:`usv_mj.core.kernels.kernel_blocker`), :func:`usv_mj.simulate` runs this
loop instead of the Python one; the record is the same bit for bit (tested in
tests/test_compiled_loop.py) and ``record.metadata["loop"]`` says which loop ran (with the reason
when it was the Python one).

How the kernels are composed: :mod:`usv_mj.loop.generate`, the one code generator (the loop's
source once per combination of kernel functions, compiled once per machine).

One call of the generated ``run_block`` does what the Python loop does for rows [k, stop): the
hook's kernel (which may answer that Python must do this row's hook: run_block returns, Python
calls the hook, and the block goes on from that row with ``resume``), the reference, the
controller, the check of its diag's length against its ``diagnostic_fields`` (the status
DIAG_MISMATCH: a contract error, before the row takes it), the row's columns (core and the
controller's diagnostics), the force check, then the
control step and the plant's step over the period (``advance``, :mod:`usv_mj.loop.generate`:
clip -> quantize -> actuators -> the row's control columns -> the plant's kernel) and the state
check. The last row's command is recorded, never applied. It returns (rows written, status,
state). Between blocks Python flushes the sinks, detects events, reports progress and lets Ctrl-C
(a KeyboardInterrupt) in, exactly where the Python loop does.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core.errors import NumbaError

from usv_mj.core.errors import PluginContractError, compiler_summary, plain_text
from usv_mj.core.kernels import Kernel, kernel_blocker, kernel_of
from usv_mj.loop.generate import _source_fingerprint, cache_dir, generate, kernel_name, load_generated  # noqa: F401 (API)
from usv_mj.record.run_record import COL, N_CORE

# statuses returned by run_block
BLOCK_END, DONE, FORCE_LIMIT, PLANT_FAILED, DIVERGED, HOOK, DIAG_MISMATCH = 0, 1, 2, 3, 4, 5, 6

_ROLES = ("ref", "ctrl", "step", "plant", "hook")

_TEMPLATE = '''

@njit(cache=True)
def run_block(k, stop, n, dt, data, base, n_diag, max_force, max_speed, max_yaw_rate, max_distance, x, out, resume,
              ref_a, ctrl_a, step_a, plant_a, hook_a):
    while True:
        t = k * dt
        if not resume and hook_fn(k, t, x, {hook_args}):  # the hook's step, unless Python just did it
            return k, {HOOK}, x
        resume = False
        ref = ref_fn(t, {ref_args})
        tau_u, tau_r, diag = ctrl_fn(t, x, ref, {ctrl_args})
        if len(diag) != n_diag:  # the controller's contract (diagnostic_fields), before the row takes it
            out[0] = len(diag)
            return k, {DIAG_MISMATCH}, x
        row = data[k - base]  # data holds the record's window: rows base..
        row[{c_t}] = t
        for i in range(6):
            row[{c_x} + i] = x[i]
        for i in range(7):
            row[{c_x_d} + i] = ref[i]
        for i in range(n_diag):
            row[{n_core} + i] = diag[i]
        if not (abs(tau_u) < max_force and abs(tau_r) < max_force):
            out[0] = tau_u
            out[1] = tau_r
            return k, {FORCE_LIMIT}, x
        if k >= n:  # the last row: its command is recorded, never applied
            control_step(tau_u, tau_r, x, row, {step_args})
            return k + 1, {DONE}, x
        x, failed = advance(k, x, tau_u, tau_r, row, step_a, plant_a)
        k += 1
        if failed:
            return k, {PLANT_FAILED}, x
        if not within_limits(x, x[0] - row[{c_x_d}], x[1] - row[{c_y_d}], max_speed, max_yaw_rate, max_distance):
            return k, {DIVERGED}, x
        if k >= stop:  # back to Python (sinks, events, progress, Ctrl-C) before the next row
            return k, {BLOCK_END}, x
'''


#: what ``run_block``'s template imports beside the kernels, and the numbers formatted into it
BLOCK_IMPORTS = "from usv_mj.physics.limits import within_limits"
BLOCK_FIELDS = dict(n_core=N_CORE, BLOCK_END=BLOCK_END, DONE=DONE, FORCE_LIMIT=FORCE_LIMIT, PLANT_FAILED=PLANT_FAILED,
                    DIVERGED=DIVERGED, HOOK=HOOK, DIAG_MISMATCH=DIAG_MISMATCH,
                    **{f"c_{c}": COL[c] for c in ("t", "x", "x_d", "y_d")})


def block_kernels(kernels: dict) -> dict:
    """{role: (kernel function, number of its arguments)}: what the generator takes (usv_mj.loop.generate)."""
    return {role: (kernels[role].fn, len(kernels[role].args)) for role in _ROLES}


def compiled_block(kernels: dict):
    """The generated ``run_block`` for this combination of kernels (module docstring)."""
    module = generate("usv_mj_loop", _TEMPLATE, block_kernels(kernels), imports=BLOCK_IMPORTS, **BLOCK_FIELDS)
    return module.run_block


@njit(cache=True)
def no_hook(k, t, x):
    """The hook role of a run without hooks: nothing to do, never Python."""
    return False


def kernels_of(parts, hooks=None, step=None) -> tuple[dict | None, str]:
    """The parts' kernels (but the plant's, taken per block), or None and why the Python loop must
    run; ``step``: the run's :class:`usv_mj.loop.step.ControlStep` (its kernel is the chain's)."""
    hooks = tuple(parts.hooks if hooks is None else hooks)
    found = {"hook": Kernel(no_hook, ())}
    if len(hooks) > 1:
        return None, "the run has several hooks (" + ", ".join(type(h).__name__ for h in hooks) + ")"
    if hooks:
        blocked = kernel_blocker(hooks[0])
        if blocked is not None:
            return None, f"the hook: {blocked}"
        make = kernel_of(hooks[0])
        found["hook"] = make() if make is not None else None
        if found["hook"] is None:
            return None, f"the hook ({type(hooks[0]).__name__}) has Python logic (moving obstacles, guidance, ...)"
    if step is not None:
        found["step"] = step.kernel()
    roles = (("ref", parts.reference, "reference"), ("ctrl", parts.controller, "controller"),
             ("plant", parts.plant, "plant"))
    for role, part, label in roles:
        blocked = kernel_blocker(part) if part is not None else None
        if blocked is not None:  # a subclass's Python must run (usv_mj.core.kernels: the rule)
            return None, f"the {label}: {blocked}"
        if role == "plant":  # its kernel is taken per block (run_compiled)
            if kernel_of(part) is None:
                return None, f"the plant ({type(part).__name__}) has no kernel"
            continue
        make = kernel_of(part) if part is not None else None
        k = make() if make is not None else None
        if k is None:
            return None, f"the {label} ({type(part).__name__}) has no kernel"
        found[role] = k
    t_max = getattr(parts.reference, "t_max", None)
    if t_max is not None and t_max < parts.duration:
        return None, f"the reference's table ends at {t_max:g} s, before the run's end"
    return found, ""


def run_compiled(record, parts, kernels, block, flush, limits, dt, n, hooks=()):
    """Rows of ``record`` until the run ends; returns (k, status, x, out) at the stop (see _run).
    A hook kernel that answers "Python" gets the Python hooks called for that row (the plant and
    the parts synced first), then the block goes on from the same row."""
    plant = parts.plant
    data = record.buffer
    n_diag = len(record.diagnostic_fields)
    x = np.array(plant.state, dtype=np.float64)
    out = np.zeros(2)
    k = 0
    run_block = None
    syncs = [kernels[r].sync for r in ("ref", "ctrl", "step", "hook") if kernels[r].sync is not None]
    resume, stop, pk = False, 0, None
    release = None
    try:
        while True:
            if not resume:
                stop = min(k + block, n + 1, record.base + len(data))  # never past the window
                pk = plant.kernel(stop * dt)
                if pk is None:  # cannot happen after kernels_of, but keep the loop honest
                    raise RuntimeError("the plant's kernel went away during the run")
                kernels["plant"] = pk
                if run_block is None:
                    run_block = compiled_block(kernels)
                    release = _hold_signals()   # its first call may compile it
            try:
                k, status, x = run_block(k, stop, n, dt, data, record.base, n_diag, limits.max_force,
                                         limits.max_speed, limits.max_yaw_rate, limits.max_distance, x, out, resume,
                                         *(kernels[r].args for r in _ROLES))
            except NumbaError as exc:   # the loop could not be compiled: which kernel, in one line
                raise compile_error(kernels, exc) from None
            resume = False
            more = _after(record, k, status, x, pk, syncs, flush, block)
            if release is not None:
                release, deliver = None, release
                deliver()
            if status == HOOK:  # Python does this row's hook work, then the block goes on from it
                for hook in hooks:
                    hook(k * dt, k, plant)
                resume = True
                continue
            if more:
                continue
            return _stop(k, status, x, out, pk)
    finally:
        if release is not None:
            release(deliver=False)
        for sync in syncs:
            sync()


def compile_error(kernels: dict, exc: BaseException) -> Exception:
    """The error of a generated loop numba could not compile: a plug-in's kernel named (a
    :class:`PluginContractError`: its module and function, numba's reason in one line, the fix), else
    usv_mj's own defect (RuntimeError), never numba's dozens of highlighted lines."""
    reason = compiler_summary(str(exc)) or " ".join(plain_text(exc).split())
    plugins = [(role, *kernel_name(kernels[role].fn)) for role in _ROLES]
    plugins = [(role, m, n) for role, m, n in plugins if not m.startswith("usv_mj.")]
    if not plugins:
        return RuntimeError(f"the compiled loop could not be compiled: {type(exc).__name__}: {reason}")
    names = ", ".join(f"{_LABELS[role]} kernel {m}.{n}" for role, m, n in plugins)
    return PluginContractError(f"numba cannot compile the loop with the plug-in's {names}: {reason}; a kernel is an "
                               f"njit function numba can type with the loop's arguments (usv_mj.core.kernels): "
                               f"fix it, or give the part no kernel (the Python loop runs it)")


_LABELS = {"ref": "reference", "ctrl": "controller", "step": "control step", "plant": "plant", "hook": "hook"}


def _hold_signals():
    """Keep the Python signal handlers (Ctrl-C, SIGTERM, SIGHUP) from running while numba compiles
    the loop (seconds, on a cold cache): an exception raised inside numba's compiler leaves it
    broken ("no compiled object yet"). Returns ``release(deliver=True)``, which puts the handlers
    back and runs the held ones, so the run stops just after, as anywhere else. Outside the main
    thread (no handlers to set) it holds nothing."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda deliver=True: None
    held, old = [], {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        handler = signal.getsignal(sig) if sig is not None else None
        if callable(handler):
            old[sig] = handler
            signal.signal(sig, lambda signum, frame: held.append((signum, frame)))

    def release(deliver: bool = True):
        for sig, handler in old.items():
            signal.signal(sig, handler)
        if deliver:
            for signum, frame in held:
                old[signum](signum, frame)

    return release


def _after(record, k, status, x, pk, syncs, flush, block) -> bool:
    """The Python side of a run_block return: rows, the parts' and the plant's state, the sinks'
    flush where the Python loop flushes; True when the loop goes on (a block ended, or a hook row
    that Python does next)."""
    record.n_rows = k + 1 if status == FORCE_LIMIT else k
    for sync in syncs:
        sync()
    # plant steps taken: one per row written, but the last row's (never applied) when the run is done
    pk.sync(k - 1 if status == DONE else k, x)
    if status in (FORCE_LIMIT, DIAG_MISMATCH):  # the Python loop stops before its flush check
        return False
    if status == HOOK:
        return True
    if k - flush.mark >= block or k >= record.base + len(record.buffer):  # where the Python loop
        flush(k)                                                     # flushes, or the window is full
    return status == BLOCK_END


def _stop(k, status, x, out, pk):
    if status == PLANT_FAILED:
        pk.fail(k - 1)
    return k, status, x, out
