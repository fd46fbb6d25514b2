"""What is where: object instances that follow the world, rooms, spatial relations, the scene graph.

- :mod:`~missiontree.semantics.semantic_map`: :class:`SemanticMap`, object instances (label,
  position, size, colour, observations, confidence, first/last seen, room) with add/update/move/
  remove and the changes they make.
- :mod:`~missiontree.semantics.rooms`: rooms segmented from an occupancy map (doors and narrow
  passages as boundaries) or read from a polygon file.
- :mod:`~missiontree.semantics.relations`: spatial relations computed from geometry.
- :mod:`~missiontree.semantics.scene_graph`: :class:`SceneGraph`, building → rooms → objects in the
  NAIS paper's JSON shape.
- :mod:`~missiontree.semantics.builder`: the pipeline from frames to the live graph.
"""
