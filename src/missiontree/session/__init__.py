"""The one wiring path of a mission run: load → check → robot → models → context → runner.

- :mod:`~missiontree.session.mission` — :class:`MissionRequest`, :class:`Session`, :func:`run_mission`.
- :mod:`~missiontree.session.models` — a models config → providers by role (:func:`build_models`).
- :mod:`~missiontree.session.params` — ``run --set`` values checked against the mission's ``params:``.
- :mod:`~missiontree.session.progress` — the live progress line on stderr.

Only this package wires concrete backends and model providers together; the CLI,
the benchmarks and the batch runner call it.
"""

from missiontree.session.mission import MissionRequest, Session, run_mission

__all__ = ["MissionRequest", "Session", "run_mission"]
