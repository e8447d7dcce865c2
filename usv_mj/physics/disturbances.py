"""The disturbance d(t): the kinds a scenario's ``[disturbance] kind`` names, and the one dispatch.

A disturbance kind (:data:`usv_mj.core.registry.DISTURBANCES`; docs/model.md §1, "d(t)") is

- an **options dataclass**, validated at construction (``__post_init__`` raises ValueError naming
  the field), with the unit of each field in its documentation;
- ``as_array()``: its parameters packed as at most :data:`D_MAX_WORDS` float64 words;
- a class attribute ``kernel``: a ``numba.njit`` function ``kernel(dp, t) -> (f_x [N], f_y [N],
  f_n [N m])``, the body-frame force at time ``t`` [s] from the packed parameters ``dp`` (its own
  words first: ``dp[0]`` is ``as_array()[0]``). It must not allocate per call if it is to be fast
  (return a tuple) and must not raise (it runs inside MuJoCo's callback).

The paper's d(t) of Eq. 46 (:class:`PaperDisturbance`, kernel :func:`disturbance_terms`) is the
built-in kind "paper". A kind registers like any other part::

    @DISTURBANCES.register("squall", options=Squall)
    @dataclass(frozen=True)
    class Squall(Disturbance):
        ...
        kernel = squall_kernel

or is named ``"package.module:Squall"`` / declared as an entry point of the group
``usv_mj.disturbances`` (examples/plugins/usv_mj_example_plugin/.../squall.py).

**The packed vector** (:func:`packed_disturbance`) that the plants carry is :data:`N_DIST_WORDS`
words: the kind's ``as_array()`` zero-padded to :data:`D_MAX_WORDS` words, then one dispatch word at
:data:`D_KERNEL`: 0.0 for the paper's kernel, else the address (an integer < 2^53, exact in a
float64, as the sea's grid addresses in the MuJoCo userdata) of a numba ``cfunc``
``void d(const double* dp, double t, double* out)`` wrapping the kind's kernel, built once per
process per kernel and kept alive here (:func:`kernel_address`). :func:`disturbance_at` (njit)
branches on that word: the paper's kernel is called directly (bit for bit and as fast as before
the dispatch existed), any other through its address. ``usv_mj.physics.ship.hull_terms`` calls it,
so both plants, both loops and the MuJoCo callback evaluate a kind's d(t) at every RK4 stage time.
A vector shorter than :data:`N_DIST_WORDS` (``PaperDisturbance().as_array()`` handed to a kernel
directly, as before) is the paper's. The address is valid in the process that packed it only:
pack in the process that steps (the plants do, when they are made).

The Python face of any kind, :func:`evaluate_disturbance` of an instance (and ``force(t)`` of
:class:`Disturbance`, the paper's included), calls the same kernel: one implementation.
"""

from __future__ import annotations

import dataclasses
import math
import threading
from dataclasses import dataclass

import numpy as np
from llvmlite import ir as llvm_ir
from numba import carray, cfunc, njit, types
from numba.core import cgutils
from numba.core.registry import CPUDispatcher
from numba.extending import intrinsic

from usv_mj.core.errors import PluginContractError
from usv_mj.core.registry import DISTURBANCES

# --- the packed vector --------------------------------------------------------------------------
#: the longest ``as_array()`` of a kind [words]
D_MAX_WORDS = 16
#: the dispatch word: 0.0 (the paper's kernel) or the address of the kind's cfunc
D_KERNEL = D_MAX_WORDS
#: words of the packed vector (the plants' ``dp``, the MuJoCo userdata's block at U_DP)
N_DIST_WORDS = D_KERNEL + 1
#: the paper's own words (PaperDisturbance.as_array(), N_DIST_PARAMS of them): scale, amplitudes (3),
#: cos frequencies (3), sin frequencies (3)
D_SCALE, D_AMP, D_WCOS, D_WSIN = 0, 1, 4, 7
N_DIST_PARAMS = 10


