"""Native kernels behind the parts' interfaces (the compiled loop of :mod:`usv_mj.compiled_loop`).

A part that can run natively has, beside its Python interface (which stays as it is), a method
``kernel()`` (plants: ``kernel(t_end)``, the time [s] the coming block of steps reaches) returning a
:class:`Kernel`: a numba ``njit`` function defined at module level (so that the loop that calls it
can be generated, compiled and cached on disk) and the tuple of arguments (arrays and scalars,
its parameters and its state) that follow the loop's own arguments. The signatures:

- reference: ``fn(t, *args) -> ref`` (the 7-vector of usv_mj.controllers.base.REF_FIELDS);
- controller: ``fn(t, x, ref, *args) -> (tau_u, tau_r, diag)`` (``diag`` laid out as its
  ``diagnostic_fields``), like ``__call__``;
- quantizer: ``fn(tau, *args) -> (q, k)`` (the quantized value and the signed level index);
- actuators: ``fn(q_u, q_r, *args) -> (f_u, f_r, sat_u, sat_r)``, like ``apply``;
- plant: ``fn(k, x, f_u, f_r, *args) -> (x_new, failed)``: the plant's ``k``-th step (from t0 + k dt)
  from state ``x`` with the force held; ``failed`` when the step failed (the plant raises the error
  through ``Kernel.fail(k)``);
- hook: ``fn(k, t, x, *args) -> python``: the hook's work at row ``k`` (time ``t``, state ``x``),
  before the reference; True when Python must do it instead (the loop then calls the hook's
  ``__call__`` for that row and goes on): :mod:`usv_mj.obstacles.native_step`.

``sync`` (optional) writes the kernel's results back into the Python object after a block (the
quantizer's level and switch count; a plant's ``sync(k, x)``: its step count and state), so that
the object is where the Python loop would have left it. A part's kernel is used only when the class
that defines ``kernel`` also defines (or inherits below it) the Python method it stands for: a
subclass that overrides ``__call__`` / ``step`` / ``evaluate`` without a kernel of its own runs in
the Python loop.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple


class Kernel(NamedTuple):
    fn: Any
    args: tuple
    sync: Callable | None = None
    fail: Callable | None = None


def kernel_of(part, method: str):
    """The bound ``kernel`` method of ``part`` when it stands for ``method`` (module docstring), else None."""
    mro = type(part).__mro__
    k_owner = next((c for c in mro if "kernel" in c.__dict__), None)
    m_owner = next((c for c in mro if method in c.__dict__), None)
    if k_owner is None or m_owner is None or mro.index(m_owner) < mro.index(k_owner):
        return None
    fn = getattr(part, "kernel")
    return fn if callable(fn) else None
