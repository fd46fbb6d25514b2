"""Shared fixtures: every test starts from clean global state (blackboard, structlog)."""

from __future__ import annotations

from collections.abc import Iterator

import py_trees
import pytest


@pytest.fixture(autouse=True)
def _clean_blackboard() -> Iterator[None]:
    """Clear py_trees' process-global blackboard before and after each test."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()
