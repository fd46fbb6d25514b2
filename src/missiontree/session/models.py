"""Model wiring: a models config (config/models/*.yaml) → model providers by role.

A models config names, for each role a mission uses, the provider and its options, and optionally
the role's simulated latency and timeout::

    roles:
      detector:
        provider: sim_detector            # a provider registered through the plugin hooks
      vlm:
        provider: offline_vlm
        detector: detector                # another role this provider uses
        latency: {uniform: [0.5, 3.0]}    # simulated seconds (the patrol-robot thesis's cloud VLM)
        timeout: 10
      embedder:
        provider: minilm
    calls:                                # optional
      timeout: 30                         # default timeout of every role
      workers: 2

Everything in a role's section except ``provider``, ``latency`` and ``timeout`` is handed to the
provider's factory. A factory with the attribute ``wants_models = True`` is called as
``factory(options, models=built, seed=seed)`` and may look up the roles its options name (they
are built first). A factory with ``wants_timeout = True`` also gets ``timeout=`` the role's
timeout (its own, else ``calls: timeout:``), so an HTTP client waits exactly as long as the call
handle and ``missiontree models`` say.

:func:`build_models` checks the whole file first and reports every problem with file:line:col
(a :class:`~missiontree.errors.ProblemsError`, exit code 2), the files its providers' options
name included: each resolves against the config's folder and must lie inside it, inside the
package's data or inside a folder of ``$MISSIONTREE_MODEL_PATH``, within its size limit
(:mod:`missiontree.session.model_files`); the factory gets the checked absolute path. A provider
that fails to *build* (a missing model file, an unset API key, a missing extra) does not stop the
run: its role holds a :class:`BrokenProvider` that raises the reason when used, so a mission that
needs it fails with the reason in the tick log and a mission that does not runs on.
``missiontree models`` shows the same reasons.

Everything above is checked at once, but a role's provider is *built* on its first use: each role
is a :class:`~missiontree.reasoning.models.PendingProvider` until a leaf (or another role's
factory) looks it up, so a mission pays only for the models it calls (the patrol never builds the
offline LLM and its imports). ``build_models(..., lazy=False)`` builds every role at once.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Iterator, Mapping
from typing import Any

from missiontree.errors import ConfigError, MissionTreeError, Problem, ProblemsError
from missiontree.paths import find_config
from missiontree.reasoning.calls import SETTINGS_KEY, BrokenProvider, CallSettings, LatencyModel
from missiontree.reasoning.models import Models, PendingProvider, resolve
from missiontree.session.model_files import config_base, model_file_problems
from missiontree.yamlio import Located, load_yaml, parse_yaml

#: The models config used when none is given.
DEFAULT_MODELS = "offline"

_ROLE_KEYS = {"provider", "latency", "timeout"}
_CALLS_KEYS = {"timeout", "workers"}
__all__ = ["DEFAULT_MODELS", "BrokenProvider", "build_models", "check_models_config", "describe_source",
           "load_models_config", "model_roles"]

_TIMEOUT_EXPECTED = "expected a positive number of seconds or null, found {!r}"


def load_models_config(models: str | os.PathLike[str] | Mapping[str, Any] | None) -> Located:
    """Read a models config: a shipped name (``offline``), a path, or data already in memory."""
    if isinstance(models, Mapping):
        import yaml

        text = yaml.safe_dump(dict(models), sort_keys=False)
        return parse_yaml(text, "<models config>", error=ProblemsError)
    path = find_config("models", models if models is not None else DEFAULT_MODELS)
    return load_yaml(path, error=ProblemsError)


def build_models(
    models: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    providers: Mapping[str, Any] | None = None,
    seed: int = 0,
    strict: bool | None = None,
    lazy: bool = True,
) -> dict[str, Any]:
    """Check a models config whole and wire every role (built on first use unless ``lazy=False``).

    Args:
        models: A shipped models config name, a path, or the config as data; default ``offline``.
        providers: Provider name → factory (from the plugin hooks); default: every loaded plugin's.
        seed: Run seed, handed to factories that want the models (``wants_models``).
        strict: Whether an unknown provider name is a problem of the file (default: when ``models``
            was given); otherwise its role holds a :class:`BrokenProvider` saying so.
        lazy: Leave each role a :class:`PendingProvider` that builds it on first use (its
            configuration checked now); False builds them all now.

    Returns:
        Role → provider (or pending provider), plus the :class:`CallSettings` under
        ``calls.SETTINGS_KEY``.

    Raises:
        ProblemsError: The file is malformed, or names a model file outside its folder and the
            allow-list or over its size limit (every problem, with file:line:col).
    """
    if providers is None:
        from missiontree.plugins.manager import load_plugins

        providers = load_plugins().providers
    document = load_models_config(models)
    # The default config must not stop missions that use no model when a provider is missing.
    roles, settings = check_models_config(document, providers, strict=models is not None if strict is None
                                          else strict)
    # files the providers' options name: confined and size-checked here, handed over as absolute paths
    file_problems, resolved = model_file_problems(document, roles, providers, config_base(models, document))
    if file_problems:
        raise ProblemsError(file_problems)
    roles = {role: {**section, **resolved.get(role, {})} for role, section in roles.items()}
    built: dict[str, Any] = {}
    view = _Resolved(built)
    for role in _build_order(roles):
        timeout = settings.timeouts.get(role, settings.default_timeout)
        pending = PendingProvider(role, str(roles[role]["provider"]), functools.partial(
            _build_role, role, roles[role], providers, view, seed, timeout))
        built[role] = pending if lazy else pending.get()
    built[SETTINGS_KEY] = settings
    return Models(built)  # a pending role is built when looked up


class _Resolved(Mapping[str, Any]):
    """The roles as a factory that wants the models sees them: a role it looks up is built then."""

    def __init__(self, roles: dict[str, Any]) -> None:
        self._roles = roles

    def __getitem__(self, role: str) -> Any:
        return resolve(self._roles[role])

    def __iter__(self) -> Iterator[str]:
        return iter(self._roles)

    def __len__(self) -> int:
        return len(self._roles)


def check_models_config(
    document: Located, providers: Mapping[str, Any], strict: bool = True
) -> tuple[dict[str, dict[str, Any]], CallSettings]:
    """Check a models config whole; return its role sections and call settings.

    With ``strict=False`` an unknown provider name is not a problem (its role will be broken).

    Raises:
        ProblemsError: Every problem found.
    """
    problems: list[Problem] = []
    data = document.data
    if not isinstance(data, dict):
        found = type(data).__name__
        raise ProblemsError([document.problem_at((), f"expected a mapping with 'roles:', found {found}")])
    for key in data:
        if key not in {"roles", "calls"}:
            problems.append(document.problem_at((key,), f"unknown section {key!r}; expected roles or calls",
                                                "put each role under roles:", key=True))
    raw_roles = data.get("roles")
    if not isinstance(raw_roles, dict) or not raw_roles:
        problems.append(document.problem_at(("roles",), "expected 'roles:' mapping each role to a provider",
                                            "e.g. roles: {vlm: {provider: offline_vlm}}"))
        raise ProblemsError(problems)
    roles: dict[str, dict[str, Any]] = {}
    latency: dict[str, LatencyModel | None] = {}
    timeouts: dict[str, float | None] = {}
    for role, section in raw_roles.items():
        if _check_role(document, role, section, providers, strict, problems):
            roles[role] = section
            with contextlib.suppress(ConfigError):  # reported by _check_role
                latency[role] = LatencyModel.parse(section.get("latency"), "latency")
            timeout = section.get("timeout", "default")
            if timeout != "default" and _is_timeout(timeout):
                timeouts[role] = float(timeout) if timeout is not None else None
    default_timeout, workers = _check_calls(document, data.get("calls") or {}, problems)
    if problems:
        raise ProblemsError(problems)
    settings = CallSettings(latency=latency, timeouts=timeouts, default_timeout=default_timeout,
                            workers=workers)
    return roles, settings


def _check_role(document: Located, role: str, section: Any, providers: Mapping[str, Any], strict: bool,
                problems: list[Problem]) -> bool:
    """Check one role's section, adding to ``problems``; whether it is a mapping to keep."""
    path = ("roles", role)
    if role.startswith("_"):
        problems.append(document.problem_at(path, f"role names may not start with '_' (found {role!r})",
                                            key=True))
        return False
    if not isinstance(section, dict):
        problems.append(document.problem_at(
            path, f"expected a mapping with 'provider:', found {section!r}",
            "e.g. vlm: {provider: offline_vlm}"))
        return False
    known = ", ".join(sorted(providers)) or "none"
    name = section.get("provider")
    if not isinstance(name, str):
        problems.append(document.problem_at(path, "expected 'provider: <name>'",
                                            f"known providers: {known}"))
    elif name not in providers and strict:
        problems.append(document.problem_at((*path, "provider"), f"unknown model provider {name!r}",
                                            f"known providers: {known}; a plugin may provide others"))
    try:
        LatencyModel.parse(section.get("latency"), "latency")
    except ConfigError as exc:
        problems.append(document.problem_at((*path, "latency"), str(exc)))
    timeout = section.get("timeout", "default")
    if timeout != "default" and not _is_timeout(timeout):
        problems.append(document.problem_at((*path, "timeout"), _TIMEOUT_EXPECTED.format(timeout)))
    return True


