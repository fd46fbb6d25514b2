"""Blackboard ports: how a node type declares the keys it reads and writes.

A port is a parameter of the node's pydantic ``Params`` model whose value is a blackboard
key name, marked with :func:`Input` or :func:`Output` in its ``Annotated`` metadata. The
default is the conventional key; a mission file may remap it::

    class Params(BaseModel):
        alarm: Annotated[str, Output("the last alarm raised", type="Alarm")] = "alarm"

So parameters and ports are declared in one place, validated together, and printed by
``missiontree nodes``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel


@dataclass(frozen=True)
class Port:
    """A blackboard key that a node reads (``in``) or writes (``out``)."""

    direction: Literal["in", "out"]
    doc: str = ""
    type: str = "any"


def Input(doc: str = "", type: str = "any") -> Port:  # noqa: N802 - reads like a type in Annotated[...]
    """Mark a parameter as a blackboard key the node reads."""
    return Port("in", doc, type)


def Output(doc: str = "", type: str = "any") -> Port:  # noqa: N802 - reads like a type in Annotated[...]
    """Mark a parameter as a blackboard key the node writes."""
    return Port("out", doc, type)


def ports_of(params: type[BaseModel]) -> dict[str, Port]:
    """Return {field name: Port} for every port field of a Params model."""
    found: dict[str, Port] = {}
    for name, info in params.model_fields.items():
        for meta in info.metadata:
            if isinstance(meta, Port):
                found[name] = meta
    return found


@dataclass(frozen=True)
class BlackboardRef:
    """A parameter value that is read from the blackboard when the node starts.

    The mission file writes it as ``{bb: key}``; the checker accepts it for any parameter and
    the leaf resolves it with :meth:`missiontree.engine.leaf.Leaf.value`, which validates the
    value against the parameter's declared type at that moment.
    """

    key: str
