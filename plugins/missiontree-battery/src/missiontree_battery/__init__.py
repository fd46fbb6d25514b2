"""missiontree-battery: an example plugin that adds a sensor, a condition and a model provider.

- :mod:`.battery`: the ``battery`` sensor — ``sensor_msgs/BatteryState`` on ``/battery_state`` over
  ROS 2 (as the TurtleBot 4 publishes it), a charge that drains with time and distance and fills on
  a dock in the simulator.
- :mod:`.nodes`: ``IsBatteryLow``, Nav2's condition of that name.
- :mod:`.blob`: ``colour_blob``, a detector provider that boxes regions of one named colour.
- :mod:`.plugin`: the hook implementations the ``missiontree`` entry point names.
"""

__version__ = "0.1.0"
