"""Registries of the parts a scenario names by ``kind``: plants, controllers, trajectories, disturbances, vessels,
manoeuvres; and of the environments' tasks (:data:`TASKS`, :class:`TaskRegistry`).

As in dm_control's suite, a part registers itself where it is defined::

    from usv_mj.core.registry import CONTROLLERS

    @CONTROLLERS.register("my-law", options=MyGains)
    class MyController:
        name = "my-law"
        diagnostic_fields = ("e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3", "s")
        @classmethod
        def from_scenario(cls, gains, scenario): ...
        def reset(self): ...
        def __call__(self, t, state, reference): return tau_u, tau_r, diagnostics

and ``[controller] kind = "my-law"`` in a scenario finds it; its table's keys are validated
against ``MyGains``. Every registry works the same way:

- ``register(kind, options=OptionsDataclass, replace=False, **info)``: a decorator. ``options`` is
  the kind's typed options dataclass (the keys of its scenario table besides ``kind``; None: the
  kind takes none); controllers may say ``gains=`` (the same thing). A kind that exists is refused
  unless ``replace=True``.
- The factory: the registered object's ``from_scenario(options, scenario, **context)`` classmethod,
  or the object itself when it is a plain callable of that signature. ``context`` is the
  registry's own: trajectories get ``duration=`` [s] (the horizon the reference must cover);
  plants get ``environment=``, ``obstacles=``, ``contact=``, ``safety_radii=`` (and
  ``rangefinders=`` when asked); controllers and vessels get nothing (a vessel's factory is called
  while the scenario is built, with ``scenario=None``, and returns a :class:`usv_mj.vessels.Vessel`). A disturbance's options dataclass is the
  disturbance itself (its ``as_array()`` and its ``kernel`` feed the plants, usv_mj.physics.disturbances),
  so it registers only that: ``@DISTURBANCES.register("squall")`` on the dataclass.

Where a kind is found, in this order (:meth:`Registry.get`):

1. registered in this process (a decorator, or a built-in whose module was imported);
2. a **built-in**, declared below by module name (imported only when its kind is looked up, so
   validating a scenario does not import MuJoCo; a checkout works without installation). The
   built-ins are not also declared as entry points in pyproject.toml: this table is their one
   source (an uninstalled checkout has no entry points, and two lists would drift apart);
3. ``"package.module:Name"`` (as Gymnasium's ``entry_point``): the module is imported and ``Name``
   taken; it is registered under that very string;
4. a Python **entry point** named ``kind`` in the registry's group (``usv_mj.controllers``,
   ``usv_mj.trajectories``, ``usv_mj.plants``, ``usv_mj.disturbances``, ``usv_mj.vessels``), loaded with :mod:`importlib.metadata`.

For 3 and 4 the object named is either registered by its own module's decorator, or registered
here with the options dataclass it declares as its class attribute ``options`` (none if it has no
such attribute). Routes 2-4 work in any process (a sweep's Dask worker resolves them by import); a
kind registered only by a decorator in a script's ``__main__`` exists only in that process
(:meth:`Registry.portable` says so). A leaf module: it imports nothing of the package but
:mod:`usv_mj.core.errors`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import importlib
import inspect
import os
import re
import sys
import warnings
from dataclasses import dataclass, field
from typing import Any

from usv_mj.core.errors import (PluginContractError, PluginImportError, PluginWarning, UnknownKindError, UsvMjError,
                                one_line)

BUILT_IN = "built-in"
_MODULE_NAME = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")


@dataclass(frozen=True)
class Entry:
    """One registered part: its ``kind``, the object (a class or a factory), what it declares
    (``info``: ``options``, the same as ``gains``, and any other registration keyword) and where it
    comes from (``source``: "built-in", "entry point usv_mj.controllers (dist NAME 1.0)",
    "module:Name", or "registered at runtime (module M)")."""

    kind: str
    obj: Any
    info: dict = field(default_factory=dict)
    source: str = "registered at runtime"
    what: str = "part"              # the registry's noun ("controller"), for messages
    returns: tuple = ()             # what the part must have (the registry's interface), checked on a plug-in's

    def __getattr__(self, name):  # entry.gains, entry.options, entry.doc, ... from the registration's keywords
        if name.startswith("__"):
            raise AttributeError(name)
        try:
            return self.info[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def options_class(self):
        """The kind's options dataclass, or None when it takes no options."""
        return self.info.get("options")

    @property
    def module(self) -> str:
        """The module that defines the object ("" if it has none)."""
        return getattr(self.obj, "__module__", "") or ""

    @property
    def plugin(self) -> bool:
        """Whether the object is a plug-in's (its errors are its own, not usv_mj's): anything but a
        built-in and a vessel data file (data, made by usv_mj's own factory)."""
        return self.source != BUILT_IN and not self.source.startswith("data file")

    def make(self, options, scenario, **context):
        """The part: ``obj.from_scenario(options, scenario, **context)``, or ``obj(options,
        scenario, **context)`` for a plain factory; a kind whose object *is* its options class (a
        disturbance) gives ``options`` itself. A plug-in's factory is held to the contract: a
        signature that cannot take these arguments, an exception of its own (not a usv_mj error
        it lets through) or a part without the registry's interface raises
        :class:`PluginContractError` naming the plug-in, the contract and the fix."""
        factory = getattr(self.obj, "from_scenario", None)
        if factory is None and self.obj is self.options_class:
            return options
        factory = factory if factory is not None else self.obj
        if not self.plugin:
            return factory(options, scenario, **context)
        name = _name_of(self.obj) + (".from_scenario" if factory is not self.obj else "")
        head = f"{self.what} kind {self.kind!r} ({name}, {self.source})"
        call = "(options, scenario" + "".join(f", {k}=..." for k in context) + ")"
        try:
            inspect.signature(factory).bind(options, scenario, **context)
        except TypeError as exc:
            raise PluginContractError(f"{head}: its factory cannot be called as {call}: {exc}; a {self.what} "
                                      f"factory takes {call} (usv_mj.core.registry)") from None
        except ValueError:   # no signature to read (a builtin): the call itself says
            pass
        try:
            part = factory(options, scenario, **context)
        except UsvMjError:
            raise
        except Exception as exc:
            hint = ""
            if options is None and self.options_class is None:
                hint = ("; it was given options None: a class named by 'module:Name' or an entry point declares "
                        "its options dataclass as the class attribute `options` (or derives from a registered class)")
            raise PluginContractError(f"{head}: its factory raised {one_line(exc)}{_where(exc)} (a defect of the "
                                      f"plug-in, not of usv_mj){hint}") from exc
        missing = [a for a in self.returns if not hasattr(part, a)]
        if missing:
            raise PluginContractError(f"{head}: its factory returned {type(part).__name__} {_short(part)}, which has "
                                      f"no {', '.join(missing)}: a {self.what} has {', '.join(self.returns)} "
                                      f"(usv_mj.core.registry)")
        return part


