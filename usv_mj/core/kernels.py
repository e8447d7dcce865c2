"""Native kernels behind the parts' interfaces (the compiled loop of :mod:`usv_mj.loop.compiled`).

A part that can run natively has, beside its Python interface (which stays as it is), a method
``kernel()`` (plants: ``kernel(t_end)``, the time [s] the coming block of steps reaches) returning a
:class:`Kernel`: a numba ``njit`` function defined at module level (so that the loop that calls it
can be generated, compiled and cached on disk) and the tuple of arguments (arrays and scalars,
its parameters and its state) that follow the loop's own arguments. The signatures:

- reference: ``fn(t, *args) -> ref`` (the vector of usv_mj.core.layouts.REF_VECTOR_FIELDS: the
  record's 7 entries, then the accelerations; the loops record the first 7);
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

``state`` (optional) names the arguments the kernel writes (by index into ``args``): what a
batch of episodes (:mod:`usv_mj.loop.batch`) must hold once per episode; every other argument is a
parameter, only read, which episodes with equal values share.

``sync`` (optional) writes the kernel's results back into the Python object after a block (a
plant's ``sync(k, x)``: its step count and state; the obstacle hook's rows), so that the object is
where the Python loop would have left it (parts whose state is the kernel's own arrays, such as the
quantizer's (k, output, switches), need none).

One implementation: a built-in part's Python method calls the same njit functions as its kernel
(e.g. ``LineReference.pose`` is :func:`usv_mj.references.trajectories.line_pose`, which ``line_kernel``
composes with the vector's assembly), so the two loops cannot drift apart.

When a kernel is used (:func:`kernel_blocker`, the one rule, for the compiled loop and the tasks'
native step): only for the class that defines ``kernel``. A subclass (or a mixin, or an instance
attribute) that adds or overrides any method, property or other descriptor below that class runs
in the Python loop, unless it defines a ``kernel`` of its own (then it answers for that kernel
standing for all its methods); the reason names the class and the
methods (``record.metadata["loop_reason"]``, e.g. "LineReference subclass WavyLine overrides
pose"). Allowed below the kernel's class, because the kernel is made from the object they built:
plain data attributes under a new name or of :data:`LABELS` (``kind = "wavy"``, ``name``, ``criterion``;
a class, such as an options dataclass, under a new name), the constructors ``__init__``, ``from_spec``, ``from_scenario``, and the names a class lists in its own ``KERNEL_NEUTRAL`` (a frozenset): methods
the kernel does not stand in for, which both loops call alike or neither calls (not the methods
the kernel replaces, nor anything they call; e.g. :class:`usv_mj.plants.harbour.HarbourPlant`'s
``rangefinders``, ``move_obstacles``, called by the Python hook in both loops, and ``close``). A
declaration holds for that name in every class below too. A data attribute that takes the place
of one the kernel's class (or a class above it) defines, with another value, keeps the Python loop
too (in the class or on the object): the kernel and its buffers were made for the kernel class's
value (a controller subclass that declares other ``diagnostic_fields`` would have its parent's
kernel write the parent's diagnostics into a record laid out for its own).

A controller's kernel may declare ``n_diag``, the length of the diag it returns; both loops check
the diag against the controller's ``diagnostic_fields`` (:func:`diag_mismatch`) before a row is
written, the compiled one before it starts when ``n_diag`` is declared.
"""

from __future__ import annotations

import types
from typing import Any, Callable, NamedTuple


class Kernel(NamedTuple):
    fn: Any
    args: tuple
    sync: Callable | None = None
    fail: Callable | None = None
    n_diag: int | None = None   # a controller's: the length of the diag it returns (None: not declared)
    #: which of ``args`` the kernel writes (its state, scratch, outputs), by index; None: not declared.
    #: The batched loop (usv_mj.loop.batch) gives each episode its own copy of these and shares the
    #: others (parameters, only read) between episodes whose values are equal; with None it copies
    #: every array per episode (always right, more memory).
    state: tuple | None = None


#: data no kernel reads, which a class below the kernel's (or the object) may give its own values:
#: the labels (messages, registries) and what the loop and the outputs read around the kernel, the
#: same way in both loops (how the run is judged, its 0/1 fields' event kinds, what the channels are)
LABELS = frozenset({"name", "kind", "criterion", "diagnostic_events", "commands"})

#: names a class below the kernel's may define (the class's bookkeeping and the constructors:
#: the kernel is made from the object they built, after them)
SAFE_NAMES = frozenset({
    "__module__", "__qualname__", "__doc__", "__dict__", "__weakref__", "__annotations__", "__firstlineno__",
    "__static_attributes__", "__orig_bases__", "__parameters__", "__slots__", "_abc_impl", "__abstractmethods__",
    "__dataclass_fields__", "__dataclass_params__", "__match_args__",
    "__init__", "from_spec", "from_scenario",
})


def _behaviour(name, value, k_owner) -> bool:
    """True for what can change what the part computes: functions, class/static methods, properties
    and every other descriptor (anything with ``__get__``), and callables; a class as attribute (an
    options dataclass a registry attaches) only when it takes the place of a name of the kernel's class."""
    if isinstance(value, (staticmethod, classmethod, property, types.FunctionType)):
        return True
    if isinstance(value, type):
        return any(name in c.__dict__ for c in k_owner.__mro__)
    return callable(value) or hasattr(type(value), "__get__")


