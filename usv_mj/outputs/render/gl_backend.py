"""Choosing the OpenGL backend for off-screen rendering on machines with no display and no GPU.

MuJoCo's Python bindings bind their ``GLContext`` when ``mujoco`` is first imported, from the
``MUJOCO_GL`` environment variable (``egl``, ``osmesa``, ``glfw``, ...), and PyOpenGL binds its
platform from ``PYOPENGL_PLATFORM`` likewise. So the backend has to be chosen *before* a process
imports mujoco. On the CPU-only machines this project targets both EGL and OSMesa run on Mesa's
llvmpipe rasteriser (docs/model.md §1).

Rules (:func:`select_backend`):

1. an explicit request (the ``--gl`` option, or the ``gl=`` argument) wins;
2. otherwise the user's ``MUJOCO_GL`` environment variable, if set;
3. otherwise ``egl``, falling back to ``osmesa`` when EGL cannot start.

Every candidate is *probed in a subprocess* (a context that fails to start can leave the process
unusable, and a failed GLFW initialisation prints a stack trace), once per process; the answer is
cached. When no backend starts, :class:`GLUnavailableError` (a RuntimeError) carries ONE message
naming the Debian packages to install, which the CLI prints as is.

The renderer's worker processes are started with the ``spawn`` method and inherit the chosen
``MUJOCO_GL`` / ``PYOPENGL_PLATFORM`` from :func:`backend_environment`.
"""

from __future__ import annotations

import os
import subprocess
import sys

BACKENDS = ("egl", "osmesa", "glfw")

DEBIAN_PACKAGES = {
    "egl": "libegl1 libegl-mesa0 libgl1-mesa-dri libgles2",
    "osmesa": "libosmesa6",
    "glfw": "libglfw3 (and a running X display)",
}

_PROBE_CODE = r"""
import os, sys
try:
    import mujoco
    ctx = mujoco.GLContext(16, 16)
    ctx.make_current()
    from OpenGL import GL
    name = GL.glGetString(GL.GL_RENDERER)
    if not name:
        raise RuntimeError("the context did not become current (no display or no GL driver)")
    name = name.decode() if isinstance(name, bytes) else str(name)
    ctx.free()
except BaseException as exc:  # report one line, never a stack trace
    sys.stdout.write("FAIL " + type(exc).__name__ + ": " + str(exc).splitlines()[0][:300] if str(exc) else "FAIL " + type(exc).__name__)
    sys.stdout.flush()
    os._exit(1)
sys.stdout.write("OK " + name)
sys.stdout.flush()
os._exit(0)
"""

_cache: dict[str, tuple[bool, str]] = {}
_selected: str | None = None


class GLUnavailableError(RuntimeError):
    """No OpenGL backend could create an off-screen context; the message says what to install."""


def install_message(tried: dict[str, str] | None = None) -> str:
    """The one message shown when rendering cannot start: what failed and which packages to install."""
    lines = ["Off-screen rendering needs OpenGL through EGL or OSMesa (Mesa, runs without a GPU), "
             "and none could start."]
    for backend, detail in (tried or {}).items():
        lines.append(f"  MUJOCO_GL={backend}: {detail}")
    lines.append("Install the Mesa libraries (Debian/Ubuntu):")
    lines.append(f"  sudo apt-get install -y {DEBIAN_PACKAGES['egl']} {DEBIAN_PACKAGES['osmesa']}")
    lines.append("  (EGL: " + DEBIAN_PACKAGES["egl"] + "; OSMesa: " + DEBIAN_PACKAGES["osmesa"] + ")")
    lines.append("or choose a backend with --gl egl|osmesa or the MUJOCO_GL environment variable; "
                 "run with --no-video to skip the video.")
    return "\n".join(lines)


def backend_environment(backend: str) -> dict[str, str]:
    """The environment variables a process needs to render with ``backend`` (set before importing mujoco)."""
    env = {"MUJOCO_GL": backend}
    if backend in ("egl", "osmesa"):
        env["PYOPENGL_PLATFORM"] = backend
    return env


def probe(backend: str, timeout: float = 60.0) -> tuple[bool, str]:
    """Try to create a 16x16 context with ``backend`` in a fresh Python process.

    Returns (True, GL renderer name) or (False, one-line reason). Cached per process.
    """
    backend = backend.lower().strip()
    if backend in _cache:
        return _cache[backend]
    env = dict(os.environ)
    env.pop("PYOPENGL_PLATFORM", None)
    env.update(backend_environment(backend))
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE_CODE], env=env, capture_output=True, text=True,
                              timeout=timeout)
        out = proc.stdout.strip()
        if proc.returncode == 0 and out.startswith("OK"):
            result = (True, out[3:].strip())
        else:
            detail = out[5:].strip() if out.startswith("FAIL") else ""
            if not detail:
                err = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
                detail = err[-1][:300] if err else f"exit code {proc.returncode}"
            result = (False, detail)
    except subprocess.TimeoutExpired:
        result = (False, f"no answer within {timeout:.0f} s")
    except OSError as exc:
        result = (False, f"could not start a probe process: {exc}")
    _cache[backend] = result
    return result


def select_backend(requested: str | None = None) -> str:
    """Choose, probe and export the GL backend; returns its name (``egl``, ``osmesa``, ...).

    ``requested`` (e.g. the ``--gl`` option) overrides the ``MUJOCO_GL`` environment variable, which
    overrides the automatic choice (EGL, then OSMesa). Sets ``os.environ['MUJOCO_GL']`` (and
    ``PYOPENGL_PLATFORM``) so that worker processes inherit the choice.

    Raises :class:`GLUnavailableError` with the install message when nothing starts.
    """
    global _selected
    if requested is not None and str(requested).strip().lower() in ("", "auto"):
        requested = None
    if requested is None and _selected is not None:
        return _selected
    user = os.environ.get("MUJOCO_GL", "").strip().lower() or None
    if requested is not None:
        candidates = [str(requested).strip().lower()]
        origin = "--gl"
    elif user is not None:
        candidates = [user]
        origin = "MUJOCO_GL"
    else:
        candidates = ["egl", "osmesa"]
        origin = "auto"
    for c in candidates:
        if c not in BACKENDS:
            raise GLUnavailableError(f"{origin} = {c!r} is not a rendering backend; use one of "
                                     f"{', '.join(BACKENDS)}.")
    tried = {}
    for backend in candidates:
        ok, detail = probe(backend)
        if ok:
            os.environ.update(backend_environment(backend))
            if backend == "glfw":
                os.environ.pop("PYOPENGL_PLATFORM", None)
            _selected = backend
            return backend
        tried[backend] = detail
    raise GLUnavailableError(install_message(tried))


def check_gl(requested: str | None = None) -> str:
    """The backend in use (``"egl"`` or ``"osmesa"`` here), or RuntimeError with the install message."""
    return select_backend(requested)


def renderer_name(backend: str) -> str:
    """The GL_RENDERER string the probe saw (e.g. ``llvmpipe (LLVM 15.0.6, 256 bits)``), '' if unknown."""
    ok, detail = _cache.get(backend, (False, ""))
    return detail if ok else ""


def in_process_backend() -> str | None:
    """The backend mujoco is bound to in *this* process, or None when mujoco is not imported yet.

    When this differs from the selected backend the renderer must use worker processes.
    """
    if "mujoco" not in sys.modules:
        return None
    gl = sys.modules.get("mujoco.rendering.classic.gl_context")
    value = getattr(gl, "_MUJOCO_GL", None)
    if value is None:
        return "unknown"
    return value or "glfw"
