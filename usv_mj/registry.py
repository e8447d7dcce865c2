"""Registries of the parts a scenario names by ``kind``: plants, controllers, trajectories, disturbances.

As in dm_control's suite, a part registers itself where it is defined::

    from usv_mj.registry import CONTROLLERS

    @CONTROLLERS.register("my-law", gains=MyGains)
    class MyController:
        name = "my-law"
        diagnostic_fields = ("e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3", "s")
        @classmethod
        def from_scenario(cls, gains, scenario): ...
        def reset(self): ...
        def __call__(self, t, state, reference): return tau_u, tau_r, diagnostics

and ``[controller] kind = "my-law"`` in a scenario finds it; its table's keys are validated
against ``MyGains``. The built-in parts are declared by module name here (imported only when a
kind is looked up, so validating a scenario does not import MuJoCo). A leaf module: it imports
nothing of the package but :mod:`usv_mj.errors`.
"""

from __future__ import annotations

import difflib
import importlib
from dataclasses import dataclass, field
from typing import Any

from .errors import UnknownKindError


@dataclass(frozen=True)
class Entry:
    """One registered part: its ``kind``, the object (a class or a factory) and what it declares."""

    kind: str
    obj: Any
    info: dict = field(default_factory=dict)

    def __getattr__(self, name):  # entry.gains, entry.doc, ... from the registration's keywords
        try:
            return self.info[name]
        except KeyError:
            raise AttributeError(name) from None


class Registry:
    """Parts of one sort by ``kind``: ``register`` (a decorator), ``get``, ``kinds``."""

    def __init__(self, what: str, builtins: dict[str, str]):
        self.what = what
        self._builtins = dict(builtins)  # kind -> module that registers it on import
        self._entries: dict[str, Entry] = {}

    def register(self, kind: str, **info):
        """Decorator: register ``obj`` under ``kind`` with keywords (``gains=`` for controllers)."""
        if not isinstance(kind, str) or not kind:
            raise ValueError(f"a {self.what} kind must be a non-empty string, got {kind!r}")

        def deco(obj):
            self._entries[kind] = Entry(kind, obj, dict(info))
            return obj

        return deco

    def unregister(self, kind: str) -> None:
        """Forget a registered kind (for tests that register their own part)."""
        self._entries.pop(kind, None)

    def kinds(self) -> tuple[str, ...]:
        """Every kind a scenario may name (the built-in ones and those registered since)."""
        return tuple(sorted(set(self._builtins) | set(self._entries)))

    def __contains__(self, kind) -> bool:
        return kind in self._entries or kind in self._builtins

    def get(self, kind: str, where: str = "") -> Entry:
        """The entry of ``kind``; :class:`UnknownKindError` names ``where`` and lists the kinds."""
        if kind not in self._entries and kind in self._builtins:
            importlib.import_module(self._builtins[kind])
        if kind not in self._entries:
            known = self.kinds()
            hint = difflib.get_close_matches(str(kind), known, n=1)
            raise UnknownKindError(
                f"{where + ': ' if where else ''}unknown {self.what} kind {kind!r}"
                + (f" (did you mean {hint[0]!r}?)" if hint else "") + f"; {self.what} kinds: {', '.join(known)}")
        return self._entries[kind]


PLANTS = Registry("plant", {"analytic": "usv_mj.plants.analytic", "mujoco": "usv_mj.plants.mujoco_plant"})
CONTROLLERS = Registry("controller", {"ppc": "usv_mj.controllers.ppc", "pi": "usv_mj.controllers.pi_baseline",
                                      "los": "usv_mj.controllers.los", "open_loop": "usv_mj.controllers.open_loop",
                                      "zigzag": "usv_mj.controllers.zigzag"})
TRAJECTORIES = Registry("trajectory", {k: "usv_mj.trajectories" for k in ("paper", "line", "circle", "waypoints")})
DISTURBANCES = Registry("disturbance", {"paper": "usv_mj.disturbances"})