class Registry:
    """Parts of one sort by ``kind``: ``register`` (a decorator), ``get``, ``kinds``, ``entries``.

    ``what``: the part's name in messages ("controller"); ``builtins``: kind -> the module that
    registers it on import; ``group``: the entry-point group searched for kinds not found.
    """

    def __init__(self, what: str, builtins: dict[str, str], group: str, files: tuple[str, str] | None = None,
                 returns: tuple = (), self_options: bool = False):
        self.what = what
        self.group = group
        self.returns = tuple(returns)   # the attributes a part must have (checked on a plug-in's)
        # a kind's object is its own options dataclass (the disturbances'): registered with no
        # options=, a dataclass takes itself (``@DISTURBANCES.register("squall")`` on the class)
        self.self_options = self_options
        self._builtins = dict(builtins)  # kind -> module that registers it on import
        # (suffix, "module:function"): a kind ending in the suffix is a data file, registered under its
        # path by that function (imported by name: looking a file kind up is the registry's business)
        self._files = files
        self._entries: dict[str, Entry] = {}
        self._entry_points = None        # name -> importlib.metadata.EntryPoint, read once
        self._ep_notes: dict = {}        # name -> why an entry point of that name is not (or not alone) used
        self._warned: set = set()

    # --- registering ----------------------------------------------------------------------------

    def register(self, kind: str, *, replace: bool = False, options=None, gains=None, **info):
        """Decorator: register ``obj`` under ``kind`` (module docstring). Refused with ValueError
        when ``kind`` exists, unless ``replace=True`` (a re-import of the same definition, same
        module and qualified name, replaces it quietly)."""
        if not isinstance(kind, str) or not kind:
            raise ValueError(f"a {self.what} kind must be a non-empty string, got {kind!r}")
        if gains is not None and options is not None and gains is not options:
            raise ValueError(f"{self.what} {kind!r}: options= and gains= name the same thing; give one")
        options = options if options is not None else gains
        if options is not None and not (isinstance(options, type) and dataclasses.is_dataclass(options)):
            raise ValueError(f"{self.what} {kind!r}: options must be a dataclass type, got {options!r}")
        caller = sys._getframe(1).f_globals.get("__name__", "")
        source = BUILT_IN if self._builtins.get(kind) == caller else f"registered at runtime (module {caller})"
        return self._decorator(kind, options, info, source, replace)

    def _decorator(self, kind, options, info, source, replace):
        def deco(obj):
            if not (callable(obj) or hasattr(obj, "from_scenario")):
                raise ValueError(f"{self.what} {kind!r}: the registered object must be callable or have "
                                 f"from_scenario, got {obj!r}")
            if source != BUILT_IN and kind in self._builtins and kind not in self._entries \
                    and self._builtins[kind] not in sys.modules:
                importlib.import_module(self._builtins[kind])  # the built-in first: it is what "exists"
            old = self._entries.get(kind)
            if old is not None and not replace and not _same_definition(old.obj, obj):
                raise ValueError(f"{self.what} kind {kind!r} is already registered ({old.source}: "
                                 f"{_name_of(old.obj)}); pass replace=True to replace it, or choose another kind")
            full = dict(info)
            own = options
            if own is None and self.self_options and isinstance(obj, type) and dataclasses.is_dataclass(obj):
                own = obj
            if own is not None:
                full["options"] = own
                full["gains"] = own  # the controllers' historical name
            self._entries[kind] = Entry(kind, obj, full, source, self.what, self.returns)
            return obj

        return deco

    def unregister(self, kind: str) -> None:
        """Forget a registered kind (for tests that register their own part); a built-in comes back
        on its next lookup only by importing its module again, so tests unregister only their own."""
        self._entries.pop(kind, None)

    # --- looking up -----------------------------------------------------------------------------

    def builtin_kinds(self) -> tuple[str, ...]:
        return tuple(sorted(self._builtins))

    def entry_point_names(self) -> tuple[str, ...]:
        return tuple(sorted(self._eps()))

    def kinds(self) -> tuple[str, ...]:
        """Every kind a scenario may name by a plain name: the built-in ones, those registered
        since, and the entry points of the group (``module:Name`` kinds are open-ended)."""
        return tuple(sorted(set(self._builtins) | set(self._entries) | set(self._eps())))

    def __contains__(self, kind) -> bool:
        if not isinstance(kind, str):
            return False
        if kind in self._entries or kind in self._builtins or kind in self._eps():
            return True
        if ":" in kind:
            try:
                self.get(kind)
            except UnknownKindError:
                return False
            return True
        return False

    def get(self, kind: str, where: str = "") -> Entry:
        """The entry of ``kind`` (module docstring for the order searched). :class:`UnknownKindError`
        names ``where`` and lists the kinds; :class:`PluginImportError` (a subclass) says why a
        ``module:Name`` or an entry point could not be imported."""
        if not isinstance(kind, str) or not kind:
            raise UnknownKindError(f"{where + ': ' if where else ''}a {self.what} kind must be a non-empty "
                                   f"string, got {kind!r}")
        if kind not in self._warned:   # once per kind: an entry point of its name is not (or not alone) used
            self._warned.add(kind)
            if ":" not in kind:
                self._eps()
                if kind in self._ep_notes:
                    warnings.warn(self._ep_notes[kind], PluginWarning, stacklevel=2)
        if kind in self._entries:
            return self._entries[kind]
        if kind in self._builtins:
            importlib.import_module(self._builtins[kind])
        elif self._files is not None and kind.endswith(self._files[0]):
            module_name, _, function = self._files[1].partition(":")
            getattr(importlib.import_module(module_name), function)(kind)
        elif ":" in kind:
            self._load_module_name(kind, where)
        elif kind in self._eps():
            self._load_entry_point(kind, where)
        if kind not in self._entries:
            known = self.kinds()
            hint = difflib.get_close_matches(str(kind), known, n=1)
            raise UnknownKindError(
                f"{where + ': ' if where else ''}unknown {self.what} kind {kind!r}"
                + (f" (did you mean {hint[0]!r}?)" if hint else "") + f"; {self.what} kinds: {', '.join(known)}"
                + " (or 'package.module:Name', or an entry point of the group " + self.group + ")")
        return self._entries[kind]

    def entries(self, load: bool = True) -> list[Entry]:
        """Every entry, sorted by kind: the built-ins and entry points loaded when ``load`` (a
        kind that cannot be loaded is skipped; ``get`` says why), those registered at runtime."""
        if load:
            for kind in self.kinds():
                try:
                    self.get(kind)
                except UnknownKindError:
                    pass
        return [self._entries[k] for k in sorted(self._entries)]

    def portable(self, kind: str) -> str | None:
        """None when a fresh process (a sweep's worker) finds ``kind`` by itself; else one line
        saying why not (a kind registered only by a decorator in ``__main__``). An entry
        registered at runtime in an importable module is found by importing that module
        (:meth:`module_to_import`)."""
        entry = self._entries.get(kind)
        if entry is None or entry.source == BUILT_IN or entry.source.startswith("entry point") or ":" in kind:
            return None
        if entry.module in ("", "__main__", "__mp_main__") or not _importable(entry.module):
            return (f"{self.what} kind {kind!r} is registered only in this process (by {_name_of(entry.obj)} "
                    f"in {entry.module or 'no module'}): other processes cannot find it; name it as "
                    f"'package.module:Name' with its folder on PYTHONPATH, or declare an entry point "
                    f"in the group {self.group}")
        return None

    def module_to_import(self, kind: str) -> str | None:
        """The module a fresh process must import to find ``kind`` when it was registered at
        runtime by an importable module's decorator (None for the other routes)."""
        entry = self._entries.get(kind)
        if entry is None or not entry.source.startswith("registered at runtime") or ":" in kind:
            return None
        return entry.module if entry.module not in ("", "__main__", "__mp_main__") else None

    # --- the routes ---------------------------------------------------------------------------

    def _eps(self) -> dict:
        if self._entry_points is None:
            from importlib.metadata import entry_points

            found, every = {}, {}
            for ep in entry_points(group=self.group):
                found.setdefault(ep.name, ep)  # the first distribution on sys.path wins, as for imports
                every.setdefault(ep.name, []).append(ep)
            notes = {}
            for name, eps in every.items():
                dists = [_dist_name(ep) for ep in eps]
                if name in self._builtins:
                    notes[name] = (f"{self.what} kind {name!r} is built in: the entry point {name!r} of the group "
                                   f"{self.group} ({', '.join(dists)}) is not used; give it another name")
                    found.pop(name, None)
                elif len(eps) > 1:
                    notes[name] = (f"{self.what} kind {name!r}: {len(eps)} distributions declare the entry point "
                                   f"({', '.join(dists)}); the first on sys.path is used ({dists[0]}: "
                                   f"{eps[0].value}); uninstall or rename the others")
            self._ep_notes = notes
            self._entry_points = found
        return self._entry_points

    def notes(self) -> list[str]:
        """Why entry points of the group are not (or not alone) used (shadowed by a built-in kind,
        declared by two distributions): one line each (``usv-mj kinds`` prints them)."""
        self._eps()
        return [self._ep_notes[k] for k in sorted(self._ep_notes)]

    def _load_module_name(self, kind: str, where: str) -> None:
        module_name, _, attr = kind.partition(":")
        head = f"{where + ': ' if where else ''}{self.what} kind {kind!r}"
        if not _MODULE_NAME.match(module_name) or not re.match(r"^[A-Za-z_][\w.]*$", attr):
            raise UnknownKindError(f"{head}: expected 'package.module:Name' (a module path, a colon, an "
                                   f"attribute)")
        try:
            with _output_to_stderr():
                module = importlib.import_module(module_name)
        except Exception as exc:
            raise PluginImportError(f"{head}: cannot import module {module_name!r} "
                                    f"({type(exc).__name__}: {_one_line(exc)})") from None
        obj = module
        for part in attr.split("."):
            if not hasattr(obj, part):
                raise PluginImportError(f"{head}: module {module_name!r} has no attribute {attr!r}")
            obj = getattr(obj, part)
        self._adopt(kind, obj, "module:Name", head)

    def _load_entry_point(self, kind: str, where: str) -> None:
        ep = self._eps()[kind]
        dist = getattr(ep, "dist", None)
        dist_name = f"{dist.name} {dist.version}" if dist is not None else "unknown distribution"
        head = f"{where + ': ' if where else ''}{self.what} kind {kind!r} (entry point {ep.value!r} of {dist_name})"
        try:
            with _output_to_stderr():
                obj = ep.load()
        except Exception as exc:
            raise PluginImportError(f"{head}: cannot be loaded ({type(exc).__name__}: {_one_line(exc)})") from None
        self._adopt(kind, obj, f"entry point {self.group} (dist {dist_name})", head)

    def _adopt(self, kind: str, obj, source: str, head: str) -> None:
        """``obj`` (what a module:Name or an entry point named) under ``kind``: its own
        registration (the module's decorator) if it has one, else registered here."""
        if kind in self._entries:  # the module registered the kind itself on import
            old = self._entries[kind]
            self._entries[kind] = dataclasses.replace(old, source=source)
            return
        if isinstance(obj, type(sys)):  # an entry point naming a module that registers other kinds
            raise UnknownKindError(f"{head}: the module {obj.__name__!r} registers no {self.what} kind {kind!r}")
        own = next((e for e in self._entries.values() if e.obj is obj), None)
        if own is not None:
            self._entries[kind] = Entry(kind, obj, dict(own.info), source, self.what, self.returns)
            return
        options = getattr(obj, "options", None) if isinstance(obj, type) else None
        if self.self_options and isinstance(obj, type) and dataclasses.is_dataclass(obj):
            options = obj   # a disturbance (or a subclass of one) is its own options dataclass
        if options is not None and not (isinstance(options, type) and dataclasses.is_dataclass(options)):
            options = None
        if options is None and isinstance(obj, type):   # a subclass of a registered class: its options
            options = next((e.options_class for base in obj.__mro__[1:] for e in list(self._entries.values())
                            if e.obj is base and e.options_class is not None), None)
        try:
            self._decorator(kind, options, {}, source, False)(obj)
        except ValueError as exc:
            raise UnknownKindError(f"{head}: {exc}") from None


