"""The mission engine: YAML → checked spec → py_trees tree; registry; runner; tick log."""
