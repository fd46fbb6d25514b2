"""FleetBuildSceneGraph: one scene graph for the whole fleet, fed by every robot's camera (docs/fleet.md).

Every robot's copy of the tree holds a FleetBuildSceneGraph leaf; they share one
:class:`~missiontree.semantics.builder.SceneBuilder` (``context.fleet.shared("scene_builder", ...)``).
Each leaf sends its own robot's new views to the detector and fuses the answers into that one
builder, so an object one robot saw, moved or found gone is in every robot's ``context.scene`` at
once (a search's candidate seen by robot 1 is known to robot 2). Rooms are segmented from the
fleet's merged map (:class:`~missiontree.behaviours.fleet_map.FleetMap`). Everything else is
:class:`~missiontree.behaviours.scene.BuildSceneGraph`'s: the NAIS filters, fusion, rooms, events;
a ``scene_graph_changed`` event carries the robot whose tick rebuilt the graph, which need not be
the robot whose camera saw the change. Each robot writes the fleet's graph into its own run
directory when it stops. Without a fleet (one robot) it is BuildSceneGraph.
"""

from __future__ import annotations

from missiontree.behaviours.fleet_map import fleet_context
from missiontree.behaviours.scene import BuildSceneGraph

__all__ = ["FleetBuildSceneGraph"]


class FleetBuildSceneGraph(BuildSceneGraph):
    """BuildSceneGraph whose builder (and so live scene) is shared by every robot of the fleet."""

    def on_setup(self) -> None:
        """BuildSceneGraph's checks; rooms from the fleet's merged map (the robot's own without a fleet)."""
        super().on_setup()
        if self.ctx is not None:
            self.ctx = fleet_context(self.ctx)

    def initialise(self) -> None:
        """BuildSceneGraph's start, then the fleet's one builder (made by the first robot to start)."""
        super().initialise()
        fleet = self.context.fleet
        if fleet is None:
            return
        mine = self.builder
        self.builder = fleet.shared("scene_builder", lambda: mine)
        self.context.scene = self.builder.scene