def _check_calls(document: Located, calls: Any, problems: list[Problem]) -> tuple[float | None, int]:
    """Check the ``calls:`` section, adding to ``problems``; its (default timeout, workers)."""
    default_timeout: float | None = 30.0
    workers = 2
    if not isinstance(calls, dict):
        problems.append(document.problem_at(("calls",), f"expected a mapping, found {calls!r}"))
        return default_timeout, workers
    for key in calls:
        if key not in _CALLS_KEYS:
            problems.append(document.problem_at(("calls", key), f"unknown option {key!r}",
                                                f"known: {', '.join(sorted(_CALLS_KEYS))}", key=True))
    if "timeout" in calls:
        value = calls["timeout"]
        if not _is_timeout(value):
            problems.append(document.problem_at(("calls", "timeout"), _TIMEOUT_EXPECTED.format(value)))
        else:
            default_timeout = float(value) if value is not None else None
    if "workers" in calls:
        value = calls["workers"]
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 32:
            problems.append(document.problem_at(("calls", "workers"),
                                                f"expected a whole number from 1 to 32, found {value!r}"))
        else:
            workers = value
    return default_timeout, workers


def _is_timeout(value: Any) -> bool:
    return value is None or (isinstance(value, int | float) and not isinstance(value, bool) and value > 0)


