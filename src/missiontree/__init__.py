"""missiontree: a behaviour-tree mission engine for mobile robots.

Missions are YAML trees that py_trees ticks; leaves talk to an abstract robot
(:mod:`missiontree.robot`) and to pluggable models. See the README and docs/ in the repository.
"""

__version__ = "0.1.0"
