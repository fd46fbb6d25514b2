"""An example missiontree plugin: the CountDown leaf, registered through the ``missiontree`` entry point."""

__version__ = "0.1.0"