def _build_order(roles: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Roles in file order, each after the roles its options name (cycles keep file order)."""
    order: list[str] = []
    visiting: set[str] = set()

    def visit(role: str) -> None:
        if role in order or role in visiting:
            return
        visiting.add(role)
        for key, value in roles[role].items():
            if key not in _ROLE_KEYS and isinstance(value, str) and value in roles and value != role:
                visit(value)
        visiting.discard(role)
        order.append(role)

    for role in roles:
        visit(role)
    return order


def _build_role(role: str, section: Mapping[str, Any], providers: Mapping[str, Any],
                built: Mapping[str, Any], seed: int, timeout: float | None = None) -> Any:
    from missiontree.plugins.builtin import resolve_factory

    name = str(section["provider"])
    options = {k: v for k, v in section.items() if k not in _ROLE_KEYS}
    if name not in providers:
        known = ", ".join(sorted(providers)) or "none"
        return BrokenProvider(role, name, f"unknown model provider {name!r} (known: {known}); install the "
                              "plugin that provides it or pick a known one in the models config")
    try:
        factory = resolve_factory("provider", name, providers[name])
        extra: dict[str, Any] = {}
        if getattr(factory, "wants_timeout", False):  # e.g. an HTTP client: the role's timeout is its own
            extra["timeout"] = timeout
        if getattr(factory, "wants_models", False):
            return factory(options, models=built, seed=seed, **extra)
        return factory(options, **extra)
    except (MissionTreeError, ImportError, ValueError, TypeError, OSError) as exc:
        reason = str(exc) if isinstance(exc, MissionTreeError) else f"{type(exc).__name__}: {exc}"
        return BrokenProvider(role, name, reason)


def model_roles(models: Mapping[str, Any]) -> dict[str, Any]:
    """The providers of a built models dict, without the hub's reserved entries."""
    return {role: provider for role, provider in models.items() if not role.startswith("_")}


def describe_source(models: str | os.PathLike[str] | Mapping[str, Any] | None) -> str:
    """Where a models config comes from, for messages."""
    if isinstance(models, Mapping):
        return "<models config>"
    return str(find_config("models", models if models is not None else DEFAULT_MODELS))