_MISSING = object()


def _class_value(classes, name):
    """The value of ``name`` in the first of ``classes`` (an MRO) that defines it, or _MISSING."""
    return next((c.__dict__[name] for c in classes if name in c.__dict__), _MISSING)


def _differs(a, b) -> bool:
    """Whether two attribute values differ (anything that cannot say it is equal differs)."""
    if a is b:
        return False
    try:
        return not bool(a == b)
    except Exception:
        return True


def _changed_data(name, value, k_owner) -> bool:
    """True when ``value`` takes the place of a data attribute ``name`` of the kernel's class (or a
    class above it) with another value: the kernel and its buffers were made for the kernel class's
    value (a controller's ``diagnostic_fields``: the length of the diag its law writes)."""
    if name.startswith("__") or name in LABELS:
        return False
    old = _class_value(k_owner.__mro__, name)
    return old is not _MISSING and _differs(old, value)


def kernel_blocker(part) -> str | None:
    """Why ``part``'s kernel must not run (module docstring), or None when it may (or it has none:
    then :func:`kernel_of` says None)."""
    cls = type(part)
    mro = cls.__mro__
    k_owner = next((c for c in mro if "kernel" in c.__dict__), None)
    if k_owner is None:
        return None
    below = [c for c in mro if c not in k_owner.__mro__]
    neutral = SAFE_NAMES.union(*(c.__dict__.get("KERNEL_NEUTRAL", ()) for c in mro))
    for c in below:
        names = sorted(n for n, v in c.__dict__.items() if n not in neutral and _behaviour(n, v, k_owner))
        how = "subclass" if issubclass(c, k_owner) else "mixin"
        if names:
            return f"{k_owner.__name__} {how} {c.__name__} overrides {', '.join(names)} (and has no kernel of its own)"
        # data the kernel was made for, changed below it (the value the part sees: the lowest definition)
        names = sorted(n for n, v in c.__dict__.items() if n not in neutral and not _behaviour(n, v, k_owner)
                       and _class_value(mro, n) is v and _changed_data(n, v, k_owner))
        if names:
            return (f"{k_owner.__name__} {how} {c.__name__} changes {', '.join(names)} (the kernel was made for "
                    f"{k_owner.__name__}'s; and has no kernel of its own)")
    own = getattr(part, "__dict__", {})
    shadowed = sorted(n for n, v in own.items()
                      if (callable(v) and any(n in c.__dict__ for c in mro))
                      or (n not in neutral and _changed_data(n, v, k_owner)))
    if shadowed:
        return f"{cls.__name__} object has its own {', '.join(shadowed)} (instance attribute)"
    return None


def kernel_of(part, method: str | None = None):
    """The bound ``kernel`` method of ``part`` when its kernel may run (:func:`kernel_blocker`), else
    None. ``method`` (the Python method the kernel stands for) is not needed by the rule: kept for
    callers that name it."""
    if kernel_blocker(part) is not None:
        return None
    fn = getattr(part, "kernel", None)
    return fn if callable(fn) else None


def diag_mismatch(controller, n_returned: int) -> str | None:
    """The one-line contract error when a controller returns ``n_returned`` diagnostics but
    declares another number of ``diagnostic_fields`` (None when they agree)."""
    fields = tuple(getattr(controller, "diagnostic_fields", ()))
    if n_returned == len(fields):
        return None
    cls = type(controller)
    return (f"controller {cls.__module__}.{cls.__qualname__} returns {n_returned} diagnostics but declares "
            f"{len(fields)} diagnostic_fields {fields!r}: the diagnostics vector has one entry per name of "
            f"diagnostic_fields (controllers/base.py); declare the fields its law writes, or override "
            f"__call__ to return a vector of your own fields")


def diag_row_problem(controller, diag, n_fields: int) -> str | None:
    """At every row (the single run's Python loop and the fleet's): the contract error of
    :func:`diag_mismatch` when the ``diag`` the controller just returned does not have ``n_fields``
    entries (its ``diagnostic_fields``), checked before the row takes it (a 1-long diag would
    broadcast into the row); a diag that is not a vector counts as -1 entries. None when it fits."""
    try:
        if len(diag) == n_fields:
            return None
        n = len(diag)
    except TypeError:
        n = -1
    return diag_mismatch(controller, n)


def diag_contract(controller) -> str | None:
    """Before a run (both loops): when ``controller``'s kernel stands for its ``__call__`` (no class
    below the kernel's and no instance attribute replaces ``__call__``) and declares the length of
    its diag (``Kernel.n_diag``), the contract error if that length is not the number of the
    controller's ``diagnostic_fields`` (:func:`diag_mismatch`); else None (the loops then check
    every row's diag before writing it)."""
    cls = type(controller)
    k_owner = next((c for c in cls.__mro__ if "kernel" in c.__dict__), None)
    if k_owner is None or "__call__" in getattr(controller, "__dict__", {}) \
            or _class_value(cls.__mro__, "__call__") is not _class_value(k_owner.__mro__, "__call__"):
        return None
    make = getattr(controller, "kernel", None)
    k = make() if callable(make) else None
    n = getattr(k, "n_diag", None)
    return None if n is None else diag_mismatch(controller, int(n))
