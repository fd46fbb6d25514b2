"""Mapping: the occupancy grid a robot learns from its lidar, frontiers, scan points, map files, planning.

- :mod:`missiontree.mapping.grid` -- log-odds occupancy grid (Nav2 conventions), numba or numpy.
- :mod:`missiontree.mapping.frontiers` -- clusters of free cells next to unknown ones.
- :mod:`missiontree.mapping.scan_points` -- the vision-language object-search report's scan points.
- :mod:`missiontree.mapping.mapfile` -- map_server's map.pgm + map.yaml, written and read.
- :mod:`missiontree.mapping.planner` -- paths on an occupancy grid.
"""
