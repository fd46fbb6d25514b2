"""What is where: object instances that follow the world, rooms, spatial relations, the scene graph.

- :mod:`~missiontree.semantics.semantic_map`: :class:`SemanticMap`, object instances (label,
  position, size, colour, observations, confidence, first/last seen, room) with add/update/move/
  remove and the changes they make.
- :mod:`~missiontree.semantics.fusion`: :class:`InstanceFusion`, projected detections fused into
  the semantic map's instances, over the shared :mod:`~missiontree.semantics.fusion_state` that its
  helpers read: :mod:`~missiontree.semantics.absence` (misses, removals, moves),
  :mod:`~missiontree.semantics.merge` (one object seen twice) and
  :mod:`~missiontree.semantics.plausibility` (a detection the learned map shows is a wall);
  parameters in :mod:`~missiontree.semantics.fusion_params`.
- :mod:`~missiontree.semantics.rooms`: rooms segmented from an occupancy map (doors and narrow
  passages as boundaries) or read from a polygon file.
- :mod:`~missiontree.semantics.relations`: spatial relations computed from geometry.
- :mod:`~missiontree.semantics.scene_graph`: :class:`SceneGraph`, building → rooms → objects in the
  NAIS paper's JSON shape.
- :mod:`~missiontree.semantics.builder`: the pipeline from frames to the live graph.
"""