@njit(cache=True)
def disturbance_terms(dp, t):
    """The paper's disturbance d(t) (Sec. 4) times its scale, body frame [N, N, N m], a 3-tuple:
    d_i = s a_i (cos(wc_i t) + sin(ws_i t)). The kernel of :class:`PaperDisturbance`."""
    s = dp[D_SCALE]
    return (s * dp[D_AMP] * (math.cos(dp[D_WCOS] * t) + math.sin(dp[D_WSIN] * t)),
            s * dp[D_AMP + 1] * (math.cos(dp[D_WCOS + 1] * t) + math.sin(dp[D_WSIN + 1] * t)),
            s * dp[D_AMP + 2] * (math.cos(dp[D_WCOS + 2] * t) + math.sin(dp[D_WSIN + 2] * t)))


# --- the dispatch -------------------------------------------------------------------------------

@intrinsic
def _call_kernel_at(typingctx, address, dp, t):
    """``f(dp.data, t, out)`` for the C function ``void f(const double*, double, double*)`` at
    ``address`` (int64), with ``out`` three doubles on the stack; returns them as a 3-tuple
    (numba intrinsic: the address is an argument, so callers stay cacheable)."""
    if not (isinstance(dp, types.Array) and dp.ndim == 1 and dp.dtype == types.float64):
        return None
    sig = types.UniTuple(types.float64, 3)(types.int64, dp, types.float64)

    def codegen(context, builder, signature, args):
        f64 = llvm_ir.DoubleType()
        f64p = f64.as_pointer()
        fnty = llvm_ir.FunctionType(llvm_ir.VoidType(), [f64p, f64, f64p])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        data = context.make_array(signature.args[1])(context, builder, value=args[1]).data
        out = cgutils.alloca_once(builder, f64, size=3)  # in the entry block: no allocation per call
        builder.call(fn, [builder.bitcast(data, f64p), args[2], out])
        values = [builder.load(cgutils.gep(builder, out, i)) for i in range(3)]
        return context.make_tuple(builder, signature.return_type, values)

    return sig, codegen


@njit(cache=True)
def disturbance_at(dp, t):
    """d(t) of the packed vector ``dp`` (module docstring), body frame [N, N, N m], a 3-tuple: the
    paper's kernel when the dispatch word ``dp[D_KERNEL]`` is 0.0 (or ``dp`` is a bare paper
    vector, shorter than N_DIST_WORDS), else the kind's kernel through its cfunc's address.
    ``dp`` must be contiguous (the packed vectors and the userdata block are)."""
    if dp.shape[0] > D_KERNEL and dp[D_KERNEL] != 0.0:
        return _call_kernel_at(np.int64(dp[D_KERNEL]), dp, t)
    return disturbance_terms(dp, t)


_CFUNCS: dict = {}         # kernel -> its cfunc, kept alive for the process (its address is in packed vectors)
_CFUNCS_LOCK = threading.Lock()
_CFUNC_SIG = types.void(types.CPointer(types.float64), types.float64, types.CPointer(types.float64))


def _native_wrapper(kernel):
    """The cfunc ``void d(const double* dp, double t, double* out)``: out = kernel(dp, t)."""

    @cfunc(_CFUNC_SIG, error_model="numpy")
    def native(dp_ptr, t, out_ptr):
        dp = carray(dp_ptr, (N_DIST_WORDS,))
        out = carray(out_ptr, (3,))
        f = kernel(dp, t)
        out[0] = f[0]
        out[1] = f[1]
        out[2] = f[2]

    return native


