"""The node registry: every node type, its parameters, ports and where it came from.

A node type is declared in one place: a :class:`NodeType` built from a class (a
:class:`~missiontree.engine.leaf.Leaf` subclass with a ``Params`` model and a docstring) or a
factory. Built-in nodes and plugins add theirs through the ``missiontree_register_nodes`` hook
(:mod:`missiontree.plugins.hookspecs`). The loader checks mission files against these
declarations; ``missiontree nodes`` prints them.

A node type may also be registered by name with where it lives (:meth:`NodeRegistry.add_lazy`,
``"module:attribute"``): its module is imported the first time a mission or a listing asks for
it, so a mission pays the imports (numba, scipy, OpenCV) of the node types it uses only.
"""

from __future__ import annotations

import difflib
import importlib
import inspect
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

import py_trees
from pydantic import BaseModel

from missiontree.engine.ports import Port, ports_of
from missiontree.errors import PluginError

Category = Literal["leaf", "decorator", "composite"]

#: Builds a node: (name, validated params, built children) -> behaviour.
Factory = Callable[[str, BaseModel, list[py_trees.behaviour.Behaviour]], py_trees.behaviour.Behaviour]


@dataclass(frozen=True)
class NodeType:
    """A node type that mission files can name.

    Attributes:
        name: The ``type:`` name in mission files (CamelCase, unique).
        category: ``leaf`` (no children), ``decorator`` (one child) or ``composite`` (several).
        params: Pydantic model of the parameters; port fields carry Input/Output metadata.
        factory: Builds the py_trees behaviour.
        summary: One line for the manifest.
        provider: Name of the plugin that registered it (``builtin`` for ours).
    """

    name: str
    category: Category
    params: type[BaseModel]
    factory: Factory
    summary: str = ""
    provider: str = "builtin"
    ports: dict[str, Port] = field(default_factory=dict)

    @classmethod
    def from_leaf(cls, leaf_cls: type, name: str | None = None, provider: str = "builtin") -> NodeType:
        """Declare a Leaf subclass: its ``Params`` and the first line of its docstring."""
        params = getattr(leaf_cls, "Params", None)
        if not (inspect.isclass(params) and issubclass(params, BaseModel)):
            raise PluginError(f"{leaf_cls.__qualname__} has no pydantic Params model")

        def build(node_name: str, p: BaseModel, children: list[Any]) -> py_trees.behaviour.Behaviour:
            return leaf_cls(node_name, p)

        doc = inspect.getdoc(leaf_cls) or ""
        return cls(
            name=name or leaf_cls.__name__, category="leaf", params=params, factory=build,
            summary=doc.splitlines()[0] if doc else "", provider=provider, ports=ports_of(params),
        )


class NodeRegistry:
    """All node types known to this process, by name (some of them not imported yet)."""

    def __init__(self) -> None:
        self._types: dict[str, NodeType] = {}
        self._lazy: dict[str, tuple[str, str]] = {}  # name -> ("module:attribute", provider)
        self._lock = threading.RLock()

    def add(self, node_type: NodeType | type, provider: str | None = None) -> None:
        """Register a node type (or a Leaf subclass); a second type with the same name is an error."""
        if not isinstance(node_type, NodeType):
            node_type = NodeType.from_leaf(node_type, provider=provider or "builtin")
        elif provider is not None and node_type.provider != provider:
            node_type = NodeType(**{**node_type.__dict__, "provider": provider})
        with self._lock:
            existing = self._types.get(node_type.name)
            if existing is None and node_type.name in self._lazy:
                self._twice(node_type.name, self._lazy[node_type.name][1], node_type.provider)
            if existing is not None and existing is not node_type:
                self._twice(node_type.name, existing.provider, node_type.provider)
            self._types[node_type.name] = node_type

    def add_lazy(self, name: str, target: str, provider: str = "builtin") -> None:
        """Register node type ``name``, imported from ``target`` (``"module:attribute"``) when asked for.

        The attribute is a :class:`NodeType` or a Leaf subclass whose type name is ``name``.
        """
        if not isinstance(target, str) or ":" not in target:
            raise PluginError(f"node type {name!r} registered as {target!r}; expected 'module:attribute'")
        with self._lock:
            if name in self._types or name in self._lazy:
                self._twice(name, self.provider_of(name), provider)
            self._lazy[name] = (target, provider)

    @staticmethod
    def _twice(name: str, first: str, second: str) -> None:
        raise PluginError(f"node type {name!r} registered twice: by {first!r} and by {second!r}; "
                          f"rename one of them")

    def _resolve(self, name: str) -> NodeType:
        """Import lazily registered ``name`` and register what it names."""
        target, provider = self._lazy[name]
        module_name, _, attribute = target.partition(":")
        try:
            found = getattr(importlib.import_module(module_name), attribute)
        except (ImportError, AttributeError) as error:
            raise PluginError(f"node type {name!r} ({target}, registered by {provider!r}) cannot be "
                              f"loaded: {type(error).__name__}: {error}") from error
        node_type = found if isinstance(found, NodeType) else NodeType.from_leaf(found, provider=provider)
        if node_type.name != name:
            raise PluginError(f"node type {name!r} was registered as {target}, which declares "
                              f"{node_type.name!r}; register it under that name")
        if node_type.provider != provider:
            node_type = NodeType(**{**node_type.__dict__, "provider": provider})
        del self._lazy[name]
        self._types[name] = node_type
        return node_type

    def get(self, name: str) -> NodeType | None:
        """The node type called ``name`` (imported now if it was registered lazily), or None."""
        found = self._types.get(name)
        if found is not None or name not in self._lazy:
            return found
        with self._lock:
            found = self._types.get(name)
            return found if found is not None else self._resolve(name)

    def provider_of(self, name: str) -> str:
        """The plugin that registered ``name`` ("" if none), without importing it."""
        if name in self._types:
            return self._types[name].provider
        return self._lazy[name][1] if name in self._lazy else ""

    def names(self) -> list[str]:
        """Every registered name, sorted, without importing anything."""
        return sorted([*self._types, *self._lazy])

    def absorb(self, other: NodeRegistry) -> None:
        """Add every node type of ``other``, lazy ones staying lazy (a name taken is an error)."""
        with other._lock:
            types, lazy = dict(other._types), dict(other._lazy)
        for node_type in types.values():
            self.add(node_type)
        for name, (target, provider) in lazy.items():
            self.add_lazy(name, target, provider)

    def nearest(self, name: str, n: int = 3) -> list[str]:
        """Known names closest to ``name`` (for "did you mean" hints)."""
        by_lower = {k.lower(): k for k in self.names()}
        close = difflib.get_close_matches(name.lower(), list(by_lower), n=n, cutoff=0.5)
        return [by_lower[c] for c in close]

    def __contains__(self, name: object) -> bool:
        return name in self._types or name in self._lazy

    def __iter__(self) -> Iterator[NodeType]:
        """Every node type, sorted by name (lazily registered ones are imported now)."""
        for name in list(self._lazy):
            self.get(name)
        return iter(sorted(self._types.values(), key=lambda t: t.name))

    def __len__(self) -> int:
        return len(self._types) + len(self._lazy)
