"""The node registry: every node type, its parameters, ports and where it came from.

A node type is declared in one place: a :class:`NodeType` built from a class (a
:class:`~missiontree.engine.leaf.Leaf` subclass with a ``Params`` model and a docstring) or a
factory. Built-in nodes and plugins add theirs through the ``missiontree_register_nodes`` hook
(:mod:`missiontree.plugins.hookspecs`). The loader checks mission files against these
declarations; ``missiontree nodes`` prints them.
"""

from __future__ import annotations

import difflib
import inspect
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
    """All node types known to this process, by name."""

    def __init__(self) -> None:
        self._types: dict[str, NodeType] = {}

    def add(self, node_type: NodeType | type, provider: str | None = None) -> None:
        """Register a node type (or a Leaf subclass); a second type with the same name is an error."""
        if not isinstance(node_type, NodeType):
            node_type = NodeType.from_leaf(node_type, provider=provider or "builtin")
        elif provider is not None and node_type.provider != provider:
            node_type = NodeType(**{**node_type.__dict__, "provider": provider})
        existing = self._types.get(node_type.name)
        if existing is not None and existing is not node_type:
            raise PluginError(
                f"node type {node_type.name!r} registered twice: by {existing.provider!r} "
                f"and by {node_type.provider!r}; rename one of them"
            )
        self._types[node_type.name] = node_type

    def get(self, name: str) -> NodeType | None:
        """The node type called ``name``, or None."""
        return self._types.get(name)

    def nearest(self, name: str, n: int = 3) -> list[str]:
        """Known names closest to ``name`` (for "did you mean" hints)."""
        by_lower = {k.lower(): k for k in self._types}
        close = difflib.get_close_matches(name.lower(), list(by_lower), n=n, cutoff=0.5)
        return [by_lower[c] for c in close]

    def __contains__(self, name: object) -> bool:
        return name in self._types

    def __iter__(self) -> Iterator[NodeType]:
        return iter(sorted(self._types.values(), key=lambda t: t.name))

    def __len__(self) -> int:
        return len(self._types)
