"""A mission's model services in one typed object: providers by role, call settings, the bound caller.

The session builds a :class:`Models` once from the models config and binds it before any leaf is
set up (:meth:`Models.bind`): the mission's :class:`~missiontree.reasoning.calls.ModelCaller` on the
robot clock, and the providers that need the robot bound to it (one that refuses it already replaced
by a :class:`~missiontree.reasoning.calls.BrokenProvider` carrying the reason). Leaves then only use
what is there (``context.calls``, ``context.model(role)``); none wires anything.

A :class:`Models` is a mapping of role to provider, so code that reads ``models[role]`` keeps
working; the call settings and the caller sit under the reserved keys ``_calls`` and ``_caller``
(:data:`~missiontree.reasoning.calls.SETTINGS_KEY`, :data:`~missiontree.reasoning.calls.CALLER_KEY`)
for the code that still looks them up there.

A role's provider may be built on its first use: the session's wiring leaves a
:class:`PendingProvider` (the configuration already checked) that :class:`Models` builds when the
role is first looked up (``models[role]``, ``get``, :meth:`Models.provider`), so a mission pays only
for the models it calls (the patrol never builds the offline LLM). Iterating the mapping does not
build anything: ``items()`` and ``values()`` show a pending role as its :class:`PendingProvider`.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from missiontree.errors import ConfigError, MissionTreeError
from missiontree.events import ForwardEvents
from missiontree.reasoning.calls import (
    CALLER_KEY,
    SETTINGS_KEY,
    BrokenProvider,
    CallContext,
    CallSettings,
    ModelCaller,
    bind_providers,
)
from missiontree.reasoning.protocols import provider_name

__all__ = ["Models", "PendingProvider", "resolve"]


class PendingProvider:
    """A role's provider not built yet: built once, on first use, by ``build`` (thread-safe).

    Listeners (:meth:`when_built`) hear of the provider when it is built, e.g. the run profile,
    which times a model's calls from its first use on. Once :meth:`bind_robot` gave it the robot, a
    provider that needs the robot (``needs_robot``) is bound as it is built; one that refuses it is
    a :class:`~missiontree.reasoning.calls.BrokenProvider` carrying the reason, as when binding a
    built one.

    Args:
        role: The role it stands for.
        name: The provider's configured name (for messages).
        build: Builds the provider (errors are the builder's to turn into a broken provider).
    """

    def __init__(self, role: str, name: str, build: Callable[[], Any]) -> None:
        self.role = role
        self.name = name
        self._build: Callable[[], Any] | None = build
        self._value: Any = None
        self._lock = threading.RLock()
        self._listeners: list[Callable[[Any], None]] = []
        self._robot: Any = None

    def __repr__(self) -> str:
        return f"PendingProvider({self.role!r}, {self.name!r}, built={self.built})"

    @property
    def built(self) -> bool:
        """Whether the provider has been built."""
        return self._build is None

    @property
    def value(self) -> Any:
        """The built provider (None before it is built)."""
        return self._value

    #: Binding passes through it (``bind_providers`` binds what is marked so): the provider is
    #: bound when built if it needs the robot.
    needs_robot = True

    def bind(self, robot: Any) -> None:
        """Bind the provider to ``robot`` when it is built (``bind_providers`` calls this)."""
        self.bind_robot(robot)

    def bind_robot(self, robot: Any) -> None:
        """Bind the provider to ``robot`` when it is built (at once if it already is)."""
        with self._lock:
            self._robot = robot
            if self.built:
                self._value = self._bound(self._value)

    def _bound(self, provider: Any) -> Any:
        """``provider`` bound to the robot if it needs one (a refusal makes it a broken provider)."""
        if self._robot is None or getattr(provider, "needs_robot", False) is not True:
            return provider
        try:
            provider.bind(self._robot)
        except MissionTreeError as exc:
            return BrokenProvider(self.role, provider_name(provider), str(exc))
        return provider

    def when_built(self, listener: Callable[[Any], None]) -> Callable[[], None]:
        """Call ``listener(provider)`` when the provider is built (at once if it is); returns a remover."""
        with self._lock:
            if not self.built:
                self._listeners.append(listener)

                def remove() -> None:
                    with self._lock:
                        if listener in self._listeners:
                            self._listeners.remove(listener)

                return remove
        listener(self._value)
        return lambda: None

    def get(self) -> Any:
        """The provider, built now if it was not."""
        if self._build is None:
            return self._value
        with self._lock:
            build = self._build
            if build is None:
                return self._value
            provider = self._bound(build())
            self._value = provider
            self._build = None
            listeners, self._listeners = self._listeners, []
        for listener in listeners:
            listener(provider)
        return provider


def resolve(value: Any) -> Any:
    """``value``, or the provider a :class:`PendingProvider` stands for (built now if need be)."""
    return value.get() if isinstance(value, PendingProvider) else value


class Models(dict[str, Any]):
    """Model providers by role, with the call settings and (once bound) the mission's caller.

    Args:
        providers: Role → provider; may hold the call settings under ``_calls`` (as the models
            config's wiring returns them).
        settings: The call settings (latency and timeout per role, workers); default: those under
            ``_calls`` in ``providers``, else the defaults.
    """

    def __init__(self, providers: Mapping[str, Any] | None = None,
                 settings: CallSettings | None = None) -> None:
        super().__init__(providers or {})
        if settings is not None:
            self[SETTINGS_KEY] = settings
        for role, value in list(dict.items(self)):
            if isinstance(value, PendingProvider):  # once built (by whoever), the entry is the provider
                value.when_built(functools.partial(self._replace, role, value))

    def _replace(self, role: str, pending: PendingProvider, provider: Any) -> None:
        if dict.get(self, role) is pending:
            dict.__setitem__(self, role, provider)

    def __getitem__(self, role: str) -> Any:
        value = dict.__getitem__(self, role)
        if isinstance(value, PendingProvider):
            value = value.get()
            dict.__setitem__(self, role, value)
        return value

    def get(self, role: str, default: Any = None) -> Any:  # type: ignore[override]
        """The provider of ``role`` (built now if pending), else ``default``."""
        return self[role] if dict.__contains__(self, role) else default

    def pending(self) -> Iterator[str]:
        """The roles not built yet."""
        return (role for role, value in dict.items(self) if isinstance(value, PendingProvider)
                and not value.built)

    @property
    def settings(self) -> CallSettings:
        """How the calls run (latency and timeout per role, workers)."""
        settings = self.get(SETTINGS_KEY)
        return settings if isinstance(settings, CallSettings) else CallSettings()

    @property
    def caller(self) -> ModelCaller | None:
        """The bound caller, None before :meth:`bind`."""
        caller = self.get(CALLER_KEY)
        return caller if isinstance(caller, ModelCaller) else None

    def roles(self) -> dict[str, Any]:
        """Role → provider, without the reserved entries (every role built: a listing shows them all)."""
        return {role: self[role] for role in list(self) if not role.startswith("_")}

    def provider(self, role: str) -> Any:
        """The provider of ``role``.

        Raises:
            ConfigError: No provider is configured for it (names the configured roles and the fix).
        """
        if role.startswith("_") or role not in self:
            known = ", ".join(sorted(self.roles())) or "none"
            raise ConfigError(f"no model configured for role {role!r} (configured: {known}); "
                              "add it to the models config (config/models/*.yaml)")
        return self[role]

    def bind(self, context: CallContext, realtime: bool = False) -> ModelCaller:
        """Make the mission's caller and bind the providers that need the robot; once (idempotent).

        The caller reports its ``model_call`` events to ``context.events`` as it is when each call
        ends, so it may be bound before the runner installs the tick log.

        Args:
            context: The mission context (robot clock, seed; these models as its ``models``).
            realtime: The run is paced to wall time (polls never wait for a worker).
        """
        caller = self.caller
        if caller is None:
            caller = ModelCaller.for_context(context, self.settings, events=ForwardEvents(context),
                                             realtime=realtime)
            bind_providers(self, context.robot)  # the built ones now; the pending ones as they are built
            self[CALLER_KEY] = caller
        context.calls = caller
        return caller

    def close(self) -> None:
        """Stop the caller's calls (queued ones dropped); idempotent."""
        caller = self.caller
        if caller is not None:
            caller.close()
