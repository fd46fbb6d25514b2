"""The reasoning layer's built-in model providers, registered through the plugin hooks.

:func:`register_providers` adds, by name (the ``provider:`` of a models config):

- ``openai`` — :class:`~missiontree.reasoning.providers.openai.OpenAIChatModel` (extra ``openai``):
  any OpenAI-compatible server (OpenAI, vLLM, Ollama, llama.cpp), as VLM or LLM.
- ``offline_vlm`` — :class:`~missiontree.reasoning.providers.offline_vlm.OfflineVisionModel`, on the detector
  of the role named by its ``detector`` option (default ``detector``).
- ``offline_llm`` — :class:`~missiontree.reasoning.providers.offline_llm.OfflineLanguageModel`, on the
  embedder of the role named by its ``embedder`` option (default ``embedder``).
- ``minilm`` — :class:`~missiontree.reasoning.embedder.MiniLMEmbedder`.

Vendor SDKs are imported inside the factories, so registering costs nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field

from missiontree.errors import ModelConfigError
from missiontree.file_limits import EMBEDDER_FILES
from missiontree.options import parse_provider_options

M = TypeVar("M", bound=BaseModel)


class OfflineVisionOptions(BaseModel):
    """Options of ``offline_vlm``."""

    model_config = ConfigDict(extra="forbid")

    detector: str = "detector"
    min_score: float = Field(0.5, ge=0, le=1)
    colour_share: float = Field(0.3, gt=0, le=1)
    room_objects: dict[str, list[str]] | None = None
    person_label: str = "person"
    name: str = "offline_vlm"


class OfflineLanguageOptions(BaseModel):
    """Options of ``offline_llm``."""

    model_config = ConfigDict(extra="forbid")

    embedder: str = "embedder"
    affordances: dict[str, str] | None = None
    margin: float = Field(0.05, ge=0, le=1)
    min_score: float = Field(0.25, ge=-1, le=1)
    name: str = "offline_llm"


def _role(models: Mapping[str, Any], role: str, provider: str, what: str) -> Any:
    if role not in models:
        configured = ", ".join(sorted(r for r in models if not r.startswith("_"))) or "none"
        raise ModelConfigError(
            f"model provider {provider!r} needs a {what}: no role {role!r} is configured (configured: "
            f"{configured}); add `{role}: {{provider: ...}}` under roles, or set its `{what}:` option to "
            "the role that holds one")
    return models[role]


def create_openai(options: Mapping[str, Any], timeout: float | None = None) -> Any:
    """Build an ``openai`` provider; ``timeout`` is the role's (its HTTP timeout)."""
    from missiontree.reasoning.providers.openai import OpenAIChatModel

    return OpenAIChatModel.from_options(options, timeout=timeout)


create_openai.wants_timeout = True  # type: ignore[attr-defined]  # the wiring hands it the role's timeout


def create_offline_vlm(options: Mapping[str, Any], models: Mapping[str, Any], seed: int = 0) -> Any:
    """Build ``offline_vlm`` on the detector role its options name."""
    from missiontree.reasoning.providers.offline_vlm import OfflineVisionModel

    parsed = parse_provider_options(OfflineVisionOptions, options, "offline_vlm")
    detector = _role(models, parsed.detector, parsed.name, "detector")
    return OfflineVisionModel(detector, min_score=parsed.min_score, colour_share=parsed.colour_share,
                              room_objects=parsed.room_objects, person_label=parsed.person_label,
                              name=parsed.name)


def create_offline_llm(options: Mapping[str, Any], models: Mapping[str, Any], seed: int = 0) -> Any:
    """Build ``offline_llm`` on the embedder role its options name."""
    from missiontree.reasoning.providers.offline_llm import OfflineLanguageModel

    parsed = parse_provider_options(OfflineLanguageOptions, options, "offline_llm")
    embedder = _role(models, parsed.embedder, parsed.name, "embedder")
    return OfflineLanguageModel(embedder, affordances=parsed.affordances, margin=parsed.margin,
                                min_score=parsed.min_score, name=parsed.name)


# the options each factory takes, so a models config is checked (file:line:col) before anything is built
create_offline_vlm.options_model = OfflineVisionOptions  # type: ignore[attr-defined]
create_offline_llm.options_model = OfflineLanguageOptions  # type: ignore[attr-defined]


def create_minilm(options: Mapping[str, Any]) -> Any:
    """Build the ``minilm`` embedder."""
    from missiontree.reasoning.embedder import MiniLMEmbedder

    return MiniLMEmbedder.from_options(dict(options))


create_minilm.path_options = EMBEDDER_FILES  # type: ignore[attr-defined]  # files checked before building
create_offline_vlm.wants_models = True  # type: ignore[attr-defined]
create_offline_llm.wants_models = True  # type: ignore[attr-defined]


def register_providers(providers: dict[str, Any]) -> None:
    """Add the reasoning layer's providers to ``providers`` (name → factory)."""
    providers["openai"] = create_openai
    providers["offline_vlm"] = create_offline_vlm
    providers["offline_llm"] = create_offline_llm
    providers["minilm"] = create_minilm
