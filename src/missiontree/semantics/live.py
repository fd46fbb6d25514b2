"""The live scene a mission shares between its leaves: ``context.scene``.

:class:`LiveScene` is what the ``BuildSceneGraph`` leaf puts on the mission context
(``MissionContext.scene``) so that later leaves of the same run (intent, search) read what is
where: the :class:`~missiontree.semantics.semantic_map.SemanticMap` (instances, kept true as
things move), the rooms, and the latest :class:`~missiontree.semantics.scene_graph.SceneGraph`
(rebuilt on every change). ``version`` goes up with every rebuild, so a reader can tell whether
the graph changed since it last looked.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from missiontree.semantics.scene_graph import SceneGraph
from missiontree.semantics.semantic_map import SemanticMap


@dataclass
class LiveScene:
    """The semantic map, the rooms and the latest graph of a running mission.

    Attributes:
        map: Object instances (the semantic map).
        graph: The latest scene graph (NAIS shape).
        rooms: The rooms as the graph knows them (:class:`~missiontree.semantics.rooms.RoomRegion`).
        version: Number of rebuilds so far.
        stamp: Robot time of the latest rebuild.
        doubtful: Places (label, x, y) where the detector saw something a few times that did not
            become an instance (seen too close, too far or too briefly): worth a second look
            (``LookAgain``); a place is dropped once an instance of its label stands there.
    """

    map: SemanticMap = field(default_factory=SemanticMap)
    graph: SceneGraph = field(default_factory=SceneGraph)
    rooms: list[Any] = field(default_factory=list)
    version: int = 0
    stamp: float = 0.0
    doubtful: list[tuple[str, float, float]] = field(default_factory=list)

    def object_ids(self) -> set[str]:
        """Ids of every object node of the latest graph (for checking answers that name objects)."""
        return {str(n["id"]) for n in self.graph.objects()}
