"""Native MuJoCo calls: raw pointers, C functions of libmujoco by address, and mjData's field offsets.

What a numba kernel needs to call MuJoCo with no Python in between (the MuJoCo plant's passive
callback and kernel, the clearance monitor's distance queries, the environments' rangefinders):
integers reinterpreted as pointers, ``void f(const mjModel*, mjData*)`` called at an address, the
address of a libmujoco function, and the byte offsets of the mjData / mjModel fields the kernels
read (found once per process by comparing memory, :func:`struct_offsets`).
"""

from __future__ import annotations

import ctypes
import functools
import os

import mujoco
import numpy as np
from llvmlite import ir as llvmlite_ir
from numba import types
from numba.extending import intrinsic

from usv_mj.support.assets import models_dir
from usv_mj.support.pointers import f64_ptr, i64_ptr

MODELS_DIR = str(models_dir())  # the installed usv_mj.models (the checkout's models/)


# integers as pointers: usv_mj.support.pointers (one implementation, also for kernels without MuJoCo)
_f64_ptr, _i64_ptr = f64_ptr, i64_ptr


@intrinsic
def call_model_data(typingctx, fn_address, m_addr, d_addr):
    """Call the C function ``void f(const mjModel*, mjData*)`` at ``fn_address`` (numba intrinsic).

    The address is an argument, not a ctypes global, so that functions calling it can be cached."""
    sig = types.void(types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        i64 = context.get_value_type(types.int64)
        fnty = llvmlite_ir.FunctionType(llvmlite_ir.VoidType(), [i64, i64])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(fn, [args[1], args[2]])
        return context.get_dummy_value()

    return sig, codegen


# --- locating mjData / mjModel fields in native memory ------------------------------------------

_PROBE_XML = """
<mujoco><size nuserdata="{n}"/><worldbody><body><joint type="slide" axis="1 0 0"/>
<joint type="slide" axis="0 1 0"/><joint type="hinge" axis="0 0 1"/>
<inertial pos="0.1 0 0" mass="1" diaginertia="1 1 1"/></body>
<body mocap="true"><geom size="0.1" contype="0" conaffinity="0"/></body></worldbody>
<actuator><general joint="yaw" dyntype="filter" dynprm="0.1"/></actuator></mujoco>
""".replace('joint="yaw"', 'joint="j3"').replace('type="hinge"', 'type="hinge" name="j3"')

_DATA_ARRAYS = ("qpos", "qvel", "ctrl", "M", "qfrc_passive", "userdata")


def _read(address: int, n: int, ctype) -> np.ndarray:
    return np.ctypeslib.as_array((ctype * n).from_address(address)).copy()


def _first_hit(address: int, value, ctype, start_word: int = 0, max_words: int = 1 << 20) -> int:
    """Index of the first word equal to ``value`` from ``start_word`` on, reading forward in chunks."""
    step = 64
    for start in range(start_word, start_word + max_words, step):
        chunk = _read(address + start * ctypes.sizeof(ctype), step, ctype)
        idx = np.flatnonzero(chunk == value)
        if idx.size:
            return int(start + idx[0])
    raise RuntimeError(f"struct field with value {value!r} not found")


def _candidate_offsets(model: mujoco.MjModel) -> dict[str, set[int]]:
    """All byte offsets in a fresh mjData of ``model`` that could hold each field of interest."""
    d = mujoco.MjData(model)
    out: dict[str, set[int]] = {}
    times = set()
    for value in (1.2345678901234567e-3, -9.87654321e5):
        d.time = value
        times.add(_first_hit(d._address, value, ctypes.c_double) * 8)
    d.time = 0.0
    if len(times) != 1:
        raise RuntimeError(f"cannot locate mjData.time (offsets {sorted(times)})")
    out["time"] = times
    t_word = next(iter(times)) // 8
    addresses = {name: getattr(d, name).ctypes.data for name in _DATA_ARRAYS}
    first = {name: _first_hit(d._address, a, ctypes.c_int64, t_word + 1) for name, a in addresses.items()}
    window = _read(d._address + (t_word + 1) * 8, max(first.values()) - t_word + 16, ctypes.c_int64)
    for name, a in addresses.items():
        out[name] = {int(t_word + 1 + i) * 8 for i in np.flatnonzero(window == a)}
    return out


_OFFSETS: dict[str, int] | None = None


def struct_offsets() -> dict[str, int]:
    """Byte offsets of ``time`` and the arrays of :data:`_DATA_ARRAYS` in mjData, ``nuserdata`` in mjModel.

    Found once per process by comparing memory: ``time`` is where a sentinel double written through
    the bindings appears (two sentinels must agree); a pointer field is a slot after ``time`` that
    holds the address of the bindings' numpy view. Zero-sized arrays can share an address with their
    neighbour (and the first array shares the buffer's address), so the candidates of two
    structurally different models (the hull of models/usv.xml and a probe with activation and
    mocap) are intersected and the last remaining slot is taken (arrays are laid out in struct
    order and the fields used here are never empty).
    ``nuserdata`` is the one mjModel word that equals 1009 in one probe and 1013 in the other.
    :func:`check_offsets` re-checks the result on every plant's own mjData.
    """
    global _OFFSETS
    if _OFFSETS is not None:
        return _OFFSETS
    hull = mujoco.MjModel.from_xml_path(os.path.join(MODELS_DIR, "usv.xml"))
    m1 = mujoco.MjModel.from_xml_string(_PROBE_XML.format(n=1009))
    m2 = mujoco.MjModel.from_xml_string(_PROBE_XML.format(n=1013))
    c1, c2 = _candidate_offsets(hull), _candidate_offsets(m1)
    off: dict[str, int] = {}
    for name in c1:
        both = c1[name] & c2[name]
        if not both:
            raise RuntimeError(f"cannot locate mjData.{name} (candidates {sorted(c1[name])} and {sorted(c2[name])})")
        # arrays are laid out in struct order, so a slot before the field (the buffer start, a
        # zero-sized array) may share its address, never one after it (our fields are non-empty)
        off[name] = max(both)
    w1 = _read(m1._address, 512, ctypes.c_int64)
    w2 = _read(m2._address, 512, ctypes.c_int64)
    idx = np.flatnonzero((w1 == 1009) & (w2 == 1013))
    if idx.size != 1:
        raise RuntimeError(f"cannot locate mjModel.nuserdata (candidates {idx.tolist()})")
    off["nuserdata"] = int(idx[0]) * 8
    _OFFSETS = off
    return off


def check_offsets(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Raise if the located offsets do not hold ``data``'s fields (a MuJoCo layout change, say)."""
    off = struct_offsets()
    words = {name: int(_read(data._address + off[name], 1, ctypes.c_int64)[0]) for name in _DATA_ARRAYS}
    for name in _DATA_ARRAYS:
        if words[name] != getattr(data, name).ctypes.data:
            raise RuntimeError(f"mjData.{name} is not at byte offset {off[name]} in this MuJoCo build")
    if float(_read(data._address + off["time"], 1, ctypes.c_double)[0]) != data.time:
        raise RuntimeError(f"mjData.time is not at byte offset {off['time']} in this MuJoCo build")
    if int(_read(model._address + off["nuserdata"], 1, ctypes.c_int64)[0]) != model.nuserdata:
        raise RuntimeError(f"mjModel.nuserdata is not at byte offset {off['nuserdata']} in this MuJoCo build")


@functools.cache
def _libmujoco() -> ctypes.CDLL:
    folder = os.path.dirname(mujoco.__file__)
    names = sorted(f for f in os.listdir(folder) if f.startswith("libmujoco.so"))
    if not names:
        raise RuntimeError(f"libmujoco.so not found next to the mujoco package in {folder}")
    # the same file the bindings loaded: dlopen returns the already-loaded library
    return ctypes.CDLL(os.path.join(folder, names[-1]))


@functools.cache
def mujoco_function_address(name: str) -> int:
    """Address of the C function ``name`` of this process's libmujoco, for kernels that call MuJoCo
    natively (found once per process: loading the library through ctypes costs about 1 ms)."""
    return int(ctypes.cast(getattr(_libmujoco(), name), ctypes.c_void_p).value)
