"""Checking a provider's options (a section of a models config) against its pydantic model.

The errors are worded by :mod:`missiontree.yamlio.problems`, the one translation of pydantic's errors.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from missiontree.errors import ModelConfigError
from missiontree.yamlio.problems import error_lines

M = TypeVar("M", bound=BaseModel)


def parse_provider_options(model: type[M], options: Mapping[str, Any], provider: str) -> M:
    """Validate ``options`` for ``provider``; every problem in one ModelConfigError naming the options.

    Raises:
        ModelConfigError: Unknown, missing or invalid options; the message lists the known ones.
    """
    try:
        return model.model_validate(dict(options))
    except ValidationError as exc:
        problems = "; ".join(error_lines(exc))  # the known options follow once
        raise ModelConfigError(
            f"model provider {provider!r}: invalid options ({problems}); known options: "
            f"{', '.join(model.model_fields)}") from None
