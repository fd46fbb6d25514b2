"""Development tools that are not the product: they make or check what ships, and are tested in CI.

Run them from the repository's root as modules (``.venv/bin/python -m tools.detector.train``);
they are not installed with missiontree.
"""
