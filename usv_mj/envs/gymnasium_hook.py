"""``gymnasium.make("usv_mj/Track-v0")`` with no import of usv_mj first: the start-up hook's second half.

Gymnasium 1.x no longer loads a package's environments through the ``gymnasium.envs`` entry-point
group (its ``gymnasium/envs/__init__.py`` registers only its own ids, and no Gymnasium module reads
entry points any more), so an installed package's ids exist only once something imports it. The
wheel therefore ships one start-up file, ``usv_mj-gymnasium.pth`` (``packaging/`` in the checkout;
``setup.py`` puts it at the top of site-packages), whose one executable line does only this at
interpreter start-up, in about 10 us:

- unless the environment variable ``USV_MJ_NO_GYMNASIUM_HOOK`` is set (to anything but empty),
  put a tiny finder first on ``sys.meta_path`` that answers nothing but the import of the top-level
  module ``gymnasium`` (every other import passes it after one string comparison);
- any exception is swallowed: start-up never fails and prints nothing because of it.

When a program imports ``gymnasium`` (or any ``gymnasium.*``), that finder calls
:func:`spec_with_registration` here. It finds gymnasium's real spec through the other finders
and returns it with the loader's ``exec_module`` wrapped: once gymnasium's own ``__init__`` has run,
the finder leaves ``sys.meta_path`` and :func:`register` imports :mod:`usv_mj.envs`, whose
:func:`~usv_mj.envs.register_gymnasium` registers the id of every task with string entry
points (``usv_mj.envs.gymnasium_env:USVGymEnv``): neither dm_control nor MuJoCo is imported until
``gymnasium.make`` asks for an environment. That costs about 4 ms once, on top of gymnasium's own
~150 ms import; any failure in it is swallowed too (then ``gymnasium.make("usv_mj/Track-v0")``
says ``NamespaceNotFound`` as without the hook, and ``"usv_mj.envs:usv_mj/Track-v0"`` still works).

Editable installs (``pip install -e``) get no hook: a checkout imports what it needs.
Python 3.15+ (PEP 829) still runs ``.pth`` import lines through 3.17; a ``.start`` entry point
would import this package at every start-up, so none is shipped.
"""

from __future__ import annotations

import os
import sys

OPT_OUT = "USV_MJ_NO_GYMNASIUM_HOOK"  # set to anything but "" to skip the hook (checked again here)


def spec_with_registration(hook, name: str, path=None, target=None):
    """Gymnasium's module spec as the finders after ``hook`` find it, with :func:`register` run right
    after the module has executed; the plain spec (or None) when the loader cannot be wrapped."""
    spec = None
    for finder in list(sys.meta_path):
        find = getattr(finder, "find_spec", None)
        if finder is hook or find is None:
            continue
        spec = find(name, path, target)
        if spec is not None:
            break
    loader = getattr(spec, "loader", None)
    original = getattr(loader, "exec_module", None)
    if original is None:
        return spec

    def exec_module(module):
        try:
            del loader.exec_module  # the loader's own method again (a loader may serve other modules)
        except AttributeError:
            pass
        original(module)
        if module.__name__ == name:
            try:
                sys.meta_path.remove(hook)
            except ValueError:
                pass
            register()

    try:
        loader.exec_module = exec_module
    except (AttributeError, TypeError):
        pass
    return spec


def register() -> None:
    """Register usv_mj's Gymnasium ids (:func:`usv_mj.envs.register_gymnasium`); never raises."""
    if os.environ.get(OPT_OUT):
        return
    try:
        from usv_mj.envs import register_gymnasium

        register_gymnasium()
    except Exception:  # noqa: BLE001 - a hook must not break the user's import of gymnasium
        pass