def kernel_address(kernel, kind: str = "") -> float:
    """The dispatch word of ``kernel``: 0.0 for the paper's (:func:`disturbance_terms`), else the
    address of its cfunc (compiled once per process per kernel, about a second; kept alive here).
    A kernel that numba cannot compile as ``kernel(float64[::1], float64) -> 3 numbers`` is a
    :class:`PluginContractError` naming ``kind``."""
    if kernel is disturbance_terms:
        return 0.0
    with _CFUNCS_LOCK:
        native = _CFUNCS.get(kernel)
        if native is None:
            try:
                native = _native_wrapper(kernel)
            except Exception as exc:  # numba's TypingError and friends: the plug-in's kernel is wrong
                first = next((line.strip() for line in str(exc).splitlines() if line.strip()), type(exc).__name__)
                raise PluginContractError(
                    f"{_head(kind, kernel)}: its kernel {_qualname(kernel)} does not compile as "
                    f"kernel(dp: float64[:], t: float64) -> (f_x, f_y, f_n) ({type(exc).__name__}: {first})"
                ) from None
            _CFUNCS[kernel] = native
    address = float(native.address)
    if not (0 < address < 2.0**53):
        raise RuntimeError(f"the cfunc of {_qualname(kernel)} is at {native.address:#x}, beyond 2^53")
    return address


# --- the contract -------------------------------------------------------------------------------

class Disturbance:
    """An optional base of a disturbance kind: its Python face ``force(t)`` from the kind's own
    ``kernel`` (so that there is one implementation of d(t); see :func:`evaluate_disturbance`)."""

    kernel = None  # the kind's njit kernel(dp, t) -> (f_x [N], f_y [N], f_n [N m])

    def force(self, t: float) -> np.ndarray:
        """d(t) in the body frame [N, N, N m]: the kind's kernel on ``as_array()``."""
        return evaluate_disturbance(self, t)


def evaluate_disturbance(disturbance, t: float) -> np.ndarray:
    """d(t) of any disturbance kind's instance in the body frame [N, N, N m]: its kernel on its own
    ``as_array()`` (the words the plants' packed vector starts with). The Python face of d(t)
    (``force(t)`` of :class:`Disturbance`); for a packed vector use
    :func:`usv_mj.physics.ship.disturbance_force`."""
    f = type(disturbance).kernel(_own_words(disturbance), float(t))
    return np.array((f[0], f[1], f[2]), dtype=np.float64)


def kind_of(disturbance) -> str:
    """The kind ``disturbance``'s class is registered under ("" if none is known in this process)."""
    cls = type(disturbance) if not isinstance(disturbance, type) else disturbance
    for entry in DISTURBANCES.entries(load=False):
        if entry.obj is cls or entry.options_class is cls:
            return entry.kind
    return ""


def check_disturbance(disturbance, kind: str = "") -> None:
    """Raise :class:`PluginContractError` (naming ``kind``, or the class) unless ``disturbance``
    keeps the contract of the module docstring: a dataclass instance whose class's ``kernel`` is a
    ``numba.njit`` function, whose ``as_array()`` gives 1 to D_MAX_WORDS finite numbers, and which
    does not define its own ``force`` beside the kernel (the plants would never see it)."""
    cls = type(disturbance)
    head = _head(kind or kind_of(disturbance), cls)
    if not dataclasses.is_dataclass(cls):
        raise PluginContractError(f"{head}: must be a dataclass (its fields are the [disturbance] table's keys), "
                                  f"got {cls.__qualname__}")
    kernel = getattr(cls, "kernel", None)
    if kernel is None:
        raise PluginContractError(f"{head}: has no kernel: give the class the attribute kernel = an @numba.njit "
                                  f"function kernel(dp, t) -> (f_x [N], f_y [N], f_n [N m]) (docs/model.md, d(t))")
    if not isinstance(kernel, CPUDispatcher):
        what = f"the plain Python function {_qualname(kernel)}" if callable(kernel) else repr(kernel)
        raise PluginContractError(f"{head}: its kernel must be an @numba.njit function kernel(dp, t) -> "
                                  f"(f_x [N], f_y [N], f_n [N m]) (the plants call it at every RK4 stage, in "
                                  f"native code), got {what}")
    force = getattr(cls, "force", None)
    if force is not None and force is not Disturbance.force:
        raise PluginContractError(f"{head}: defines its own force(t) beside its kernel; the plants call only the "
                                  f"kernel, so write d(t) there once (inherit usv_mj.physics.disturbances.Disturbance "
                                  f"for force(t))")
    _own_words(disturbance, head)


