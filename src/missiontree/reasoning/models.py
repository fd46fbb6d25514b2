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
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from missiontree.errors import ConfigError
from missiontree.events import ForwardEvents
from missiontree.reasoning.calls import (
    CALLER_KEY,
    SETTINGS_KEY,
    CallContext,
    CallSettings,
    ModelCaller,
    bind_providers,
)

__all__ = ["Models"]


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
        """Role → provider, without the reserved entries."""
        return {role: provider for role, provider in self.items() if not role.startswith("_")}

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
            bind_providers(self, context.robot)
            self[CALLER_KEY] = caller
        context.calls = caller
        return caller

    def close(self) -> None:
        """Stop the caller's calls (queued ones dropped); idempotent."""
        caller = self.caller
        if caller is not None:
            caller.close()