def _same_definition(a, b) -> bool:
    """The same object, or the same definition imported again (module and qualified name)."""
    if a is b:
        return True
    name_a = (getattr(a, "__module__", None), getattr(a, "__qualname__", None))
    return None not in name_a and name_a == (getattr(b, "__module__", None), getattr(b, "__qualname__", None)) \
        and name_a[1] != "<lambda>"


def _name_of(obj) -> str:
    return f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', repr(obj))}"


def _output_to_stderr():
    """While a plug-in is imported, what it prints goes to stderr: a command's stdout (``usv-mj kinds
    --json``, ``inspect``) stays its own."""
    return contextlib.redirect_stdout(sys.stderr)


def _dist_name(ep) -> str:
    dist = getattr(ep, "dist", None)
    return f"dist {dist.name} {dist.version}" if dist is not None else "an unknown distribution"


def _one_line(exc) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _where(exc) -> str:
    """" (at file.py:N)": the innermost frame of ``exc``'s traceback."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    if tb is None:
        return ""
    return f" at {os.path.basename(tb.tb_frame.f_code.co_filename)}:{tb.tb_lineno}"


def _short(obj) -> str:
    text = repr(obj)
    return text if len(text) <= 60 else text[:57] + "..."


def _importable(module: str) -> bool:
    from importlib.util import find_spec

    try:
        return find_spec(module) is not None
    except (ImportError, ValueError):
        return False


PLANTS = Registry("plant", {"analytic": "usv_mj.plants.analytic", "mujoco": "usv_mj.plants.harbour"},
                  "usv_mj.plants", returns=("name", "control_period", "reset", "step", "state", "time"))
CONTROLLERS = Registry("controller", {"ppc": "usv_mj.controllers.ppc", "pi": "usv_mj.controllers.pi_baseline",
                                      "los": "usv_mj.controllers.los", "open_loop": "usv_mj.controllers.open_loop",
                                      "zigzag": "usv_mj.controllers.zigzag"},
                       "usv_mj.controllers", returns=("name", "diagnostic_fields", "reset", "__call__"))
TRAJECTORIES = Registry("trajectory", {k: "usv_mj.references.trajectories" for k in ("paper", "line", "circle", "waypoints")},
                        "usv_mj.trajectories",  # the entry-point group: a public name, kept from before the layers
                        returns=("evaluate",))
#: d(t) (usv_mj.physics.disturbances: the contract, the dispatch); a kind's object is its options dataclass
DISTURBANCES = Registry("disturbance", {"paper": "usv_mj.physics.disturbances"}, "usv_mj.disturbances",
                        self_options=True)
#: the hulls (docs/vessels.md): a module, or a data file of usv_mj/vessels/data/ read by
#: usv_mj.vessels.datafile (its kinds are named here, so that looking one up imports no physics)
VESSELS = Registry("vessel", {"paper": "usv_mj.vessels.paper", "clarke83": "usv_mj.vessels.clarke83",
                              "kvlcc2": "usv_mj.vessels.kvlcc2",
                              "cybership2": "usv_mj.vessels.datafile", "otter": "usv_mj.vessels.datafile"},
                   "usv_mj.vessels", files=(".toml", "usv_mj.vessels.datafile:register_file"),
                   returns=("kind", "ship", "split", "dimensions"))
#: the standard manoeuvres (docs/manoeuvres.md): a kind's object is its options dataclass, as a
#: disturbance's (the ``[manoeuvre]`` table's keys); the job that runs them is usv_mj.jobs.manoeuvres
MANOEUVRES = Registry("manoeuvre", {k: "usv_mj.scenario.manoeuvre" for k in ("turning", "zigzag", "spiral", "stopping")},
                      "usv_mj.manoeuvres")


class TaskRegistry(Registry):
    """The environments' tasks (:mod:`usv_mj.envs`), registered as dm_control's suite registers its
    own: by a decorator on the task's factory, with its typed options and its tags::

        @TASKS.register("my_task", options=MyOptions, tags=("waves",), scenario={"sea": {...}})
        def my_task(options, scenario, *, random, environment_kwargs): ...   # -> the environment

    ``options``: the dataclass of the task's keyword options of ``usv_mj.envs.load`` (its
    ``duration`` [s] and ``preview_times`` [s] fields, when it has them, set the episode's length
    and how far the scenario's reference reaches); ``tags``: words that say what the task holds
    ("waves": the task's own sea; "obstacles": a harbour), read by :meth:`tagged`; ``scenario``:
    the scenario tables the task sets, under the user's overrides. The factory's contract is in
    :mod:`usv_mj.envs.suite`. The built-in tasks come first in :meth:`kinds`, in their declared
    order; :meth:`on_register` calls a function with every entry registered from then on (the
    Gymnasium ids of a task registered at runtime). It imports no dm_control: a built-in's module
    is imported when its kind is looked up."""

    def __init__(self, what: str, builtins: dict[str, str], group: str):
        super().__init__(what, builtins, group)
        self._listeners = []

    def kinds(self) -> tuple[str, ...]:
        """The built-in tasks in their declared order, then the others (registered, entry points) sorted."""
        others = (set(self._entries) | set(self._eps())) - set(self._builtins)
        return tuple(self._builtins) + tuple(sorted(others))

    def tagged(self, *tags: str) -> tuple[str, ...]:
        """The kinds (in :meth:`kinds` order) whose entry has every one of ``tags`` (loads the entries)."""
        want = set(tags)
        entries = {e.kind: e for e in self.entries()}
        return tuple(k for k in self.kinds() if k in entries and want <= set(entries[k].tags))

    def on_register(self, listener) -> None:
        """Call ``listener(entry)`` after each registration from now on (not for the earlier ones)."""
        if listener not in self._listeners:
            self._listeners.append(listener)

    def _decorator(self, kind, options, info, source, replace):
        info = dict(info)
        tags = info.get("tags", ())
        if isinstance(tags, str) or not all(isinstance(t, str) and t for t in tags):
            raise ValueError(f"{self.what} {kind!r}: tags must be a tuple of words, got {tags!r}")
        info["tags"] = tuple(tags)
        tables = info.get("scenario")
        if tables is not None and not isinstance(tables, dict):
            raise ValueError(f"{self.what} {kind!r}: scenario must be a dict of scenario tables, got {tables!r}")
        info["scenario"] = dict(tables or {})
        register = super()._decorator(kind, options, info, source, replace)

        def deco(obj):
            out = register(obj)
            for listener in list(self._listeners):
                listener(self._entries[kind])
            return out

        return deco


#: the environments' tasks (usv_mj.envs.load, the Gymnasium ids, usv-mj env): :class:`TaskRegistry`
TASKS = TaskRegistry("task", {k: "usv_mj.envs.suite" for k in ("track", "track_waves", "harbor", "harbor_waves")},
                     "usv_mj.tasks")
#: every registry by its scenario section (``usv-mj kinds`` lists them), and the environments' tasks
REGISTRIES = {"controller": CONTROLLERS, "trajectory": TRAJECTORIES, "plant": PLANTS, "disturbance": DISTURBANCES,
              "vessel": VESSELS, "manoeuvre": MANOEUVRES, "task": TASKS}


def _packages() -> dict:
    """importlib.metadata.packages_distributions(), read once per process (it reads every installed
    distribution's file list)."""
    global _PACKAGES
    if _PACKAGES is None:
        import importlib.metadata as md

        _PACKAGES = md.packages_distributions()
    return _PACKAGES


_PACKAGES = None


def origin(entry: Entry) -> dict:
    """Where a registered kind comes from, for a run's metadata (the run log names every plug-in a run
    used): ``source`` (as :attr:`Entry.source`), ``module`` (the object's), and for anything not
    built in the installed ``distribution`` that provides the module and its ``version`` (None when
    the module is not part of an installed distribution: a ``module:Name`` on PYTHONPATH, a runtime
    registration; then ``file``, the module's file). A data file's kind (a vessel file) names the file."""
    import importlib.metadata as md

    out = {"source": entry.source, "module": entry.module}
    if entry.source == BUILT_IN:
        return out
    if entry.source.startswith("data file"):
        out["file"] = entry.kind
        return out
    top = entry.module.split(".")[0] if entry.module else ""
    dists = _packages().get(top, []) if top else []
    out["distribution"] = dists[0] if dists else None
    out["version"] = None
    if dists:
        try:
            out["version"] = md.version(dists[0])
        except md.PackageNotFoundError:
            pass
    else:
        module = sys.modules.get(entry.module)
        out["file"] = getattr(module, "__file__", None)
    return out


def origins(kinds: dict) -> dict:
    """``{"<registry> <kind>": origin}`` of every kind in ``kinds`` ({registry name: kind or None},
    registry names of :data:`REGISTRIES`) that is not built in; a kind that cannot be looked up is
    named with the error."""
    out = {}
    for section, kind in kinds.items():
        if not kind:
            continue
        try:
            entry = REGISTRIES[section].get(kind, section)
        except Exception as exc:   # noqa: BLE001 - metadata: say why, never fail a run for it
            out[f"{section} {kind}"] = {"source": "unknown", "error": str(exc)}
            continue
        if entry.source != BUILT_IN:
            out[f"{section} {kind}"] = origin(entry)
    return out