def packed_disturbance(disturbance, kind: str = "") -> np.ndarray:
    """The packed vector of ``disturbance`` (module docstring: N_DIST_WORDS words, the dispatch
    word last), after :func:`check_disturbance`. Made in the process that steps the plant."""
    check_disturbance(disturbance, kind)
    own = _own_words(disturbance)
    out = np.zeros(N_DIST_WORDS)
    out[:own.size] = own
    out[D_KERNEL] = kernel_address(type(disturbance).kernel, kind or kind_of(disturbance))
    return out


def _own_words(disturbance, head: str = "") -> np.ndarray:
    try:
        own = np.asarray(disturbance.as_array(), dtype=np.float64)
    except Exception as exc:
        head = head or _head(kind_of(disturbance), type(disturbance))
        raise PluginContractError(f"{head}: as_array() must give its parameters as float64 numbers "
                                  f"({type(exc).__name__}: {exc})") from None
    if own.ndim != 1 or not 1 <= own.size <= D_MAX_WORDS or not np.all(np.isfinite(own)):
        head = head or _head(kind_of(disturbance), type(disturbance))
        what = (f"{own.size} words" if own.ndim == 1 else f"an array of shape {own.shape}")
        if own.ndim == 1 and 1 <= own.size <= D_MAX_WORDS:
            what = f"a non-finite word at {int(np.flatnonzero(~np.isfinite(own))[0])}"
        raise PluginContractError(f"{head}: as_array() must give 1 to {D_MAX_WORDS} finite numbers "
                                  f"(usv_mj.physics.disturbances.D_MAX_WORDS), got {what}")
    return np.ascontiguousarray(own)


def _qualname(obj) -> str:
    return f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', None) or getattr(obj, '__name__', repr(obj))}"


def _head(kind: str, obj) -> str:
    return f"disturbance kind {kind!r}" if kind else f"disturbance {_qualname(obj)}"


# --- the paper's d(t), the built-in kind ---------------------------------------------------------

@dataclass(frozen=True)
class PaperDisturbance(Disturbance):
    """The paper's environmental disturbance d(t) (docs/model.md §1), scaled by ``scale``.

    d(t) = scale * [A_1 (cos w_c1 t + sin w_s1 t), A_2 (...), A_3 (...)] in body-frame [N, N, N m].

    Attributes
    ----------
    scale:
        s of docs/model.md §1 [-] (>= 0): 1 is the paper as printed, 1e-4 the ``paper`` preset.
    amplitudes:
        A_i [N, N, N m]; printed 1e4, 1e2, 1e5.
    cos_frequencies, sin_frequencies:
        [rad/s]; printed (0.5, 0.4, 0.2) and (0.3, 0.2, 0.5).
    """

    scale: float = 1e-4
    amplitudes: tuple[float, float, float] = (1e4, 1e2, 1e5)
    cos_frequencies: tuple[float, float, float] = (0.5, 0.4, 0.2)
    sin_frequencies: tuple[float, float, float] = (0.3, 0.2, 0.5)

    kernel = disturbance_terms

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale >= 0):
            raise ValueError(f"disturbance.scale must be a finite number >= 0, got {self.scale!r}")

    def as_array(self) -> np.ndarray:
        """The paper's N_DIST_PARAMS words: D_SCALE, D_AMP (3), D_WCOS (3), D_WSIN (3)."""
        dp = np.zeros(N_DIST_PARAMS)
        dp[D_SCALE] = self.scale
        dp[D_AMP : D_AMP + 3] = self.amplitudes
        dp[D_WCOS : D_WCOS + 3] = self.cos_frequencies
        dp[D_WSIN : D_WSIN + 3] = self.sin_frequencies
        return dp


DISTURBANCES.register("paper", options=PaperDisturbance, doc="the paper's d(t), Eq. 46, times `scale`")(PaperDisturbance)
