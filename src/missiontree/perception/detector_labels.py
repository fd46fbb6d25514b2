"""Class names of a detector: from a model's ``names`` metadata or from a labels file.

Used by :class:`~missiontree.perception.detectors.YoloOnnxDetector`; Ultralytics writes a model's
``names`` as the text of a Python dict ``{0: 'person', ...}``; a labels file holds one name a line,
or a YAML/JSON ``names`` list or mapping, as in an Ultralytics dataset file.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import yaml

from missiontree.errors import ModelConfigError

__all__ = ["parse_names", "read_labels_file"]


def parse_names(text: str) -> list[str]:
    """Class names from a model's ``names`` metadata: a dict ``{0: 'person'}`` or list, as text.

    Raises:
        ValueError: The text is neither.
    """
    value = ast.literal_eval(text)
    if isinstance(value, dict):
        return [str(value[k]) for k in sorted(value, key=int)]
    if isinstance(value, list | tuple):
        return [str(v) for v in value]
    raise ValueError(f"expected a dict or list of class names, found {type(value).__name__}")


def read_labels_file(path: Path, provider: str) -> list[str]:
    """Class names from a labels file: one a line (.txt), or ``names`` in a YAML/JSON file.

    Raises:
        ModelConfigError: The file is missing or holds no names.
    """
    if not path.is_file():
        raise ModelConfigError(
            f"detector {provider!r}: labels file {str(path)!r} does not exist; "
            f"give a text file with one class name a line, in the model's class order"
        )
    text = path.read_text(encoding="utf-8")
    if path.suffix.lower() in {".yaml", ".yml", ".json"}:
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
        names = data.get("names") if isinstance(data, dict) else data
        if isinstance(names, dict):
            labels = [str(names[k]) for k in sorted(names, key=int)]
        elif isinstance(names, list):
            labels = [str(n) for n in names]
        else:
            labels = []
    else:
        labels = [line.strip() for line in text.splitlines() if line.strip() and not line.startswith("#")]
    if not labels:
        raise ModelConfigError(
            f"detector {provider!r}: labels file {str(path)!r} holds no class names; "
            f"expected one name a line, or a 'names' list or mapping"
        )
    return labels
