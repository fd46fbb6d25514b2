"""The services a running mission offers its leaves, as protocols under everything.

:class:`~missiontree.engine.context.MissionContext` carries them typed, yet the engine knows no
maps and no models (it stands beside the domain): what a leaf may do with the live scene and with
the mission's model calls is said here, and the domain's classes
(:class:`missiontree.semantics.live.LiveScene`, :class:`missiontree.reasoning.calls.ModelCaller`)
provide it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol, runtime_checkable

__all__ = ["CallHandle", "ModelCalls", "Scene", "SceneGraphView", "SceneMap"]


class SceneMap(Protocol):
    """The semantic map as leaves use it: object instances by id, label and place; marking one."""

    def __iter__(self) -> Iterator[Any]:
        """Every instance."""
        ...

    def __len__(self) -> int:
        """How many instances."""
        ...

    def __contains__(self, instance_id: object) -> bool:
        """Whether an instance of this id exists."""
        ...

    def get(self, instance_id: str) -> Any:
        """The instance of this id, or None."""
        ...

    def by_label(self, label: str) -> list[Any]:
        """The instances of one label."""
        ...

    def near(self, x: float, y: float, radius: float, label: str | None = None) -> list[Any]:
        """The instances within ``radius`` metres of (x, y), of ``label`` when given."""
        ...

    def update(self, instance_id: str, stamp: float | None = None, *, announce: bool = False,
               reason: str = "", **fields: Any) -> Any:
        """Set attributes of an instance (a leaf marks one ``doubtful=True`` a look did not confirm)."""
        ...


class SceneGraphView(Protocol):
    """The latest scene graph (NAIS shape), read-only."""

    def objects(self) -> list[dict[str, Any]]:
        """The object nodes."""
        ...

    def rooms(self) -> list[dict[str, Any]]:
        """The room nodes."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The graph as NAIS JSON data."""
        ...


@runtime_checkable
class Scene(Protocol):
    """What is where, shared by the leaves of one run (``context.scene``).

    A ``BuildSceneGraph`` leaf puts one on the context; later leaves (intent, search) read it.
    """

    @property
    def map(self) -> SceneMap:
        """The semantic map (instances kept true as things move)."""
        ...

    @property
    def graph(self) -> SceneGraphView:
        """The latest scene graph."""
        ...

    @property
    def rooms(self) -> list[Any]:
        """The rooms as the graph knows them."""
        ...

    @property
    def doubtful(self) -> list[tuple[str, float, float]]:
        """Places (label, x, y) seen a few times that did not become instances."""
        ...

    @property
    def version(self) -> int:
        """Number of graph rebuilds so far."""
        ...

    def object_ids(self) -> set[str]:
        """Ids of the latest graph's objects."""
        ...


class CallHandle(Protocol):
    """One submitted model call: poll it every tick, cancel it on halt (every method returns at once)."""

    def status(self) -> Any:
        """The call's status now (a ``CallStatus``; ``.done`` once it ended)."""
        ...

    def result(self) -> Any:
        """The answer once succeeded, else None."""
        ...

    def error(self) -> str:
        """Why it did not succeed, empty while running or on success."""
        ...

    def cancel(self) -> None:
        """Stop caring about the call (idempotent)."""
        ...


class ModelCalls(Protocol):
    """The mission's model calls: submitted on workers, handed back as handles (``context.calls``)."""

    def submit(self, role: str, fn: Callable[..., Any], *args: Any, timeout: float | None | str = "default",
               provider: str | None = None, node: str = "", log_success: bool = True,
               **kwargs: Any) -> CallHandle:
        """Run ``fn(*args, **kwargs)`` on a worker under ``role``'s latency and timeout."""
        ...

    def ask(self, role: str, images: Sequence[Any], prompt: str, schema: Any = None, *,
            valid_ids: Any = None, timeout: float | None | str = "default", node: str = "") -> CallHandle:
        """Ask the vision-language model of ``role`` about ``images``."""
        ...

    def chat(self, role: str, messages: Sequence[Any], schema: Any = None, *,
             valid_ids: Any = None, timeout: float | None | str = "default", node: str = "") -> CallHandle:
        """Ask the language model of ``role``."""
        ...

    def close(self) -> None:
        """Stop accepting calls."""
        ...
