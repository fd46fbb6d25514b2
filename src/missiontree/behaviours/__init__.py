"""The leaves that do the robot's work, grouped by mission.

- :mod:`~missiontree.behaviours.motion`: NavigateTo, Rotate.
- :mod:`~missiontree.behaviours.patrol`: Patrol (waypoint loops, skip-on-failure, resume).
- :mod:`~missiontree.behaviours.fleet_patrol`: FleetPatrol (a robot's stretch of a fleet's route).
- :mod:`~missiontree.behaviours.surveillance`: Surveillance (people, alarms with positions).
- :mod:`~missiontree.behaviours.servo`: ServoToTarget (visual servoing on an alarm).
- :mod:`~missiontree.behaviours.explore`: Explore (frontiers or scan points on a learned map).
- :mod:`~missiontree.behaviours.commands`: ServeCommands (a child run once per user command).
- :mod:`~missiontree.behaviours.intent`: ReadIntent and
  :mod:`~missiontree.behaviours.intent_choose`: ChooseIntentTarget, ServeIntent (go where the user means).
- :mod:`~missiontree.behaviours.search`: ScanRotate, ColourAttention, Locate, Approach, Verify (search).
- :mod:`~missiontree.behaviours.approach_steps`: PlanStandoff, DriveToStandoff, FaceTarget, and
  :mod:`~missiontree.behaviours.confirm_steps`: PlaceByDepth, LookFor, ConfirmTarget (the steps of
  ``trees/subtrees/approach_confirm.yaml``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from missiontree.engine.registry import NodeRegistry


def register_nodes(registry: NodeRegistry) -> None:
    """Add the behaviour leaves to ``registry`` (listed in missiontree.plugins.builtin.NODE_MODULES)."""
    from missiontree.behaviours.approach_steps import DriveToStandoff, FaceTarget, PlanStandoff
    from missiontree.behaviours.commands import SERVE_COMMANDS
    from missiontree.behaviours.confirm_steps import ConfirmTarget, LookFor, PlaceByDepth
    from missiontree.behaviours.explore import Explore
    from missiontree.behaviours.fleet_explore import FleetExplore
    from missiontree.behaviours.fleet_patrol import FleetPatrol
    from missiontree.behaviours.fleet_scene import FleetBuildSceneGraph
    from missiontree.behaviours.fleet_search import FleetFound, FleetLocate, FleetSearchWatch
    from missiontree.behaviours.intent import ReadIntent
    from missiontree.behaviours.intent_choose import ChooseIntentTarget, ServeIntent
    from missiontree.behaviours.motion import NavigateTo, Rotate
    from missiontree.behaviours.patrol import Patrol
    from missiontree.behaviours.scene import BuildSceneGraph
    from missiontree.behaviours.scene_look import LookAgain
    from missiontree.behaviours.search import (
        Approach,
        ColourAttention,
        Locate,
        ResumeExplore,
        ScanRotate,
        Verify,
    )
    from missiontree.behaviours.servo import ServoToTarget
    from missiontree.behaviours.surveillance import Surveillance

    for leaf in (NavigateTo, Rotate, Patrol, Surveillance, ServoToTarget, ReadIntent, ChooseIntentTarget,
                 ServeIntent):
        registry.add(leaf)
    registry.add(FleetPatrol)
    for fleet_leaf in (FleetExplore, FleetLocate, FleetFound, FleetSearchWatch, FleetBuildSceneGraph):
        registry.add(fleet_leaf)
    registry.add(SERVE_COMMANDS)
    registry.add(Explore)
    registry.add(BuildSceneGraph)
    registry.add(LookAgain)
    for search_leaf in (ScanRotate, ColourAttention, ResumeExplore, Locate, Approach, Verify):
        registry.add(search_leaf)
    for step in (PlanStandoff, DriveToStandoff, FaceTarget, PlaceByDepth, LookFor, ConfirmTarget):
        registry.add(step)
