"""Registries: the names a scene (or a :class:`~fenicsx_mortar.ContactProblem` user) gives a
contact method, smoothing, enforcement or friction law → the class that implements it.

A new capability is one class, registered where it is defined::

    @SMOOTHINGS.register("my-curve")
    class MyCurve(MasterCurve): ...

Scene validation, the study, the stability suite and the tests take their lists from here
(``SMOOTHINGS.names()``), so a registered class is usable everywhere at once. The built-in
classes register when their modules are imported; every lookup imports them first.
"""
from __future__ import annotations

import importlib
from typing import Callable, Iterator, TypeVar

T = TypeVar("T")

#: modules whose import registers the built-in classes
_BUILTINS = ("curves", "discretization", "enforcement", "friction")


class Registry:
    """Name → class, in registration order."""

    def __init__(self, kind: str):
        self.kind = kind
        self._classes: dict[str, type] = {}

    def register(self, name: str) -> Callable[[T], T]:
        """Class decorator: make ``cls`` available under ``name`` (sets ``cls.name``)."""
        def add(cls: T) -> T:
            if name in self._classes and self._classes[name] is not cls:
                raise ValueError(f"{self.kind} {name!r} is registered already "
                                 f"({self._classes[name].__qualname__})")
            cls.name = name
            self._classes[name] = cls
            return cls
        return add

    def unregister(self, name: str) -> None:
        self._classes.pop(name, None)

    def __getitem__(self, name: str) -> type:
        _load_builtins()
        try:
            return self._classes[name]
        except KeyError:
            raise KeyError(f"unknown {self.kind} {name!r}; expected one of "
                           f"{', '.join(self.names())}") from None

    def __contains__(self, name: object) -> bool:
        _load_builtins()
        return name in self._classes

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def names(self) -> tuple[str, ...]:
        _load_builtins()
        return tuple(self._classes)


METHODS = Registry("contact method")
SMOOTHINGS = Registry("smoothing")
ENFORCEMENTS = Registry("enforcement")
FRICTION_LAWS = Registry("friction law")

_loaded = False


def _load_builtins() -> None:
    global _loaded
    if not _loaded:
        _loaded = True
        for mod in _BUILTINS:
            importlib.import_module(f"{__package__}.{mod}")
